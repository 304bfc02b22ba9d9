//! Flight control: the three control laws and the reference shaper (being written).

//! The tokio runtime: paces simulated time, owns the sockets (being written).

//! Momentum-based external-wrench estimator of order r (being written).

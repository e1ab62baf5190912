//! Accuracy figures against ground truth.

pub mod metrics;

//! Accuracy figures against ground truth: image-space metrics, and a strand model scored
//! against 3D ground-truth strands.

pub mod gt3d;
pub mod mask;
pub mod metrics;
pub mod video;

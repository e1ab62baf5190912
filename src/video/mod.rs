//! Hair through a video (C13 §3–4): clip loading, flow, features, the dynamic hair model.

pub mod frames;

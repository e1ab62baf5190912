//! Hair through a video (C13 §3–4).

pub mod flow;

//! coif: single-view 3D strand hair modelling after Chai et al. 2013, with the Chen-Zhu 2006
//! generative sketch model. Every heavy stage is a WGSL pass with a CPU mirror; see
//! [`gpu::engine`] for how one recording runs on either.

pub mod analyze;
pub mod base;
pub mod batch;
pub mod edit;
pub mod error;
pub mod eval;
pub mod gpu;
pub mod hair;
pub mod interrupt;
pub mod io;
pub mod jobs;
pub mod model;
pub mod render;
pub mod sim;
pub mod sketch;
pub mod stages;
pub mod synth;
pub mod testing;
pub mod timings;
pub mod video;

pub use error::{Error, Result};
pub use gpu::engine::{BackendChoice, Engine};

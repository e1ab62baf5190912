//! coif: single-view 3D strand hair modelling after Chai et al. 2013, with the Chen-Zhu 2006
//! generative sketch model. Every heavy stage is a WGSL pass with a CPU mirror; see
//! [`engine`] for how one recording runs on either.

pub mod analyze;
pub mod annot;
pub mod assets;
pub mod direction;
pub mod engine;
pub mod error;
pub mod field3d;
pub mod gpu;
pub mod grid;
pub mod grow;
pub mod head;
pub mod head_texture;
pub mod imgio;
pub mod import;
pub mod inpaint;
pub mod io;
pub mod metrics;
pub mod model;
pub mod npy;
pub mod orient;
pub mod raster;
pub mod refine;
pub mod render;
pub mod resolve;
pub mod rng;
pub mod segment;
pub mod shade;
pub mod stages;
pub mod strands;
pub mod synth;
pub mod synth3d;
pub mod testing;
pub mod trace;
pub mod vis;
pub mod volume;

pub use engine::{BackendChoice, Engine};
pub use error::{Error, Result};

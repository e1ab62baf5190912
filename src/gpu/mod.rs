//! The GPU side: the adapter and device ([`context`]) and the engine that runs a recording of
//! passes on it or on their CPU mirrors ([`engine`]).

pub mod context;
pub mod engine;
pub mod pool;
pub mod timer;
pub mod wgsl;

pub use context::{describe, hardware_gpu_present, list_adapters, GpuContext};

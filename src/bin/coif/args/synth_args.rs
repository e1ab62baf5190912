//! `coif synth`: a synthetic portrait with exact ground truth, in any texture variation.

use super::Request;
use clap::Args;
use coif::gpu::engine::BackendChoice;
use coif::jobs::{Job, SynthJob};
use coif::synth;
use std::path::PathBuf;

#[derive(Args)]
pub struct SynthArgs {
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value = "long")]
    style: synth::Style,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// 3D ground truth: a strand model grown on the parametric head and rendered through a
    /// known camera (writes gt_strands.hair and camera.json too).
    #[arg(long)]
    gt3d: bool,
    /// Texture variation of the hair (2D only): a preset (plain, thin, thick, faint, noisy,
    /// blurry, jpeg, curly, photo) and/or key=value pairs, comma-separated, e.g.
    /// "curly,jpeg=70". Keys: width (strand width factor), contrast (strand opacity
    /// factor), noise (Gaussian sigma, 0..1 units), blur (sigma, px), jpeg (quality),
    /// curl (largest turn, degrees), wavelength (of the curl, px at 512²).
    #[arg(long, default_value = "plain")]
    texture: synth::Texture,
}

impl SynthArgs {
    pub fn request(self) -> Request {
        Request::one(
            Job::Synth(SynthJob {
                out: self.out,
                params: synth::SynthParams {
                    style: self.style,
                    seed: self.seed,
                    width: self.size,
                    height: self.size,
                },
                gt3d: self.gt3d,
                texture: self.texture,
            }),
            // Synthesis runs no pass: the CPU backend, which cannot fail to open.
            BackendChoice::Cpu,
        )
    }
}

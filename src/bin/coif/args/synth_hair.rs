//! `coif synth-hair`: a sketch to a hair image (CZ06 §3).

use super::{BackendArgs, Request};
use clap::Args;
use coif::jobs::{Job, SynthHairJob};
use coif::sketch::synth::SynthParams;
use std::path::PathBuf;

#[derive(Args)]
pub struct SynthHairArgs {
    /// A sketch: hair.czs, sketch.json or sketch.svg (e.g. edited in Inkscape).
    #[arg(long)]
    sketch: PathBuf,
    /// The image to write: .png (the hair on a transparent card unless --over is given) or
    /// .jpg (on white).
    #[arg(long)]
    out: PathBuf,
    /// Seed of the noise draws (default: the sketch's own): another seed gives another
    /// image, "different but similar".
    #[arg(long)]
    seed: Option<u64>,
    /// Rounds of streamline averaging and contrast matching.
    #[arg(long, default_value_t = coif::sketch::texture::TextureParams::default().rounds)]
    rounds: u32,
    /// Half-length of the streamline average, px each way (longer: longer streaks).
    #[arg(long, default_value_t = coif::sketch::texture::TextureParams::default().half_len)]
    half_length: f32,
    /// No grain: the high band as streamline averaging leaves it (by default grain is added
    /// up to the along/across gradient ratio the sketch stores from its photo).
    #[arg(long)]
    no_grain: bool,
    /// A photo of the sketch's size to put the hair over.
    #[arg(long)]
    over: Option<PathBuf>,
    /// Also write the filled field and bands (theta.npy, vector.npy, rho.npy, low.npy,
    /// high.npy, field.png) into this folder.
    #[arg(long)]
    layers: Option<PathBuf>,
    #[command(flatten)]
    backend: BackendArgs,
}

impl SynthHairArgs {
    pub fn request(self) -> Request {
        let mut params = SynthParams {
            seed: self.seed,
            grain: !self.no_grain,
            ..Default::default()
        };
        params.texture.rounds = self.rounds;
        params.texture.half_len = self.half_length;
        Request::Jobs {
            jobs: vec![Job::SynthHair(SynthHairJob {
                sketch: self.sketch,
                out: self.out,
                over: self.over,
                layers: self.layers,
                params,
            })],
            backend: self.backend.backend,
            max_binding_bytes: None,
            banner: None,
        }
    }
}

//! `coif cartoon`'s arguments and the job they ask for.

use crate::args::Request;
use clap::Args;
use coif::jobs::{CartoonJob, Job};
use coif::sketch::cartoon::CartoonParams;
use std::path::PathBuf;

#[derive(Args)]
pub struct CartoonArgs {
    /// A sketch: hair.czs, sketch.json or sketch.svg.
    #[arg(long)]
    sketch: PathBuf,
    /// The cartoon: .png or .jpg (anti-aliased, through the rasteriser) or .svg (one
    /// Bézier path per curve), by extension.
    #[arg(long)]
    out: PathBuf,
    /// Stroke width W, px (side boundaries are drawn 1.3 W, stream lines 0.85 W).
    #[arg(long, default_value_t = CartoonParams::default().width)]
    width: f32,
    /// Draw over this photo (the sketch's size) instead of white paper.
    #[arg(long)]
    over: Option<PathBuf>,
    /// ink: dark strokes; type: a colour per curve type a-e; direction: hue by growth
    /// direction, with arrow-heads toward where the hair grows.
    #[arg(long, default_value = "ink")]
    style: String,
    #[command(flatten)]
    backend: crate::args::BackendArgs,
}

impl CartoonArgs {
    pub fn request(self) -> anyhow::Result<Request> {
        let params = CartoonParams {
            width: self.width,
            style: self.style.parse()?,
            ..Default::default()
        };
        Ok(Request::Jobs {
            jobs: vec![Job::Cartoon(CartoonJob {
                sketch: self.sketch,
                out: self.out,
                over: self.over,
                params,
            })],
            backend: self.backend.backend,
            max_binding_bytes: None,
            banner: None,
        })
    }
}

//! Shi–Tomasi corner score per pixel: the smaller eigenvalue of the box-averaged structure
//! tensor (Gaussian window of sigma r/2), 0 where the tensor is too anisotropic (KLT feature detection, `crate::video::features::detect`).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "klt_score",
    wgsl: include_str!("../../wgsl/klt_score.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::ReadWrite],
    cpu: klt_score_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Window half size r: the window is (2r+1)², its Gaussian weights have sigma r/2.
    pub radius: u32,
    /// Scores with λmin < min_iso·λmax are set to 0 (edges and stripes).
    pub min_iso: f32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [
        crate::gpu::engine::groups(cfg.width, 8),
        crate::gpu::engine::groups(cfg.height, 8),
        1,
    ]
}

fn klt_score_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let g_gray = b[1].get::<f32>();
    // A plain slice: the RefCell guard is not Sync, the data is.
    let gray: &[f32] = &g_gray;
    let mut score = b[2].get_mut::<f32>();
    let (w, h) = (cfg.width as i32, cfg.height as i32);
    let px = |x: i32, y: i32| gray[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let r = cfg.radius as i32;
    score[..(w * h) as usize]
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(gy, row)| {
            for (gx, out) in row.iter_mut().enumerate() {
                let (mut sxx, mut sxy, mut syy, mut wsum) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
                let k = -2.0 / (r * r) as f32;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (x, y) = (gx as i32 + dx, gy as i32 + dy);
                        let ix = 0.5 * (px(x + 1, y) - px(x - 1, y));
                        let iy = 0.5 * (px(x, y + 1) - px(x, y - 1));
                        let wt = (k * (dx * dx + dy * dy) as f32).exp();
                        sxx += wt * ix * ix;
                        sxy += wt * ix * iy;
                        syy += wt * iy * iy;
                        wsum += wt;
                    }
                }
                let n = wsum;
                let (a, b, c) = (sxx / n, sxy / n, syy / n);
                let hh = 0.5 * (a - c);
                let root = (hh * hh + b * b).sqrt();
                let (lo, hi) = (0.5 * (a + c) - root, 0.5 * (a + c) + root);
                *out = if lo >= cfg.min_iso * hi { lo } else { 0.0 };
            }
        });
}

//! Separable convolution along one axis, clamp-to-edge, optional subtraction (DoG).

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "sep_blur",
    wgsl: include_str!("../../wgsl/sep_blur.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: sep_blur_cpu,
};

/// Outputs per invocation along the axis; the weights are padded with this many zeros.
pub const OUT_PER_INV: u32 = 8;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub radius: u32,
    pub axis: u32,
    pub subtract: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// Normalised Gaussian taps for `sigma`, radius ceil(3 sigma), padded for the shader.
pub fn gaussian_weights(sigma: f32) -> (u32, Vec<f32>) {
    let radius = (3.0 * sigma).ceil().max(1.0) as u32;
    let taps: Vec<f64> = (-(radius as i32)..=radius as i32)
        .map(|t| (-0.5 * (t as f64 / sigma as f64).powi(2)).exp())
        .collect();
    let sum: f64 = taps.iter().sum();
    let pad = OUT_PER_INV as usize;
    let mut w = vec![0.0f32; taps.len() + 2 * pad];
    for (i, t) in taps.iter().enumerate() {
        w[pad + i] = (t / sum) as f32;
    }
    (radius, w)
}

/// Workgroups for a dispatch over a `width` x `height` image.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    let (along, across) = if cfg.axis == 0 {
        (cfg.width, cfg.height)
    } else {
        (cfg.height, cfg.width)
    };
    [
        crate::gpu::engine::groups(along.div_ceil(OUT_PER_INV), 8),
        crate::gpu::engine::groups(across, 8),
        1,
    ]
}

/// Records a Gaussian blur of `src` (w x h) by `sigma` into the first w*h values of `dst`
/// (`sep_blur` along x, then y).
pub fn record_gaussian(
    rec: &mut crate::gpu::engine::Recording,
    src: crate::gpu::engine::BufProxy,
    dst: crate::gpu::engine::BufProxy,
    w: u32,
    h: u32,
    sigma: f32,
) {
    let (radius, weights) = gaussian_weights(sigma);
    let wbuf = rec.upload("coif.sep_blur.weights", &weights);
    let tmp = rec.alloc(
        "coif.sep_blur.tmp",
        w as u64 * h as u64 * 4,
        crate::base::sentinel::SENTINEL,
    );
    for (axis, from, to) in [(0u32, src, tmp), (1, tmp, dst)] {
        let cfg = Config {
            width: w,
            height: h,
            radius,
            axis,
            ..Default::default()
        };
        let u = rec.uniform("coif.sep_blur.cfg", &cfg);
        // The unused `minus` binding still needs a buffer; `from` is as good as any.
        rec.dispatch(&STAGE, workgroups(&cfg), &[u, wbuf, from, from, to], &[]);
    }
}

fn sep_blur_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    // Plain slices: the RefCell guards are not Sync, the data is.
    let (weights, src, minus) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (weights, src, minus): (&[f32], &[f32], &[f32]) = (&weights, &src, &minus);
    let mut dst = b[4].get_mut::<f32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let r = cfg.radius as i64;
    let pad = OUT_PER_INV as usize;
    let taps = &weights[pad..pad + 2 * r as usize + 1];
    dst[..w * h]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let mut acc = 0.0f32;
                for (k, &wt) in taps.iter().enumerate() {
                    let t = k as i64 - r;
                    let v = if cfg.axis == 0 {
                        let xx = (x as i64 + t).clamp(0, w as i64 - 1) as usize;
                        src[y * w + xx]
                    } else {
                        let yy = (y as i64 + t).clamp(0, h as i64 - 1) as usize;
                        src[yy * w + x]
                    };
                    acc += wt * v;
                }
                if cfg.subtract == 1 {
                    acc -= minus[y * w + x];
                }
                *out = acc;
            }
        });
}

//! Cut (C13 appendix A.2), one invocation per strand. Pairs with `wgsl/edit_cut.wgsl`; the
//! mirror below does the same f32 arithmetic in the same order.
//!
//! Every vertex whose projection is within R of the cut stroke (2D distance r) is a
//! candidate with weight 1 − r/R; one is drawn with a uniform from a PCG hash of the seed
//! and the strand's index, so both backends draw the same vertex, and the strand ends there
//! (the drawn vertex is kept). The root and the tip are candidates too: a strand drawn at
//! its root keeps only the root, one drawn at its tip is unchanged. With R = 0 the cut is
//! clean: the strand keeps the vertices up to the one just before its projection first
//! crosses the stroke (no new vertex is made, so the tip lies within one vertex spacing of
//! the crossing). Strands that do not reach the stroke keep their count. The pass writes
//! the new vertex count of each strand; the host drops the tips and compacts on the CPU.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use crate::stages::edit_stroke::{crosses, nearest, project, strand_uniform, SEG_FLOATS};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "edit_cut",
    wgsl: include_str!("../../wgsl/edit_cut.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: edit_cut_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 64;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub n_strands: u32,
    pub n_segs: u32,
    /// R, image px (0: a clean cut at the first crossing).
    pub radius: f32,
    /// Camera scale, px per metre.
    pub s: f32,
    /// The first two rows of the camera rotation (view x and y).
    pub r00: f32,
    pub r01: f32,
    pub r02: f32,
    pub r10: f32,
    pub r11: f32,
    pub r12: f32,
    pub tx: f32,
    pub ty: f32,
    /// The 64-bit seed, low and high words.
    pub seed_lo: u32,
    pub seed_hi: u32,
    /// Index of the tile's first strand in the whole set (keys the hash).
    pub first_strand: u32,
    pub _pad0: u32,
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_strands, WORKGROUP), 1, 1]
}

/// The new vertex count of one strand (`x`: its vertices, xyz); `strand` is its index in
/// the tile.
pub fn cut_strand(cfg: &Config, segs: &[f32], x: &[f32], strand: u32) -> u32 {
    let n = (x.len() / 3) as u32;
    let (r0, r1) = ([cfg.r00, cfg.r01, cfg.r02], [cfg.r10, cfg.r11, cfg.r12]);
    let proj = |k: u32| {
        let i = 3 * k as usize;
        project(r0, r1, cfg.s, [cfg.tx, cfg.ty], [x[i], x[i + 1], x[i + 2]])
    };
    let mut keep = n;
    if cfg.radius <= 0.0 {
        let mut p0 = proj(0);
        'walk: for k in 0..n.saturating_sub(1) {
            let p1 = proj(k + 1);
            for g in segs.chunks_exact(SEG_FLOATS).take(cfg.n_segs as usize) {
                if crosses(p0, p1, [g[0], g[1]], [g[4], g[5]]) {
                    keep = k + 1;
                    break 'walk;
                }
            }
            p0 = p1;
        }
    } else {
        let mut total = 0.0f32;
        for k in 0..n {
            let r = nearest(segs, cfg.n_segs, proj(k)).0;
            if r < cfg.radius {
                total += 1.0 - r / cfg.radius;
            }
        }
        if total > 0.0 {
            let target = strand_uniform(
                cfg.seed_lo,
                cfg.seed_hi,
                cfg.first_strand.wrapping_add(strand),
            ) * total;
            let mut acc = 0.0f32;
            for k in 0..n {
                let r = nearest(segs, cfg.n_segs, proj(k)).0;
                if r < cfg.radius {
                    acc += 1.0 - r / cfg.radius;
                    keep = k + 1;
                    if acc > target {
                        break;
                    }
                }
            }
        }
    }
    keep
}

/// Bindings: cfg, segs (8 f32 per stroke segment), offsets (n_strands + 1, vertices), xs
/// (xyz per vertex, model space), counts (out: new vertex count per strand).
pub fn edit_cut_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let segs = b[1].get::<f32>();
    let offsets = b[2].get::<u32>();
    let xs = b[3].get::<f32>();
    let mut counts = b[4].get_mut::<u32>();
    let (segs, offsets, xs) = (&*segs, &*offsets, &*xs);
    let ns = cfg.n_strands as usize;
    counts[..ns].par_iter_mut().enumerate().for_each(|(s, c)| {
        let (a, b) = (3 * offsets[s] as usize, 3 * offsets[s + 1] as usize);
        *c = cut_strand(&cfg, segs, &xs[a..b], s as u32);
    });
}

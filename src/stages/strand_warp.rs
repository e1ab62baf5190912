//! Eq. (7) of C13, one invocation per strand vertex. Pairs with `wgsl/strand_warp.wgsl`;
//! the mirror does the same f32 arithmetic in the same order.
//!
//! The vertices are in head model space, where the head does not move: its rigid motion
//! M_i is the frame's camera C_i. With p_r = C_r(v_r) and p′_i = C_i(v_r) (where the vertex
//! would be if the hair moved rigidly with the head), the hair's own motion is the residual
//! W_i = W*_i(p_r) − (p′_i − p_r), lifted back to model space through C_i (divide by its
//! scale, flip y, rotate back; no depth change: one view gives none) and weighted by β.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use crate::hair::head::WeakPerspective;
use crate::stages::warp_compose::sample2;
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "strand_warp",
    wgsl: include_str!("../../wgsl/strand_warp.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
    ],
    cpu: strand_warp_cpu,
};

/// Workgroup width of the WGSL entry point.
pub const WORKGROUP: u32 = 64;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub n_verts: u32,
    pub _pad0: u32,
    pub rs: f32,
    pub r00: f32,
    pub r01: f32,
    pub r02: f32,
    pub r10: f32,
    pub r11: f32,
    pub r12: f32,
    pub rtx: f32,
    pub rty: f32,
    pub fs: f32,
    pub i00: f32,
    pub i01: f32,
    pub i02: f32,
    pub i10: f32,
    pub i11: f32,
    pub i12: f32,
    pub itx: f32,
    pub ity: f32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl Config {
    /// The uniform for a `width` x `height` warp field, `n_verts` vertices, the reference
    /// camera and frame `i`'s camera.
    pub fn new(
        width: u32,
        height: u32,
        n_verts: u32,
        cam_r: &WeakPerspective,
        cam_i: &WeakPerspective,
    ) -> Self {
        let (a0, a1) = (cam_r.r.row(0), cam_r.r.row(1));
        let (b0, b1) = (cam_i.r.row(0), cam_i.r.row(1));
        Config {
            width,
            height,
            n_verts,
            rs: cam_r.s,
            r00: a0.x,
            r01: a0.y,
            r02: a0.z,
            r10: a1.x,
            r11: a1.y,
            r12: a1.z,
            rtx: cam_r.t.x,
            rty: cam_r.t.y,
            fs: cam_i.s,
            i00: b0.x,
            i01: b0.y,
            i02: b0.z,
            i10: b1.x,
            i11: b1.y,
            i12: b1.z,
            itx: cam_i.t.x,
            ity: cam_i.t.y,
            ..Default::default()
        }
    }
}

pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [crate::gpu::engine::groups(cfg.n_verts, WORKGROUP), 1, 1]
}

fn dot(a: [f32; 3], v: [f32; 3]) -> f32 {
    a[0] * v[0] + a[1] * v[1] + a[2] * v[2]
}

/// One vertex of Eq. (7).
pub fn warp_vertex(cfg: &Config, field: &[f32], v: [f32; 3], beta: f32) -> [f32; 3] {
    let (rx, ry) = ([cfg.r00, cfg.r01, cfg.r02], [cfg.r10, cfg.r11, cfg.r12]);
    let (ix, iy) = ([cfg.i00, cfg.i01, cfg.i02], [cfg.i10, cfg.i11, cfg.i12]);
    let pr = [
        cfg.rs * dot(rx, v) + cfg.rtx,
        -cfg.rs * dot(ry, v) + cfg.rty,
    ];
    let pi = [
        cfg.fs * dot(ix, v) + cfg.itx,
        -cfg.fs * dot(iy, v) + cfg.ity,
    ];
    let ws = sample2(field, cfg.width, cfg.height, pr[0], pr[1]);
    let wi = [ws[0] - (pi[0] - pr[0]), ws[1] - (pi[1] - pr[1])];
    let mut o = [0.0f32; 3];
    for k in 0..3 {
        let d = (wi[0] * ix[k] - wi[1] * iy[k]) / cfg.fs;
        o[k] = v[k] + beta * d;
    }
    o
}

fn strand_warp_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (xs, beta, field) = (b[1].get::<f32>(), b[2].get::<f32>(), b[3].get::<f32>());
    let (xs, beta, field): (&[f32], &[f32], &[f32]) = (&xs, &beta, &field);
    let mut out = b[4].get_mut::<f32>();
    out[..3 * cfg.n_verts as usize]
        .par_chunks_mut(3)
        .enumerate()
        .for_each(|(k, o)| {
            let v = [xs[3 * k], xs[3 * k + 1], xs[3 * k + 2]];
            o.copy_from_slice(&warp_vertex(&cfg, field, v, beta[k]));
        });
}

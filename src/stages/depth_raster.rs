//! Front/back depth rasterisation of volume-space triangles (C13 §2.1: the initial hair model
//! and the head "rasterized together from both the front and back views"). One GPU invocation
//! per triangle; the CPU mirror below does the same integer coverage test and the same f32
//! interpolation, so coverage is identical and depths differ only by fused multiply-adds.

use crate::gpu::engine::{Bind, CpuBinding, StageDef};
use rayon::prelude::*;

pub const STAGE: StageDef = StageDef {
    name: "depth_raster",
    wgsl: include_str!("../../wgsl/depth_raster.wgsl"),
    bindings: &[
        Bind::Uniform,
        Bind::Read,
        Bind::Read,
        Bind::ReadWrite,
        Bind::ReadWrite,
    ],
    cpu: depth_raster_cpu,
};

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    pub n_tris: u32,
    /// Workgroups along x; set it from [`workgroups`].
    pub groups_x: u32,
}

/// Invocations per workgroup (one triangle each).
pub const WORKGROUP: u32 = 64;
/// Sub-pixel precision of the snapped x, y: 1/16 px.
pub const SUB: f32 = 16.0;
/// Largest bounding-box span of a triangle in 1/16 px (2^15 - 1), so that the i32 edge
/// functions cannot overflow; larger triangles are skipped by the pass and refused by the host.
pub const MAX_SPAN: i32 = 32767;
/// The same limit in pixels, for host-side checks (snapping can add 1/32 px at each end).
pub const MAX_SPAN_PX: f32 = (MAX_SPAN - 2) as f32 / SUB;

/// Initial word of the front buffer: below every encoded depth, so it survives only where no
/// triangle covers the pixel centre.
pub const FRONT_EMPTY: u32 = 0;
/// Initial word of the back buffer: above every encoded depth.
pub const BACK_EMPTY: u32 = u32::MAX;

/// Order-preserving f32 -> u32 (for finite values and infinities): a < b iff enc(a) < enc(b).
pub fn encode_depth(z: f32) -> u32 {
    let b = z.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Inverse of [`encode_depth`].
pub fn decode_depth(e: u32) -> f32 {
    if e & 0x8000_0000 != 0 {
        f32::from_bits(e & 0x7fff_ffff)
    } else {
        f32::from_bits(!e)
    }
}

/// Dispatch size for `n_tris` triangles: a 2D grid once one dimension would exceed the
/// 65535-workgroup limit. Returns the workgroups and the `groups_x` to put in [`Config`].
pub fn workgroups(n_tris: u32) -> [u32; 3] {
    let g = crate::gpu::engine::groups(n_tris, WORKGROUP);
    let gx = g.min(65535);
    [gx, g.div_ceil(gx), 1]
}

fn snap(v: f32) -> i32 {
    // WGSL `round` is round-half-to-even; `as` saturates like WGSL's f32 -> i32.
    (v * SUB).round_ties_even() as i32
}

type P = [i32; 2];

fn edge(a: P, b: P, p: P) -> i32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

fn bias(a: P, b: P) -> i32 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    if dy < 0 || (dy == 0 && dx > 0) {
        0
    } else {
        1
    }
}

/// A triangle after snapping and winding normalisation, as the shader sets it up.
struct Setup {
    p: [P; 3],
    z0: f32,
    dz1: f32,
    dz2: f32,
    bias: [i32; 3],
    area: f32,
    x: [i32; 2],
    y: [i32; 2],
}

fn setup(verts: &[f32], tri: &[u32], width: u32, height: u32) -> Option<Setup> {
    let v = |i: u32, c: usize| verts[3 * i as usize + c];
    let (i0, mut i1, mut i2) = (tri[0], tri[1], tri[2]);
    let p0 = [snap(v(i0, 0)), snap(v(i0, 1))];
    let mut p1 = [snap(v(i1, 0)), snap(v(i1, 1))];
    let mut p2 = [snap(v(i2, 0)), snap(v(i2, 1))];
    let lo = [p0[0].min(p1[0]).min(p2[0]), p0[1].min(p1[1]).min(p2[1])];
    let hi = [p0[0].max(p1[0]).max(p2[0]), p0[1].max(p1[1]).max(p2[1])];
    if hi[0] - lo[0] > MAX_SPAN || hi[1] - lo[1] > MAX_SPAN {
        return None;
    }
    let mut area = edge(p0, p1, p2);
    if area == 0 {
        return None;
    }
    if area < 0 {
        std::mem::swap(&mut p1, &mut p2);
        std::mem::swap(&mut i1, &mut i2);
        area = -area;
    }
    let z0 = v(i0, 2);
    Some(Setup {
        p: [p0, p1, p2],
        z0,
        dz1: v(i1, 2) - z0,
        dz2: v(i2, 2) - z0,
        bias: [bias(p1, p2), bias(p2, p0), bias(p0, p1)],
        area: area as f32,
        x: [
            ((lo[0] - 8 + 15) >> 4).max(0),
            ((hi[0] - 8) >> 4).min(width as i32 - 1),
        ],
        y: [
            ((lo[1] - 8 + 15) >> 4).max(0),
            ((hi[1] - 8) >> 4).min(height as i32 - 1),
        ],
    })
}

/// Rows per band of the CPU mirror: bands run in parallel, each owning its rows, so the
/// mirror needs no atomics and stays deterministic.
const BAND: usize = 8;

fn depth_raster_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let (g_verts, g_tris) = (b[1].get::<f32>(), b[2].get::<u32>());
    let (verts, tris): (&[f32], &[u32]) = (&g_verts, &g_tris);
    let mut front = b[3].get_mut::<u32>();
    let mut back = b[4].get_mut::<u32>();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    if w == 0 || h == 0 {
        return;
    }
    let setups: Vec<Setup> = (0..cfg.n_tris as usize)
        .into_par_iter()
        .filter_map(|t| setup(verts, &tris[3 * t..3 * t + 3], cfg.width, cfg.height))
        .collect();
    // Bin triangles by band, in triangle order.
    let n_bands = h.div_ceil(BAND);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); n_bands];
    for (t, s) in setups.iter().enumerate() {
        if s.y[0] > s.y[1] || s.x[0] > s.x[1] {
            continue;
        }
        for bin in &mut bins[s.y[0] as usize / BAND..=s.y[1] as usize / BAND] {
            bin.push(t as u32);
        }
    }
    front[..w * h]
        .par_chunks_mut(BAND * w)
        .zip(back[..w * h].par_chunks_mut(BAND * w))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(band, ((fr, bk), bin))| {
            let y0 = (band * BAND) as i32;
            let y1 = y0 + (fr.len() / w) as i32 - 1;
            for &t in bin {
                let s = &setups[t as usize];
                let [p0, p1, p2] = s.p;
                for y in s.y[0].max(y0)..=s.y[1].min(y1) {
                    for x in s.x[0]..=s.x[1] {
                        let p = [16 * x + 8, 16 * y + 8];
                        let w0 = edge(p1, p2, p);
                        let w1 = edge(p2, p0, p);
                        let w2 = edge(p0, p1, p);
                        if w0 - s.bias[0] < 0 || w1 - s.bias[1] < 0 || w2 - s.bias[2] < 0 {
                            continue;
                        }
                        let z = s.z0 + (w1 as f32 * s.dz1 + w2 as f32 * s.dz2) / s.area;
                        let e = encode_depth(z);
                        let i = (y - y0) as usize * w + x as usize;
                        fr[i] = fr[i].max(e);
                        bk[i] = bk[i].min(e);
                    }
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_preserves_order() {
        let vals = [
            f32::NEG_INFINITY,
            -1e30,
            -2.5,
            -0.0,
            0.0,
            1e-30,
            3.0,
            1e30,
            f32::INFINITY,
        ];
        for w in vals.windows(2) {
            assert!(encode_depth(w[0]) <= encode_depth(w[1]), "{w:?}");
            assert!(encode_depth(w[0]) > FRONT_EMPTY && encode_depth(w[1]) < BACK_EMPTY);
        }
        for v in vals {
            assert_eq!(decode_depth(encode_depth(v)).to_bits(), v.to_bits());
        }
    }

    #[test]
    fn shared_edge_is_covered_once() {
        // Two triangles of a square whose diagonal passes through pixel centres.
        let verts = [0.0, 0.0, 1.0, 4.0, 0.0, 2.0, 4.0, 4.0, 3.0, 0.0, 4.0, 4.0];
        let mut count = [0u32; 16];
        for tri in [[0u32, 1, 2], [0, 2, 3]] {
            let s = setup(&verts, &tri, 4, 4).unwrap();
            for y in s.y[0]..=s.y[1] {
                for x in s.x[0]..=s.x[1] {
                    let p = [16 * x + 8, 16 * y + 8];
                    let w = [
                        edge(s.p[1], s.p[2], p),
                        edge(s.p[2], s.p[0], p),
                        edge(s.p[0], s.p[1], p),
                    ];
                    if (0..3).all(|k| w[k] - s.bias[k] >= 0) {
                        count[(y * 4 + x) as usize] += 1;
                    }
                }
            }
        }
        assert_eq!(count, [1; 16]);
    }
}

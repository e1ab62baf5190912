//! Textured head mesh and background (`wgsl/render/mesh_raster.wgsl`): the CPU mirror of
//! `vs_mesh` / `fs_mesh` for one triangle in one tile. The background pass
//! (`vs_background` / `fs_background`) copies the background into every sample, which the
//! tile driver (`crate::render::raster`, `cpu.rs`) does when it clears a tile.

#![allow(clippy::needless_range_loop)]

use crate::gpu::engine::RenderStageDef;
use crate::render::raster::Texture;
use crate::stages::raster_common::{
    a2c_count, a2c_mask, bilinear_at, snap, Fb, Offsets, Plane, Poly, TileBuf,
};

/// Entry points (vertex, fragment) of the mesh and the background pipelines.
pub const MESH: (&str, &str) = ("vs_mesh", "fs_mesh");
pub const BACKGROUND: (&str, &str) = ("vs_background", "fs_background");

pub const STAGE: RenderStageDef = RenderStageDef {
    name: "mesh_raster",
    wgsl: include_str!("../../wgsl/render/mesh_raster.wgsl"),
    entry_points: &[MESH, BACKGROUND],
    compute: &[],
    int64_atomics: false,
};

/// One mesh triangle as both paths see it (the WGSL `Tri`): corners (x, y, z, u), then v.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TriRec {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
    pub v: [f32; 4],
}

/// Conservative pixel bounding box of a triangle (for binning only).
pub fn tri_bounds(t: &TriRec) -> [f32; 4] {
    let xs = [t.a[0], t.b[0], t.c[0]];
    let ys = [t.a[1], t.b[1], t.c[1]];
    let min = |v: [f32; 3]| v[0].min(v[1]).min(v[2]) - 1.0;
    let max = |v: [f32; 3]| v[0].max(v[1]).max(v[2]) + 1.0;
    [min(xs), min(ys), max(xs), max(ys)]
}

/// Draws triangle `t` into the tile: `vs_mesh`'s corners, snapped as the rasteriser does,
/// back faces culled, every covered pixel textured as `fs_mesh` does and keeping the samples
/// its texture alpha covers ([`coverage_mask`]).
pub fn mesh_tri<const N: usize>(
    buf: &mut TileBuf<N>,
    t: &TriRec,
    tex: &Texture,
    fb: &Fb,
    offs: &Offsets<N>,
) {
    let corners = [t.a, t.b, t.c];
    let fl = corners.map(|q| fb.map([q[0], q[1]]));
    let fx = fl.map(|p| p.map(snap));
    let Some(tri) = Poly::<3, N>::new(fx, true, &offs.0) else {
        return;
    };
    let Some((lx0, ly0, lx1, ly1)) = buf.clip(tri.bbox) else {
        return;
    };
    let bary = Bary::new(fl);
    let zp = bary.plane(corners.map(|q| q[2]));
    let z_off = zp.offsets(&offs.1);
    let (us, vs) = (corners.map(|q| q[3]), [t.v[0], t.v[1], t.v[2]]);
    let (step, so) = (tri.step(), tri.sample_offsets());
    for ly in ly0..=ly1 {
        let py = buf.y0 + ly;
        let mut e = tri.edges(buf.x0 + lx0, py);
        for lx in lx0..=lx1 {
            let px = buf.x0 + lx;
            let cov = tri.mask(&e, &so);
            for k in 0..3 {
                e[k] += step[k];
            }
            if cov == 0 {
                continue;
            }
            let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
            let uv = [
                bary.interp(us, cx, cy) as f32,
                bary.interp(vs, cx, cy) as f32,
            ];
            let c = sample_bilinear(tex, uv);
            let cov = cov & coverage_mask(c[3], px, py, N as u32);
            if cov == 0 {
                continue;
            }
            let z = zp.samples(px, py, &z_off);
            buf.write(lx, ly, cov, [c[0], c[1], c[2], 1.0], z);
        }
    }
}

/// The samples `fs_mesh` keeps at pixel (`px`, `py`) for texture alpha `a`: the strands'
/// alpha-to-coverage rule without the strand term (k = floor(a·N + 0.5) samples from
/// r = (px + 2·py) mod N on).
pub fn coverage_mask(a: f32, px: i32, py: i32, n: u32) -> u32 {
    let k = a2c_count(n, a);
    let r = (px as u32).wrapping_add(2u32.wrapping_mul(py as u32)) & (n - 1);
    a2c_mask(n, r, k)
}

/// Screen-linear interpolation over a triangle's float corners (fb px).
struct Bary {
    v0: [f64; 2],
    e1: [f64; 2],
    e2: [f64; 2],
    inv_den: f64,
}

impl Bary {
    fn new(fl: [[f32; 2]; 3]) -> Bary {
        let f = fl.map(|p| p.map(|x| x as f64));
        let e1 = [f[1][0] - f[0][0], f[1][1] - f[0][1]];
        let e2 = [f[2][0] - f[0][0], f[2][1] - f[0][1]];
        let den = e1[0] * e2[1] - e2[0] * e1[1];
        Bary {
            v0: f[0],
            e1,
            e2,
            inv_den: if den != 0.0 { 1.0 / den } else { 0.0 },
        }
    }

    /// The value interpolated from the corners' `val` at (x, y).
    fn interp(&self, val: [f32; 3], x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.v0[0], y - self.v0[1]);
        let l1 = (dx * self.e2[1] - self.e2[0] * dy) * self.inv_den;
        let l2 = (self.e1[0] * dy - dx * self.e1[1]) * self.inv_den;
        let v = val.map(|v| v as f64);
        v[0] + l1 * (v[1] - v[0]) + l2 * (v[2] - v[0])
    }

    /// The same interpolation as a plane.
    fn plane(&self, val: [f32; 3]) -> Plane {
        let c = self.interp(val, 0.0, 0.0);
        Plane {
            c,
            gx: self.interp(val, 1.0, 0.0) - c,
            gy: self.interp(val, 0.0, 1.0) - c,
        }
    }
}

/// Clamp-to-edge bilinear fetch with the f32 operations of `fs_mesh`.
fn sample_bilinear(t: &Texture, uv: [f32; 2]) -> [f32; 4] {
    let s = uv[0] * t.width as f32 - 0.5;
    let r = uv[1] * t.height as f32 - 0.5;
    bilinear_at(t, s, r)
}

//! The CPU mirror's driver: bins the prepared triangles and segments into tiles, clears each
//! tile to the background, draws the mesh then the strands through the per-primitive mirrors
//! in [`crate::stages::mesh_raster`] and [`crate::stages::strand_raster`], and resolves the
//! samples as the GPU's f16 target does.

#![allow(clippy::needless_range_loop)]

use super::Scene;
use crate::base::colour::f16_store;
use crate::stages::mesh_raster::{mesh_tri, tri_bounds};
use crate::stages::raster_common::{sample_offsets, Fb, TileBuf};
use crate::stages::strand_raster::{seg_bounds, strand_quad};
use rayon::prelude::*;

/// CPU tile side in pixels: big enough that few segments straddle two tiles (each is set
/// up once per tile), small enough for a tile's samples (128² x 4 x 20 B) to stay in L2.
const TILE: u32 = 128;

/// Per tile, the indices of the items whose bounds touch it, in input order (the draw
/// order the depth tie rule needs).
fn bin(bounds: &[[f32; 4]], tiles_x: u32, tiles_y: u32) -> Vec<Vec<u32>> {
    let ranges: Vec<[u32; 4]> = bounds
        .par_iter()
        .map(|b| {
            let t = |v: f32, n: u32| ((v / TILE as f32).max(0.0) as u32).min(n - 1);
            [
                t(b[0], tiles_x),
                t(b[1], tiles_y),
                t(b[2], tiles_x),
                t(b[3], tiles_y),
            ]
        })
        .collect();
    let mut bins = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    for (i, r) in ranges.iter().enumerate() {
        for ty in r[1]..=r[3] {
            for tx in r[0]..=r[2] {
                bins[(ty * tiles_x + tx) as usize].push(i as u32);
            }
        }
    }
    bins
}

/// The premultiplied MSAA resolve of the scene, row-major.
pub fn raster(s: &Scene) -> Vec<[f32; 4]> {
    match s.cfg.samples {
        1 => raster_n::<1>(s),
        _ => raster_n::<4>(s),
    }
}

fn raster_n<const N: usize>(s: &Scene) -> Vec<[f32; 4]> {
    let (w, h) = (s.cfg.width, s.cfg.height);
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let half = s.cfg.half_width;
    let seg_bins = bin(
        &s.segs
            .par_iter()
            .map(|q| seg_bounds(q, half))
            .collect::<Vec<_>>(),
        tiles_x,
        tiles_y,
    );
    let tri_bins = bin(
        &s.tris.par_iter().map(tri_bounds).collect::<Vec<_>>(),
        tiles_x,
        tiles_y,
    );
    let tiles: Vec<Vec<[f32; 4]>> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let i = t as usize;
            tile::<N>(s, t % tiles_x, t / tiles_x, &tri_bins[i], &seg_bins[i])
        })
        .collect();
    let mut img = vec![[0.0f32; 4]; w as usize * h as usize];
    for (t, px) in tiles.iter().enumerate() {
        let t = t as u32;
        let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
        let tw = TILE.min(w - x0) as usize;
        for (ly, row) in px.chunks(tw).enumerate() {
            let o = (y0 as usize + ly) * w as usize + x0 as usize;
            img[o..o + tw].copy_from_slice(row);
        }
    }
    img
}

fn tile<const N: usize>(s: &Scene, tx: u32, ty: u32, tris: &[u32], segs: &[u32]) -> Vec<[f32; 4]> {
    let cfg = &s.cfg;
    let (x0, y0) = ((tx * TILE) as i32, (ty * TILE) as i32);
    let tw = (TILE as i32).min(cfg.width as i32 - x0);
    let th = (TILE as i32).min(cfg.height as i32 - y0);
    let npx = (tw * th) as usize;
    let mut buf = TileBuf::<N> {
        x0,
        y0,
        w: tw,
        h: th,
        color: Vec::with_capacity(npx),
        depth: Vec::with_capacity(npx),
    };
    match &s.background {
        Some(bg) => {
            for ly in 0..th {
                let o = ((y0 + ly) as usize) * cfg.width as usize + x0 as usize;
                buf.color
                    .extend(bg[o..o + tw as usize].iter().map(|&c| [c; N]));
            }
        }
        None => buf.color.resize(npx, [[0.0; 4]; N]),
    }
    buf.depth.resize(npx, [1.0; N]);
    let offs = sample_offsets::<N>();
    let fb = Fb::new(cfg);
    if let Some(tex) = &s.texture {
        for &i in tris {
            mesh_tri(&mut buf, &s.tris[i as usize], tex, &fb, &offs);
        }
    }
    for &i in segs {
        strand_quad(
            &mut buf,
            &s.segs[i as usize],
            cfg,
            s.photo.as_ref().filter(|_| cfg.photo != 0),
            &fb,
            &offs,
        );
    }
    // Resolve: f16 samples (the target format), f32 mean, f16 result, as lavapipe.
    let inv = 1.0 / N as f32;
    buf.color
        .iter()
        .map(|px| {
            let mut acc = [0.0f32; 4];
            for c in px {
                for k in 0..4 {
                    acc[k] += f16_store(c[k]);
                }
            }
            acc.map(|v| f16_store(v * inv))
        })
        .collect()
}

//! The CPU mirror's driver: bins the triangles and the strand segments into tiles, clears
//! each tile to the background, draws the mesh then the strands through the per-primitive
//! mirrors in [`crate::stages::mesh_raster`] and [`crate::stages::strand_raster`], and
//! resolves the samples as the GPU's f16 target does.
//!
//! Segments are binned straight from the strands' points, each with its cull record
//! ([`SegCull`]: nearest depth and pixel box), and prepared ([`super::SegSource::seg`]) in
//! each tile that draws them: a segment rarely straddles two tiles, so this costs less than
//! materialising every prepared segment first.
//!
//! Each tile draws its segments front to back (by their nearest depth, bucketed:
//! [`DrawOrder`]), not in input order:
//! with heavy overdraw most later fragments then fail the depth test before they are
//! shaded, and whole segments behind what is drawn are skipped by the depth bounds (with
//! the 2x2 depth blocks, 0.89 -> 0.72 CPU-s per render on the raster bench). The image is the same as in input order,
//! to the bit: an exact depth tie goes to the lower draw rank ([`TileBuf::rank`]), which is
//! what `Less` in input order gives.

#![allow(clippy::needless_range_loop)]

use super::{Scene, SegCull};
use crate::base::colour::f16_store;
use crate::stages::mesh_raster::{mesh_tri, tri_bounds};
use crate::stages::raster_common::{sample_offsets, trunc_i32, Fb, TileBuf};
use crate::stages::strand_raster::{seg_bounds, strand_quad};
use rayon::prelude::*;

/// CPU tile side in pixels: big enough that few segments straddle two tiles (each is set
/// up once per tile; 128 measured 5-8% faster than 64 on the raster bench), while a 1024²
/// frame still has 64 tiles to share between threads.
const TILE: u32 = 128;

/// Segments drawn between refreshes of a tile's depth bounds ([`TileBuf::zmax`]): often
/// enough that hidden segments are skipped soon after what hides them is drawn, rarely
/// enough that the refresh (every sample of the tile) costs little.
const ZMAX_EVERY: u32 = 64;

/// Strands per binning task: each task bins its strands into its own per-tile lists, so the
/// tasks' lists concatenated in task order keep the input (draw) order.
const BIN_STRANDS: usize = 2048;

/// Inclusive tile range `[x0, y0, x1, y1]` of pixel bounds `b`; None when `b` misses the
/// frame (then nothing it bounds can cover a pixel).
#[inline]
fn tile_range(b: [f32; 4], w: u32, h: u32, tiles_x: u32, tiles_y: u32) -> Option<[u32; 4]> {
    if !(b[2] >= 0.0 && b[3] >= 0.0 && b[0] <= w as f32 && b[1] <= h as f32) {
        return None;
    }
    // Times 1/TILE, not divided by TILE: the same value (a power of two), without a divide
    // per segment corner.
    // Clamped in f32, then truncated: the floor of a finite value in range (a NaN bound
    // fails the test above, an infinite one clamps).
    let t = |v: f32, n: u32| trunc_i32((v * (1.0 / TILE as f32)).clamp(0.0, (n - 1) as f32)) as u32;
    Some([
        t(b[0], tiles_x),
        t(b[1], tiles_y),
        t(b[2], tiles_x),
        t(b[3], tiles_y),
    ])
}

/// Per tile, the indices of the triangles whose bounds touch it, in input order.
fn bin_tris(s: &Scene, tiles_x: u32, tiles_y: u32) -> Vec<Vec<u32>> {
    let (w, h) = (s.cfg.width, s.cfg.height);
    let ranges: Vec<Option<[u32; 4]>> = s
        .tris
        .par_iter()
        .map(|t| tile_range(tri_bounds(t), w, h, tiles_x, tiles_y))
        .collect();
    let mut bins = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    for (i, r) in ranges.iter().enumerate() {
        let Some(r) = r else { continue };
        for ty in r[1]..=r[3] {
            for tx in r[0]..=r[2] {
                bins[(ty * tiles_x + tx) as usize].push(i as u32);
            }
        }
    }
    bins
}

/// One binning task's segments of one tile, and the range of their depths.
#[derive(Clone)]
struct Bin {
    segs: Vec<SegCull>,
    /// Least and greatest [`SegCull::z`] in `segs`, NaN left out (+inf and -inf when
    /// there is none): worked out here, where each record is at hand, rather than in a
    /// pass of its own before the tile orders its segments (a serial chain of `min`s that
    /// was 2% of the render).
    z: [f32; 2],
}

impl Default for Bin {
    fn default() -> Bin {
        Bin {
            segs: Vec::new(),
            z: [f32::INFINITY, f32::NEG_INFINITY],
        }
    }
}

/// Per binning task, per tile: the cull record of every segment whose quad may touch the
/// tile, in input order, by [`seg_bounds`] of the raw end points.
fn bin_segs(s: &Scene, tiles_x: u32, tiles_y: u32) -> Vec<Vec<Bin>> {
    let Some(src) = &s.src else {
        return Vec::new();
    };
    let (w, h) = (s.cfg.width, s.cfg.height);
    let half = s.cfg.half_width;
    let n_strands = src.s.counts.len();
    (0..n_strands.div_ceil(BIN_STRANDS))
        .into_par_iter()
        .map(|task| {
            let mut bins = vec![Bin::default(); (tiles_x * tiles_y) as usize];
            let pts = &src.s.points;
            for k in task * BIN_STRANDS..((task + 1) * BIN_STRANDS).min(n_strands) {
                let (a, n) = (src.starts[k], src.s.counts[k] as usize);
                for i in a..(a + n).saturating_sub(1) {
                    let (p, q) = (pts[i], pts[i + 1]);
                    let b = seg_bounds([p[0], p[1]], [q[0], q[1]], half);
                    if !b.iter().all(|v| v.is_finite()) {
                        continue;
                    }
                    let Some(r) = tile_range(b, w, h, tiles_x, tiles_y) else {
                        continue;
                    };
                    let rec = src.cull(i as u32, k as u32, p, q, b);
                    for ty in r[1]..=r[3] {
                        for tx in r[0]..=r[2] {
                            let bin = &mut bins[(ty * tiles_x + tx) as usize];
                            bin.segs.push(rec);
                            // (Plain compares: a NaN depth changes neither.)
                            if rec.z < bin.z[0] {
                                bin.z[0] = rec.z;
                            }
                            if rec.z > bin.z[1] {
                                bin.z[1] = rec.z;
                            }
                        }
                    }
                }
            }
            bins
        })
        .collect()
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
    let (seg_bins, tri_bins) = rayon::join(
        || bin_segs(s, tiles_x, tiles_y),
        || bin_tris(s, tiles_x, tiles_y),
    );
    let mut img = vec![[0.0f32; 4]; w as usize * h as usize];
    let out = ImageRows(img.as_mut_ptr());
    (0..tiles_x * tiles_y).into_par_iter().for_each_init(
        // Sample storage and the draw order reused across a worker's tiles (no page
        // faults per tile).
        || (TileBuf::<N>::default(), DrawOrder::default()),
        |(buf, order), t| {
            let i = t as usize;
            let segs = seg_bins.iter().map(|b| &b[i]);
            let (tx, ty, tris) = (t % tiles_x, t / tiles_x, &tri_bins[i]);
            #[cfg(target_arch = "x86_64")]
            if avx2() {
                // SAFETY: the CPU has the features `tile_avx2` is compiled for.
                unsafe { tile_avx2::<N>(s, buf, order, tx, ty, tris, segs) }
            } else {
                tile::<N>(s, buf, order, tx, ty, tris, segs)
            }
            #[cfg(not(target_arch = "x86_64"))]
            tile::<N>(s, buf, order, tx, ty, tris, segs);
            // Resolved straight into the image, row by row (resolving into a vector per
            // tile and copying the tiles into the image was 2% of the render).
            let (tw, th) = (buf.w as usize, buf.h as usize);
            for ly in 0..th {
                let at = (buf.y0 as usize + ly) * w as usize + buf.x0 as usize;
                // SAFETY: the tiles partition the image, so this row of this tile is
                // written by this worker alone, and it lies in `img` (the tile lies in
                // the frame), which outlives the loop.
                let row = unsafe { out.row(at, tw) };
                resolve(&buf.color[ly * tw..(ly + 1) * tw], row);
            }
        },
    );
    img
}

/// The image's pixels, written by the tile loop's workers each in its own tiles.
struct ImageRows(*mut [f32; 4]);

// SAFETY: the workers write disjoint pixels (see `raster_n`).
unsafe impl Sync for ImageRows {}

impl ImageRows {
    /// Pixels `at..at + len` of the image.
    /// SAFETY: they lie in the image, which is alive, and no one else touches them meanwhile.
    #[allow(clippy::mut_from_ref)]
    unsafe fn row(&self, at: usize, len: usize) -> &mut [[f32; 4]] {
        // SAFETY: as the caller promises.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(at), len) }
    }
}

/// How many segments ahead of the one drawn the tile loop prefetches.
const PREFETCH_AHEAD: usize = 8;

/// Depth buckets of [`DrawOrder`]: fine enough that a bucket's segments lie within ~1/4096
/// of the tile's depth range of each other (nearly sorted is as good as sorted for the
/// depth test), few enough that clearing the counts costs nothing.
const DEPTH_BUCKETS: usize = 4096;

/// A tile's segments front to back, by a counting sort of their nearest depth
/// ([`SegCull::z`]) into [`DEPTH_BUCKETS`] (a comparison sort of the exact depths was 5%
/// of the profile, with no fewer fragments shaded). Scratch reused across a worker's tiles.
#[derive(Default)]
struct DrawOrder {
    counts: Vec<u32>,
    sorted: Vec<SegCull>,
}

impl DrawOrder {
    /// The segments of `segs` nearest first, by [`SegCull::z`] (depth-buffer units, smaller
    /// = nearer: the nearer end's depth less a margin, which orders the prepared segments
    /// well enough); any order gives the same image.
    fn front_to_back<'b>(&mut self, bins: impl Iterator<Item = &'b Bin> + Clone) -> &[SegCull] {
        let (mut lo, mut hi, mut n) = (f32::INFINITY, f32::NEG_INFINITY, 0);
        for b in bins.clone() {
            lo = lo.min(b.z[0]);
            hi = hi.max(b.z[1]);
            n += b.segs.len();
        }
        let segs = bins.map(|b| b.segs.as_slice());
        // Nearest (smallest z) in bucket 0; NaN depths (never skipped, rarely drawn) in the
        // last one (the truncation gives i32::MIN for NaN).
        let scale = if hi > lo {
            (DEPTH_BUCKETS - 1) as f32 / (hi - lo)
        } else {
            0.0
        };
        let bucket = |z: f32| (trunc_i32((z - lo) * scale) as u32 as usize).min(DEPTH_BUCKETS - 1);
        self.counts.clear();
        self.counts.resize(DEPTH_BUCKETS + 1, 0);
        for c in segs.clone().flatten() {
            self.counts[bucket(c.z) + 1] += 1;
        }
        for b in 1..=DEPTH_BUCKETS {
            self.counts[b] += self.counts[b - 1];
        }
        self.sorted.clear();
        let blank = SegCull {
            i: 0,
            k: 0,
            z: 0.0,
            lo: [0; 2],
            hi: [0; 2],
        };
        self.sorted.resize(n, blank);
        for c in segs.flatten() {
            let at = &mut self.counts[bucket(c.z)];
            self.sorted[*at as usize] = *c;
            *at += 1;
        }
        &self.sorted
    }
}

#[cfg(target_arch = "x86_64")]
use crate::stages::raster_common::has_avx2 as avx2;

/// [`tile`] compiled for AVX2: the same arithmetic (Rust never fuses a multiply and an
/// add on its own, so the image is bit-identical), with wider vectors for the sample
/// tests and native rounding instead of libm calls.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,popcnt,lzcnt")]
unsafe fn tile_avx2<'b, const N: usize>(
    s: &Scene,
    buf: &mut TileBuf<N>,
    order: &mut DrawOrder,
    tx: u32,
    ty: u32,
    tris: &[u32],
    segs: impl Iterator<Item = &'b Bin> + Clone,
) {
    tile::<N>(s, buf, order, tx, ty, tris, segs)
}

#[inline(always)]
fn tile<'b, const N: usize>(
    s: &Scene,
    buf: &mut TileBuf<N>,
    order: &mut DrawOrder,
    tx: u32,
    ty: u32,
    tris: &[u32],
    segs: impl Iterator<Item = &'b Bin> + Clone,
) {
    let cfg = &s.cfg;
    let (x0, y0) = ((tx * TILE) as i32, (ty * TILE) as i32);
    let tw = (TILE as i32).min(cfg.width as i32 - x0);
    let th = (TILE as i32).min(cfg.height as i32 - y0);
    let npx = (tw * th) as usize;
    buf.reset(x0, y0, tw, th);
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
    let offs = sample_offsets::<N>();
    let fb = Fb::new(cfg);
    if let Some(tex) = &s.texture {
        for &i in tris {
            mesh_tri(buf, &s.tris[i as usize], tex, &fb, &offs);
        }
    }
    if let Some(src) = &s.src {
        let photo = s.photo.as_ref().filter(|_| cfg.photo != 0);
        // Front to back (see `DrawOrder`); any order gives the same image.
        let mut since = ZMAX_EVERY;
        let sorted = order.front_to_back(segs);
        for (n, c) in sorted.iter().enumerate() {
            if let Some(ahead) = sorted.get(n + PREFETCH_AHEAD) {
                src.prefetch(ahead.i as usize);
            }
            if since == ZMAX_EVERY {
                buf.refresh_zmax();
                since = 0;
            }
            since += 1;
            if c.hidden(buf) {
                continue;
            }
            if let Some(seg) = src.seg(c.i as usize, c.k) {
                strand_quad(buf, &seg, cfg, photo, &fb, &offs, c.i + 1);
            }
        }
    }
}

/// The MSAA resolve: f16 samples (the target format), their f32 mean, an f16 result, as
/// lavapipe does. On x86-64 with F16C the conversions are the hardware's, four channels at
/// a time (the same values: see [`resolve_f16c`]).
fn resolve<const N: usize>(color: &[[[f32; 4]; N]], out: &mut [[f32; 4]]) {
    #[cfg(target_arch = "x86_64")]
    if f16c() {
        // SAFETY: the CPU has the features `resolve_f16c` is compiled for.
        return unsafe { resolve_f16c(color, out) };
    }
    resolve_plain(color, out)
}

/// [`resolve`] in plain Rust, through `f16_store`.
fn resolve_plain<const N: usize>(color: &[[[f32; 4]; N]], out: &mut [[f32; 4]]) {
    let inv = 1.0 / N as f32;
    for (px, o) in color.iter().zip(out) {
        // Every sample alike (no edge crosses the pixel; most pixels): the mean of N equal
        // f16 values is that value, exactly (N·v needs at most 2 more bits than v has, and
        // times 1/N is exact), so the sum is skipped. Bitwise equal, so -0 and +0 differ.
        let first = px[0].map(f32::to_bits);
        if px.iter().all(|c| c.map(f32::to_bits) == first) {
            *o = px[0].map(f16_store);
            continue;
        }
        // From -0, the one zero that adding leaves alone: a sum of samples that are all -0
        // stays -0, as the shortcut above gives.
        let mut acc = [-0.0f32; 4];
        for c in px {
            for k in 0..4 {
                acc[k] += f16_store(c[k]);
            }
        }
        for v in &mut acc {
            *v = f16_store(*v * inv);
        }
        *o = acc;
    }
}

/// Whether the F16C resolve can run here (checked once; `COIF_NO_AVX2=1` turns it off
/// with the AVX2 tile loop).
#[cfg(target_arch = "x86_64")]
fn f16c() -> bool {
    static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAS.get_or_init(|| avx2() && std::arch::is_x86_feature_detected!("f16c"))
}

/// [`resolve`] with F16C: `f16_store` is a conversion to f16 rounding toward zero and back
/// (`vcvtps2ph` with rounding 3, which keeps -0 and subnormals as the software does), the
/// input clamped to ±65504 first as the software clamps, and a NaN channel its own quiet
/// NaN, as the software's arithmetic leaves it (the conversion would cut its payload).
/// Every pixel takes the one branch-free path (the same value as the plain path's
/// shortcut), the samples summed in the same order from the same -0.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
unsafe fn resolve_f16c<const N: usize>(color: &[[[f32; 4]; N]], out: &mut [[f32; 4]]) {
    use std::arch::x86_64::*;
    let (lo, hi) = (_mm_set1_ps(-65504.0), _mm_set1_ps(65504.0));
    let store = |v: __m128| {
        // Clamped first: the conversion keeps an infinity, `f16_store` gives ±65504.
        let c = _mm_max_ps(_mm_min_ps(v, hi), lo);
        let r = _mm_cvtph_ps(_mm_cvtps_ph::<_MM_FROUND_TO_ZERO>(c));
        _mm_blendv_ps(r, _mm_add_ps(v, v), _mm_cmpunord_ps(v, v))
    };
    let inv = _mm_set1_ps(1.0 / N as f32);
    // (Both slices are a row of the tile; `zip` keeps to the shorter anyway.)
    for (px, o) in color.iter().zip(out) {
        let mut acc = _mm_set1_ps(-0.0);
        for c in px {
            // SAFETY: `c` is 4 f32s; unaligned load.
            acc = _mm_add_ps(acc, store(unsafe { _mm_loadu_ps(c.as_ptr()) }));
        }
        // SAFETY: `o` is 4 f32s; unaligned store.
        unsafe { _mm_storeu_ps(o.as_mut_ptr(), store(_mm_mul_ps(acc, inv))) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plain_vec<const N: usize>(px: &[[[f32; 4]; N]]) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0; 4]; px.len()];
        resolve_plain(px, &mut out);
        out
    }

    /// (Unsafe: needs F16C.)
    unsafe fn f16c_vec<const N: usize>(px: &[[[f32; 4]; N]]) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0; 4]; px.len()];
        // SAFETY: the caller checked the CPU.
        unsafe { resolve_f16c(px, &mut out) };
        out
    }

    /// The F16C resolve gives the plain one's values to the bit, the awkward ones included:
    /// ±0, subnormal f16 and f32, values that truncate, overflow, infinities and NaN.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn f16c_resolve_matches_the_plain_one() {
        if !f16c() {
            eprintln!("no F16C here: nothing to compare");
            return;
        }
        let special = [
            0.0f32,
            -0.0,
            1.0,
            0.999_999,
            1.0e-5,
            -3.0e-6,
            6.1e-5,
            6.103_515_6e-5,
            1.0e-40,
            65504.0,
            65519.0,
            -7.0e4,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::from_bits(0x7fa0_1234),
            0.333_333_34,
            0.1,
        ];
        let mut state = 0x9e37_79b9u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let mut pick = || -> f32 {
            let r = next();
            if r % 3 == 0 {
                special[(r / 3) as usize % special.len()]
            } else {
                (r >> 8) as f32 / (1u32 << 24) as f32 * 1.2 - 0.1
            }
        };
        let px4: Vec<[[f32; 4]; 4]> = (0..4000)
            .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| pick())))
            .collect();
        let px1: Vec<[[f32; 4]; 1]> = px4.iter().map(|p| [p[0]]).collect();
        let bits = |v: Vec<[f32; 4]>| -> Vec<[u32; 4]> {
            v.into_iter().map(|p| p.map(f32::to_bits)).collect()
        };
        // SAFETY: `f16c()` said the CPU has the features.
        let (fast4, fast1) = unsafe { (f16c_vec(&px4), f16c_vec(&px1)) };
        let first_diff = |a: Vec<[u32; 4]>, b: Vec<[u32; 4]>, px: &[[[f32; 4]; 4]]| {
            let i = a.iter().zip(&b).position(|(x, y)| x != y);
            i.map(|i| format!("pixel {i}: {:x?} vs {:x?} from {:?}", a[i], b[i], px[i]))
        };
        let px1_as4: Vec<[[f32; 4]; 4]> = px1.iter().map(|p| [p[0]; 4]).collect();
        assert_eq!(first_diff(bits(fast4), bits(plain_vec(&px4)), &px4), None);
        assert_eq!(
            first_diff(bits(fast1), bits(plain_vec(&px1)), &px1_as4),
            None
        );
        // And the comparison can fail: a one-ulp change shows.
        let mut off = plain_vec(&px4);
        off[7][1] = f32::from_bits(off[7][1].to_bits() ^ 1);
        assert_ne!(bits(off), bits(plain_vec(&px4)));
    }
}

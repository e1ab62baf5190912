//! Strand quads (`wgsl/render/strand_raster.wgsl`): the CPU mirror of `vs_main` (corner
//! construction, depth plane, photo points) and `fs_main` (colour at the pixel centre, photo
//! colour and HSV adjustment, explicit alpha-to-coverage) for one segment in one tile.

#![allow(clippy::needless_range_loop)]

use crate::gpu::engine::RenderStageDef;
use crate::render::raster::Texture;
#[cfg(target_arch = "x86_64")]
use crate::stages::raster_common::has_avx2;
use crate::stages::raster_common::{
    a2c_count, a2c_mask, bilinear_at, mask32, snap, trunc_i32, Config, Fb, Narrow, Offsets, Plane,
    Poly, TileBuf, DEPTH_ROUNDING, SUBPIXEL,
};

/// Entry points (vertex, fragment) of the strand pipeline.
pub const STRANDS: (&str, &str) = ("vs_main", "fs_main");

pub const STAGE: RenderStageDef = RenderStageDef {
    name: "strand_raster",
    wgsl: include_str!("../../wgsl/render/strand_raster.wgsl"),
    entry_points: &[STRANDS],
    compute: &[],
    int64_atomics: false,
};

/// The same strands as compute passes (`wgsl/render/strand_vis.wgsl`): the GPU path for
/// 4x MSAA frames; its coverage, alpha-to-coverage, depth and colour are [`strand_quad`]'s,
/// which is therefore its CPU mirror too (`src/render/raster/gpu.rs` says when it is used).
pub const VIS: RenderStageDef = RenderStageDef {
    name: "strand_vis",
    wgsl: include_str!("../../wgsl/render/strand_vis.wgsl"),
    entry_points: &[],
    compute: &["zinit", "depth", "pick", "colour", "resolve", "shade"],
    int64_atomics: false,
};

/// [`VIS`] with its `depth` and `pick` in one walk, by 64-bit atomic minima
/// (`wgsl/render/strand_vis64.wgsl`), for devices that have them: the same image.
pub const VIS64: RenderStageDef = RenderStageDef {
    name: "strand_vis64",
    wgsl: include_str!("../../wgsl/render/strand_vis64.wgsl"),
    entry_points: &[],
    compute: &["zinit", "depth", "colour", "resolve", "shade"],
    int64_atomics: true,
};

/// One strand segment as both paths see it (the WGSL `Seg`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SegRec {
    pub p0: [f32; 2],
    pub p1: [f32; 2],
    /// Depth-buffer values in [0, 1] (0 = near); may lie outside, then clipped.
    pub z0: f32,
    pub z1: f32,
    pub strand: u32,
    /// Free for the GPU host: the compute walks keep the segment's index within its chunk here
    /// (they run a chunk in their own order); 0 elsewhere.
    pub local: u32,
    pub c0: [f32; 4],
    pub c1: [f32; 4],
    /// Photo points of the two ends (o0.xy, o1.xy); zero without a photo.
    pub o: [f32; 4],
}

/// Conservative pixel bounding box of the quad of the segment p0 p1 (for binning only): its
/// corners lie within half·√2 of the end points, plus rounding and snapping. Clipping only
/// shrinks a segment, so the raw end points bound the prepared segment too.
#[inline]
pub fn seg_bounds(p0: [f32; 2], p1: [f32; 2], half: f32) -> [f32; 4] {
    let m = half * 1.415 + 0.01;
    [
        p0[0].min(p1[0]) - m,
        p0[1].min(p1[1]) - m,
        p0[0].max(p1[0]) + m,
        p0[1].max(p1[1]) + m,
    ]
}

/// Draws segment `s`, of draw rank `rank` (see [`TileBuf::rank`]), into the tile: the corners `vs_main` builds, snapped as the rasteriser
/// does, the quad's coverage, and every covered pixel shaded as `fs_main` ([`Shade`] below).
/// (Inlined into the tile loop, which has an AVX2 build.)
#[inline(always)]
pub fn strand_quad<const N: usize>(
    buf: &mut TileBuf<N>,
    s: &SegRec,
    cfg: &Config,
    photo: Option<&Texture>,
    fb: &Fb,
    offs: &Offsets<N>,
    rank: u32,
) {
    // The vertex shader's corner construction, operation for operation.
    let h = cfg.half_width;
    let d = [s.p1[0] - s.p0[0], s.p1[1] - s.p0[1]];
    let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
    let u = [d[0] / len, d[1] / len];
    let e = [u[0] * h, u[1] * h];
    let nn = [-u[1] * h, u[0] * h];
    let start = [s.p0[0] - e[0], s.p0[1] - e[1]];
    let end = [s.p1[0] + e[0], s.p1[1] + e[1]];
    // A, B, C, D = start+, start-, end+, end-; the GPU draws triangles ABC and CBD.
    let corner = |p: [f32; 2], sign: f32| {
        let q = fb.map([p[0] + sign * nn[0], p[1] + sign * nn[1]]);
        [snap(q[0]), snap(q[1])]
    };
    let (qa, qb, qc, qd) = (
        corner(start, 1.0),
        corner(start, -1.0),
        corner(end, 1.0),
        corner(end, -1.0),
    );
    // Pixel of a snapped corner: floor(v / 256), an arithmetic shift.
    let mut bbox = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
    for p in [qa, qb, qc, qd] {
        let (x, y) = ((p[0] >> 8) as i32, (p[1] >> 8) as i32);
        bbox = [
            bbox[0].min(x),
            bbox[1].min(y),
            bbox[2].max(x),
            bbox[3].max(y),
        ];
    }
    let Some((lx_min, ly0, lx_max, ly1)) = buf.clip(bbox) else {
        return;
    };
    let samples_kept = a2c_samples_everywhere::<N>(s.c0[3], s.c1[3]);
    if samples_kept == Some(0) {
        // Alpha-to-coverage keeps no sample anywhere on the quad: it draws nothing.
        return;
    }
    // Depth: one plane over the quad, z0 along the start cap's edge to z1 along the end
    // cap's edge (what the GPU interpolates from the corners), in screen px.
    let (gz, zl) = ((s.z1 - s.z0) as f64, (len + 2.0 * h) as f64);
    // So the quad's depth lies between z0 and z1, give or take its slope times the 1/256 px
    // the corners were snapped by: a segment behind everything already drawn where it lands
    // is skipped before the rest of the set-up.
    let z_near = s.z0.min(s.z1) - (gz.abs() / zl) as f32 * 0.01;
    if buf.hidden(lx_min, ly0, lx_max, ly1, z_near) {
        return;
    }
    let (ux, uy) = (u[0] as f64 * gz / zl, u[1] as f64 * gz / zl);
    let zp = Plane {
        c: s.z0 as f64 - ux * start[0] as f64 - uy * start[1] as f64,
        gx: ux,
        gy: uy,
    };
    let z_off = zp.offsets(&offs.1);
    // Row spans from the two long sides A->C and B->D: when both run the same way in y,
    // every point of the quad lies between them, so a row's columns are bounded by the
    // sides' x at the row's top and bottom. Otherwise (sides near horizontal, where
    // snapping may tilt them apart) the bounding box is used.
    // Tile-local px in f32: exact for the snapped corners, and the spans only need to
    // contain the covered pixels (a margin absorbs rounding; coverage is decided exactly).
    let (ox, oy) = (buf.x0 as i64 * 256, buf.y0 as i64 * 256);
    let to_px = |q: [i64; 2]| [(q[0] - ox) as f32 / SUBPIXEL, (q[1] - oy) as f32 / SUBPIXEL];
    let (a, b, c, dd) = (to_px(qa), to_px(qb), to_px(qc), to_px(qd));
    let (dy_ac, dy_bd) = (qc[1] - qa[1], qd[1] - qb[1]);
    let by_sides = (dy_ac > 0 && dy_bd > 0) || (dy_ac < 0 && dy_bd < 0);
    let mut spans = Spans::new(
        by_sides,
        (a[0], a[1], (c[0] - a[0]) / (c[1] - a[1])),
        (b[0], b[1], (dd[0] - b[0]) / (dd[1] - b[1])),
        ly0,
    );
    let shade = Shade {
        p0: s.p0,
        d,
        inv_len2: 1.0 / (len * len),
        c0: s.c0,
        c1: s.c1,
        strand: s.strand,
        rank,
        zp,
        z_off,
        z_near,
        samples_kept,
        photo: photo.map(|tex| {
            let o0 = [s.o[0], s.o[1]];
            let od = [s.o[2] - s.o[0], s.o[3] - s.o[1]];
            let ol = (od[0] * od[0] + od[1] * od[1]).sqrt();
            let hp = cfg.photo_half_width;
            let on = if ol > 1e-6 {
                [-od[1] / ol * hp, od[0] / ol * hp]
            } else {
                [0.0; 2]
            };
            PhotoShade {
                tex,
                o0,
                od,
                on,
                nl: [nn[0] / (h * h), nn[1] / (h * h)],
                hsv: (cfg.photo == 2).then_some([cfg.hue_deg, cfg.saturation, cfg.value]),
            }
        }),
    };
    let (rows, cols) = ((ly0, ly1), (lx_min, lx_max));
    // The quad A C D B as one convex polygon covers exactly the samples of ABC ∪ CBD:
    // the top-left rule equals nudging a sample by (ε, ε²) and testing strictly, and the
    // nudged sample never lies on the diagonal, so it is in the quad iff it is in one of
    // the triangles. That needs a convex quad; snapping can break it for very thin quads,
    // and then the two triangles are used.
    let convex = {
        let ring = [qa, qc, qd, qb];
        let turns: [i64; 4] = std::array::from_fn(|k| {
            let (p, q, r) = (ring[k], ring[(k + 1) % 4], ring[(k + 2) % 4]);
            (q[0] - p[0]) * (r[1] - q[1]) - (q[1] - p[1]) * (r[0] - q[0])
        });
        turns.iter().all(|&t| t > 0) || turns.iter().all(|&t| t < 0)
    };
    if convex {
        if let Some(quad) = Poly::<4, N>::new([qa, qc, qd, qb], false, &offs.0) {
            if narrow(bbox) {
                scan_quad_best(buf, &quad, rows, cols, &mut spans, &shade);
            } else {
                scan(buf, &[quad], bbox, rows, cols, &mut spans, &shade);
            }
        }
    } else {
        let tris: Vec<Poly<3, N>> = [[qa, qb, qc], [qc, qb, qd]]
            .into_iter()
            .filter_map(|t| Poly::new(t, false, &offs.0))
            .collect();
        scan(buf, &tris, bbox, rows, cols, &mut spans, &shade);
    }
}

/// Alpha-to-coverage's sample count `floor(clamp(alpha)·N + 0.5)` (see `Shade::pixel`)
/// when it is the same at every pixel of a segment whose ends have alphas `a0`, `a1`:
/// a pixel's alpha is their lerp, which lies between them give or take a few ulps (under
/// 1e-6 for alphas in [-1, 2]), and the count never decreases with alpha, so it is that
/// of both ends widened by 4e-6 when those agree. None otherwise (then each pixel works
/// its own out). Most segments have one count: alpha changes little along one.
#[inline(always)]
fn a2c_samples_everywhere<const N: usize>(a0: f32, a1: f32) -> Option<u32> {
    let (lo, hi) = if a0 < a1 { (a0, a1) } else { (a1, a0) };
    // (Also false for NaN.)
    if !(lo >= -1.0 && hi <= 2.0) {
        return None;
    }
    let k = a2c_count(N as u32, lo - 4e-6);
    (k == a2c_count(N as u32, hi + 4e-6)).then_some(k)
}

/// Row spans of a quad from its two long sides A->C and B->D (see `strand_quad`), in tile
/// pixels. Rows are asked for one by one from the first (`Spans::new`'s `ly0`) down, so
/// each side's x at a row's bottom is kept as the next row's top.
struct Spans {
    by_sides: bool,
    /// Per side: x and y of its first corner (tile px) and its slope dx/dy.
    ac: (f32, f32, f32),
    bd: (f32, f32, f32),
    /// x of A->C and of B->D at the top of the next row.
    top: (f32, f32),
}

impl Spans {
    #[inline]
    fn x(side: (f32, f32, f32), y: f32) -> f32 {
        side.0 + side.2 * (y - side.1)
    }

    fn new(by_sides: bool, ac: (f32, f32, f32), bd: (f32, f32, f32), ly0: i32) -> Spans {
        let y0 = ly0 as f32;
        let top = if by_sides {
            (Self::x(ac, y0), Self::x(bd, y0))
        } else {
            (0.0, 0.0)
        };
        Spans {
            by_sides,
            ac,
            bd,
            top,
        }
    }

    /// Tile columns that may hold covered pixels of tile row `ly`, within `cols`.
    #[inline]
    fn row(&mut self, ly: i32, cols: (i32, i32)) -> (i32, i32) {
        if !self.by_sides {
            return cols;
        }
        let y1 = (ly + 1) as f32;
        let (t_ac, t_bd) = self.top;
        let (b_ac, b_bd) = (Self::x(self.ac, y1), Self::x(self.bd, y1));
        self.top = (b_ac, b_bd);
        // f32 error here is below 1e-3 px even 16k px from the tile; 0.02 px is ample.
        // Plain compares, not `f32::min`/`max`: the values are finite (both sides have
        // dy != 0), so the NaN handling those add on every row buys nothing.
        let (mn, mx) = (
            |a: f32, b: f32| if b < a { b } else { a },
            |a: f32, b: f32| if b > a { b } else { a },
        );
        // Clamped to the columns first, so that truncation is the floor (of a finite value
        // in range): the left end is >= cols.0 >= 0, the right end >= -1 (an empty row).
        let lo = mx(mn(mn(t_ac, b_ac), mn(t_bd, b_bd)) - 0.02, cols.0 as f32);
        let hi = mx(
            mn(mx(mx(t_ac, b_ac), mx(t_bd, b_bd)) + 0.02, cols.1 as f32),
            -1.0,
        );
        (trunc_i32(lo), trunc_i32(hi + 1.0) - 1)
    }
}

/// Polygons up to 64 px a side keep every edge value at their pixels within ±2^31
/// (|a|, |b| <= 64·256 and offsets <= 66·256 from the edge), so they run in i32.
#[inline]
fn narrow(bbox: [i32; 4]) -> bool {
    bbox[2] - bbox[0] <= 64 && bbox[3] - bbox[1] <= 64
}

/// Sample lanes [`scan_quad`] tests at once: `LANES / N` pixels of N samples each.
const LANES: usize = 8;

/// Bit l set when lane l of `or` is not negative. SSE2's sign-bit gather on x86-64: the
/// compiler does not find it for the plain loop on 8 lanes (in the profile that loop cost
/// more than the edge values it tests).
#[inline(always)]
fn inside_lanes(or: &[i32; LANES]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86-64; the loads read the 8 i32 of `or`, unaligned.
        let signs = unsafe {
            let lo = _mm_loadu_si128(or.as_ptr().cast());
            let hi = _mm_loadu_si128(or.as_ptr().add(4).cast());
            _mm_movemask_ps(_mm_castsi128_ps(lo)) | (_mm_movemask_ps(_mm_castsi128_ps(hi)) << 4)
        };
        !(signs as u32) & 0xff
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut bits = 0u32;
        for l in 0..LANES {
            bits |= ((or[l] >= 0) as u32) << l;
        }
        bits
    }
}

/// [`scan_quad`] compiled for AVX2 where the CPU has it, else as is; either way a function
/// of its own, not inlined into the tile loop: in that loop's one large function most of
/// the scan's values lived on the stack (register allocation over the whole tile loop),
/// here they stay in registers.
#[inline(always)]
fn scan_quad_best<const N: usize>(
    buf: &mut TileBuf<N>,
    quad: &Poly<4, N>,
    rows: (i32, i32),
    cols: (i32, i32),
    spans: &mut Spans,
    shade: &Shade<N>,
) {
    #[cfg(target_arch = "x86_64")]
    if N == 4 && has_avx2() && !forced_plain() {
        // SAFETY: the CPU has the features `scan_quad_avx2` is compiled for.
        // (Four builds: all of a quad's columns in one window or not, and one
        // alpha-to-coverage count over the quad or not.)
        return unsafe {
            match (cols.1 - cols.0 < 4, shade.samples_kept.is_some()) {
                (true, true) => {
                    scan_quad_avx2::<N, true, true>(buf, quad, rows, cols, spans, shade)
                }
                (true, false) => {
                    scan_quad_avx2::<N, true, false>(buf, quad, rows, cols, spans, shade)
                }
                (false, true) => {
                    scan_quad_avx2::<N, false, true>(buf, quad, rows, cols, spans, shade)
                }
                (false, false) => {
                    scan_quad_avx2::<N, false, false>(buf, quad, rows, cols, spans, shade)
                }
            }
        };
    }
    scan_quad(buf, quad, rows, cols, spans, shade)
}

/// Per 4-bit mask of a window's pixels with coverage, the lanes of those pixels in order
/// then the rest (`_mm_permutevar_ps` indices): a compressing store of the fragment list.
const COMPRESS4: [[i32; 4]; 16] = {
    let mut t = [[0i32; 4]; 16];
    let mut m = 0;
    while m < 16 {
        let (mut k, mut j) = (0, 0i32);
        while j < 4 {
            if m & (1 << j) != 0 {
                t[m][k] = j;
                k += 1;
            }
            j += 1;
        }
        while k < 4 {
            t[m][k] = 3;
            k += 1;
        }
        m += 1;
    }
    t
};

/// Most fragments a narrow quad can list at 4x MSAA: 4 per 4-pixel window, at most
/// ⌈65 / 4⌉ windows a row (a narrow quad spans at most 65 columns and 65 rows).
const MAX_FRAGS: usize = 4 * 17 * 65;

#[cfg(test)]
thread_local! {
    /// Tests set it to draw with `scan_quad` where `scan_quad_avx2` would run.
    static FORCE_PLAIN: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

#[inline(always)]
fn forced_plain() -> bool {
    #[cfg(test)]
    return FORCE_PLAIN.with(|f| f.get());
    #[cfg(not(test))]
    false
}

/// [`scan_quad`] at 4x MSAA with AVX2 intrinsics, in two passes. First the coverage: each
/// row's span in windows of four pixels (usually one window: a 1 px strand's rows are a
/// few pixels long), per edge two registers of the window's 16 sample values, inside and
/// not yet nearer (the same depth filter as `scan_quad`) by an AND-NOT and two sign-bit
/// gathers, and every pixel with a sample left appended to a list without a branch. Then
/// the listed pixels are shaded in the same order as `scan_quad` visits them. The same
/// tests on the same i32 and f32 values, so the same bits. The branches of `scan_quad`'s
/// loops (a trip count per row and per group that no predictor guesses) cost it more than
/// its arithmetic did. `ONE`: every column of the quad lies in one window, so each row runs
/// exactly that window (a build of its own: with both loops in one function the scan ran
/// slower, and separately this one saved ~2.5% of the render).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,popcnt,lzcnt")]
#[inline(never)]
unsafe fn scan_quad_avx2<const N: usize, const ONE: bool, const KEPT: bool>(
    buf: &mut TileBuf<N>,
    quad: &Poly<4, N>,
    rows: (i32, i32),
    cols: (i32, i32),
    spans: &mut Spans,
    shade: &Shade<N>,
) {
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;
    // Written for 4 samples a pixel (the caller checks): 8 lanes are two pixels.
    assert_eq!(N, 4);
    let (so, st, sr) = quad.narrow();
    // Lanes of pixels 0-1 and 2-3 of a window: sample offset plus the pixel's steps right
    // (built in registers: from arrays, lane by lane, they were a tenth of the set-up).
    let lo: [__m256i; 4] = std::array::from_fn(|k| {
        // SAFETY: `so[k]` is 4 i32s (N = 4); unaligned load.
        let s = unsafe { _mm_loadu_si128(so[k].as_ptr().cast()) };
        let next = _mm_add_epi32(s, _mm_set1_epi32(st[k]));
        _mm256_set_m128i(next, s)
    });
    let hi: [__m256i; 4] =
        std::array::from_fn(|k| _mm256_add_epi32(lo[k], _mm256_set1_epi32(st[k].wrapping_mul(2))));
    let window: [i32; 4] = std::array::from_fn(|k| st[k].wrapping_mul(4));
    let z_far = _mm256_set1_ps(shade.z_near - DEPTH_ROUNDING);
    let mut frags = [MaybeUninit::<u32>::uninit(); MAX_FRAGS];
    let mut n = 0usize;
    let (j4, nibble) = (_mm_set_epi32(3, 2, 1, 0), _mm_set_epi32(12, 8, 4, 0));
    let low4 = _mm_set1_epi32(0xf);
    // `KEPT`: alpha-to-coverage keeps the same number of samples at every pixel, so the
    // samples it keeps at a window's four pixels depend only on the first one's rotation
    // r (see `Shade::pixel`): dropped here per window, before the pixels are listed, and
    // not per listed pixel (a third of them kept nothing).
    let kept: [u32; 4] = std::array::from_fn(|r0| {
        let k = shade.samples_kept.unwrap_or(N as u32);
        (0..4).fold(0, |m, j| {
            m | (a2c_mask(4, (r0 as u32 + j) & 3, k) << (4 * j))
        })
    });
    // The rotation of tile pixel (lx, ly) is (r_tile + lx + 2 ly) mod 4.
    let r_tile = (buf.x0 as u32)
        .wrapping_add(2u32.wrapping_mul(buf.y0 as u32))
        .wrapping_add(shade.strand);
    let kept_at = |lx: i32, ly: i32| {
        if KEPT {
            let r = r_tile.wrapping_add(lx as u32).wrapping_add(2 * ly as u32);
            kept[(r & 3) as usize]
        } else {
            u32::MAX
        }
    };
    // One window: the samples of the four pixels from (lx, ly), whose edge values at the
    // first of them are `base`, inside the quad and not yet nearer, for the pixels `wanted`
    // (a nibble each), appended to the list. (A macro, so that each loop below has it
    // inline; as a closure the scan ran a quarter slower.)
    macro_rules! window {
        ($base:expr, $row_start:expr, $lx:expr, $ly:expr, $wanted:expr) => {{
            let (base, lx, ly): (&[i32; 4], i32, i32) = ($base, $lx, $ly);
            let v = |lanes: &[__m256i; 4]| {
                let at = |k: usize| _mm256_add_epi32(_mm256_set1_epi32(base[k]), lanes[k]);
                _mm256_castsi256_ps(_mm256_or_si256(
                    _mm256_or_si256(at(0), at(1)),
                    _mm256_or_si256(at(2), at(3)),
                ))
            };
            let (or_lo, or_hi) = (v(&lo), v(&hi));
            // The window's depths (the buffer is padded past the tile's last pixel).
            let i = $row_start + lx as usize;
            let depth = &buf.depth[i..i + 4].as_flattened()[..16];
            // SAFETY: `depth` holds 16 f32s; unaligned loads of 8 each.
            let (d_lo, d_hi) = unsafe {
                (
                    _mm256_loadu_ps(depth.as_ptr()),
                    _mm256_loadu_ps(depth.as_ptr().add(8)),
                )
            };
            let keep = |or: __m256, d: __m256| {
                _mm256_movemask_ps(_mm256_andnot_ps(or, _mm256_cmp_ps::<_CMP_GT_OQ>(d, z_far)))
                    as u32
            };
            let bits = (keep(or_lo, d_lo) | (keep(or_hi, d_hi) << 8)) & $wanted;
            // The window's four fragments (pixel, row, coverage) side by side, those with
            // coverage moved to the front by a permutation from a table and stored as one
            // vector; the count advances by how many there were. (Four scalar appends cost
            // about 50 instructions a window, a tenth of the render's.)
            let at = _mm_add_epi32(_mm_set1_epi32((lx as u32 | ((ly as u32) << 12)) as i32), j4);
            let cov = _mm_and_si128(_mm_srlv_epi32(_mm_set1_epi32(bits as i32), nibble), low4);
            let f = _mm_or_si128(at, _mm_slli_epi32::<24>(cov));
            // Which pixels have coverage, from `bits` in scalar code: the count feeds the
            // next store's address, and taken from the vector instead it made the render 7%
            // slower.
            let t = bits | (bits >> 1);
            let t = (t | (t >> 2)) & 0x1111;
            let some = _pext_u32(t, 0x1111) as usize;
            let order = _mm_loadu_si128(COMPRESS4[some].as_ptr().cast());
            let packed = _mm_permutevar_ps(_mm_castsi128_ps(f), order);
            // SAFETY: n <= 4 x the windows before this one, so n + 4 <= MAX_FRAGS; the
            // entries past the new count are written but not counted (overwritten later).
            unsafe { _mm_storeu_ps(frags.as_mut_ptr().add(n).cast(), packed) };
            n += t.count_ones() as usize;
        }};
    }
    let mut row = quad.edges32(buf.x0 + cols.0, buf.y0 + rows.0);
    if ONE {
        // Every row's span lies in the one window at the quad's first column: each row runs
        // that window, its span kept by a mask, with no loop over windows (whose trip count
        // no predictor guesses) and no step to the span's first pixel.
        for ly in rows.0..=rows.1 {
            let (lx0, lx1) = spans.row(ly, cols);
            let e = row;
            for k in 0..4 {
                row[k] = row[k].wrapping_add(sr[k]);
            }
            // Nibbles [a, b) of the window; none when the span is empty (b <= a).
            let a = (lx0 - cols.0).clamp(0, 4) as u32;
            let b = (lx1 - cols.0 + 1).clamp(0, 4) as u32;
            let wanted = ((1u32 << (4 * b)) - 1) & !((1u32 << (4 * a)) - 1);
            window!(
                &e,
                (ly * buf.w) as usize,
                cols.0,
                ly,
                wanted & kept_at(cols.0, ly)
            );
        }
    } else {
        for ly in rows.0..=rows.1 {
            let (lx0, lx1) = spans.row(ly, cols);
            let e = row;
            for k in 0..4 {
                row[k] = row[k].wrapping_add(sr[k]);
            }
            let mut base: [i32; 4] =
                std::array::from_fn(|k| e[k].wrapping_add(st[k].wrapping_mul(lx0 - cols.0)));
            let row_start = (ly * buf.w) as usize;
            let mut lx = lx0;
            // (An empty span, lx0 > lx1, runs no window.)
            while lx <= lx1 {
                // Pixels past the span's end are not this row's (they may lie past the tile).
                let left = (lx1 - lx + 1).min(4) as u32;
                let wanted = ((1u64 << (4 * left)) - 1) as u32 & kept_at(lx, ly);
                window!(&base, row_start, lx, ly, wanted);
                for k in 0..4 {
                    base[k] = base[k].wrapping_add(window[k]);
                }
                lx += 4;
            }
        }
    }
    for f in &frags[..n] {
        // SAFETY: the first n entries were written above.
        let f = unsafe { f.assume_init() };
        let (lx, ly) = ((f & 0xfff) as i32, ((f >> 12) & 0xfff) as i32);
        shade.pixel::<KEPT>(buf, lx, ly, f >> 24);
    }
}

/// [`scan`] for one narrow convex quad, the common case. A row's span is walked
/// `LANES / N` pixels at a time (two at 4x MSAA): per edge one vector of the edge values at
/// those pixels' samples, stepped along the row; a sample is inside when none of its four
/// values is negative, so the pixels' masks are the sign bits of the vectors' OR (the same
/// test as `mask32`), one compare-and-branch per group of pixels rather than per pixel.
#[inline(never)]
fn scan_quad<const N: usize>(
    buf: &mut TileBuf<N>,
    quad: &Poly<4, N>,
    rows: (i32, i32),
    cols: (i32, i32),
    spans: &mut Spans,
    shade: &Shade<N>,
) {
    let px_per = LANES / N;
    let (so, st, sr) = quad.narrow();
    // Per edge, lane l = (pixel j, sample s): the sample's offset plus j steps right; and
    // the step from one group of pixels to the next.
    let lane: [[i32; LANES]; 4] = std::array::from_fn(|k| {
        std::array::from_fn(|l| so[k][l % N].wrapping_add(st[k].wrapping_mul((l / N) as i32)))
    });
    let group: [i32; 4] = std::array::from_fn(|k| st[k].wrapping_mul(px_per as i32));
    let z_far = shade.z_near - DEPTH_ROUNDING;
    // Edge values at the first column of each row, stepped down row by row in i32.
    let mut row = quad.edges32(buf.x0 + cols.0, buf.y0 + rows.0);
    for ly in rows.0..=rows.1 {
        let (lx0, lx1) = spans.row(ly, cols);
        let e = row;
        for k in 0..4 {
            row[k] = row[k].wrapping_add(sr[k]);
        }
        if lx0 > lx1 {
            continue;
        }
        // Edge values at the group's first pixel, before its lanes' offsets.
        let mut base: [i32; 4] =
            std::array::from_fn(|k| e[k].wrapping_add(st[k].wrapping_mul(lx0 - cols.0)));
        let mut lx = lx0;
        while lx <= lx1 {
            let mut or = [0i32; LANES];
            for k in 0..4 {
                for l in 0..LANES {
                    or[l] |= base[k].wrapping_add(lane[k][l]);
                }
                base[k] = base[k].wrapping_add(group[k]);
            }
            let mut bits = inside_lanes(&or);
            // Pixels past the span's end are not this row's (they may lie past the tile).
            let left = (lx1 - lx + 1) as usize;
            if left < px_per {
                bits &= (1u32 << (left * N)) - 1;
            }
            if bits == 0 {
                lx += px_per as i32;
                continue;
            }
            // Samples already nearer than the quad's nearest depth fail `Less` whatever the
            // quad's depth there: cleared for the group's pixels side by side (with heavy
            // overdraw most covered samples are; `Shade::pixel` then sees the others only).
            // The buffer is padded, so the group's last pixel may lie past the tile.
            let i = (ly * buf.w + lx) as usize;
            let depth = &buf.depth[i..i + px_per].as_flattened()[..LANES];
            let mut live = 0u32;
            for l in 0..LANES {
                live |= ((depth[l] > z_far) as u32) << l;
            }
            bits &= live;
            while bits != 0 {
                let j = bits.trailing_zeros() as usize / N;
                let cov = (bits >> (j * N)) & ((1u32 << N) - 1);
                bits &= !(((1u32 << N) - 1) << (j * N));
                shade.pixel::<false>(buf, lx + j as i32, ly, cov);
            }
            lx += px_per as i32;
        }
    }
}

// fs_main
/// What a covered strand pixel needs once its raster coverage is known.
struct Shade<'a, const N: usize> {
    p0: [f32; 2],
    d: [f32; 2],
    inv_len2: f32,
    c0: [f32; 4],
    c1: [f32; 4],
    strand: u32,
    rank: u32,
    zp: Plane,
    z_off: [f64; N],
    /// The nearest depth any sample of the quad gets (see `strand_quad`).
    z_near: f32,
    /// How many samples alpha-to-coverage keeps at every pixel of the quad, when that is
    /// one number ([`a2c_samples_everywhere`]).
    samples_kept: Option<u32>,
    /// Photo colour: the photo, o0, o1 - o0, n_o, the screen normal n / h² (so that
    /// (c - p0)·it is the signed width fraction), the mode and the HSV settings.
    photo: Option<PhotoShade<'a>>,
}

struct PhotoShade<'a> {
    tex: &'a Texture,
    o0: [f32; 2],
    od: [f32; 2],
    on: [f32; 2],
    nl: [f32; 2],
    hsv: Option<[f32; 3]>,
}

impl<const N: usize> Shade<'_, N> {
    #[inline(always)]
    fn pixel<const KEPT: bool>(&self, buf: &mut TileBuf<N>, lx: i32, ly: i32, cov: u32) {
        let i = (ly * buf.w + lx) as usize;
        let n = N as u32;
        let (px, py) = (buf.x0 + lx, buf.y0 + ly);
        // Position along the segment at the pixel centre, clamped.
        let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
        let (rx, ry) = (cx - self.p0[0], cy - self.p0[1]);
        let t_raw = (rx * self.d[0] + ry * self.d[1]) * self.inv_len2;
        let t = t_raw.clamp(0.0, 1.0);
        // Alpha-to-coverage (see the WGSL): keep floor(alpha·N + 0.5) samples. Alpha, the
        // coverage and the depth test come before the colour, which most fragments (hidden
        // under nearer strands) never need. `KEPT`: the scan has applied it already (the
        // same count everywhere: `Shade::samples_kept`).
        let mask = if KEPT {
            cov
        } else {
            let alpha = self.c0[3] * (1.0 - t) + self.c1[3] * t;
            let k = a2c_count(n, alpha);
            let r = (px as u32)
                .wrapping_add(2u32.wrapping_mul(py as u32))
                .wrapping_add(self.strand)
                & (n - 1);
            cov & a2c_mask(n, r, k)
        };
        if mask == 0 {
            return;
        }
        let z = self.zp.samples(px, py, &self.z_off);
        let pass = buf.passing(i, mask, z, self.rank);
        if pass == 0 {
            return;
        }
        let mut col: [f32; 4] = std::array::from_fn(|k| self.c0[k] * (1.0 - t) + self.c1[k] * t);
        if let Some(ph) = &self.photo {
            let l = rx * ph.nl[0] + ry * ph.nl[1];
            let o: [f32; 2] = std::array::from_fn(|k| ph.o0[k] + ph.od[k] * t_raw + ph.on[k] * l);
            let p = bilinear_at(ph.tex, o[0] - 0.5, o[1] - 0.5);
            let p = [p[0], p[1], p[2]].map(|v| v.clamp(0.0, 1.0));
            let p = match ph.hsv {
                Some([hue, sat, val]) => crate::base::colour::hsv_adjust(p, hue, sat, val),
                None => p,
            };
            for k in 0..3 {
                col[k] = (p[k] + col[k]).clamp(0.0, 1.0);
            }
        }
        buf.write_passed(lx, ly, pass, [col[0], col[1], col[2], 1.0], z, self.rank);
    }
}

/// Rasterises the pixels of `pieces` (convex polygons whose coverage masks are OR-ed)
/// inside `bbox`, shading the covered tile pixels.
#[allow(clippy::too_many_arguments)]
fn scan<const E: usize, const N: usize>(
    buf: &mut TileBuf<N>,
    pieces: &[Poly<E, N>],
    bbox: [i32; 4],
    rows: (i32, i32),
    cols: (i32, i32),
    spans: &mut Spans,
    shade: &Shade<N>,
) {
    let narrow = narrow(bbox);
    let np = pieces.len().min(2);
    // One of the two set-ups, as the polygon's size asks.
    let small: [Narrow<E, N>; 2] = [0, 1].map(|i| {
        pieces
            .get(i)
            .filter(|_| narrow)
            .map_or(([[0; N]; E], [0; E], [0; E]), |p| p.narrow())
    });
    let wide: [[[i64; N]; E]; 2] = [0, 1].map(|i| {
        pieces
            .get(i)
            .filter(|_| !narrow)
            .map_or([[0; N]; E], |p| p.sample_offsets())
    });
    for ly in rows.0..=rows.1 {
        let py = buf.y0 + ly;
        let (lx0, lx1) = spans.row(ly, cols);
        if lx0 > lx1 {
            continue;
        }
        let px0 = buf.x0 + lx0;
        if narrow {
            let mut e: [[i32; E]; 2] =
                [0, 1].map(|i| pieces.get(i).map_or([0; E], |p| p.edges32(px0, py)));
            for lx in lx0..=lx1 {
                let mut cov = 0;
                for (i, (so, st, _)) in small[..np].iter().enumerate() {
                    cov |= mask32(&e[i], so);
                    for k in 0..E {
                        e[i][k] = e[i][k].wrapping_add(st[k]);
                    }
                }
                if cov != 0 && !buf.pixel_hidden((ly * buf.w + lx) as usize, shade.z_near) {
                    shade.pixel::<false>(buf, lx, ly, cov);
                }
            }
        } else {
            let mut e: [[i64; E]; 2] =
                [0, 1].map(|i| pieces.get(i).map_or([0; E], |p| p.edges(px0, py)));
            for lx in lx0..=lx1 {
                let mut cov = 0;
                for (i, p) in pieces.iter().enumerate() {
                    cov |= p.mask(&e[i], &wide[i]);
                    let st = p.step();
                    for k in 0..E {
                        e[i][k] += st[k];
                    }
                }
                if cov != 0 && !buf.pixel_hidden((ly * buf.w + lx) as usize, shade.z_near) {
                    shade.pixel::<false>(buf, lx, ly, cov);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::Rng;
    use crate::stages::raster_common::sample_offsets;

    /// Random segments of every kind a tile sees (short, long up to the narrow limit, any
    /// direction, ends off the tile, depths inside and outside [0, 1], any alpha) drawn
    /// into one 64² tile at (16, 8), the block bounds refreshed now and then as the tile
    /// loop does: colour, depth and rank of every sample.
    fn draw(plain: bool, half_width: f32, seed: u64) -> Vec<u32> {
        FORCE_PLAIN.with(|f| f.set(plain));
        let cfg = Config::frame(100, 90, 4, half_width);
        let mut buf = TileBuf::<4>::default();
        buf.reset(16, 8, 64, 64);
        buf.color.resize(64 * 64, [[0.0; 4]; 4]);
        let (offs, fb) = (sample_offsets::<4>(), Fb::new(&cfg));
        let mut rng = Rng::new(seed);
        for n in 0..3000u32 {
            let p0 = [rng.range_f32(8.0, 88.0), rng.range_f32(0.0, 80.0)];
            let (a, l) = (rng.range_f32(0.0, 6.3), rng.range_f32(0.3, 40.0));
            let c = |rng: &mut Rng| std::array::from_fn(|_| rng.range_f32(0.0, 1.0));
            let (c0, mut c1): ([f32; 4], [f32; 4]) = (c(&mut rng), c(&mut rng));
            // Half the segments with alphas close at both ends (alpha-to-coverage keeps one
            // count of samples over the quad, the scan's `KEPT` builds), some of those
            // straddling a count's threshold.
            if n % 2 == 0 {
                c1[3] = c0[3] + rng.range_f32(-0.02, 0.02);
            }
            let s = SegRec {
                p0,
                p1: [p0[0] + l * a.cos(), p0[1] + l * a.sin()],
                z0: rng.range_f32(-0.1, 1.1),
                z1: rng.range_f32(-0.1, 1.1),
                strand: rng.below(1000),
                local: 0,
                c0,
                c1,
                o: [0.0; 4],
            };
            strand_quad(&mut buf, &s, &cfg, None, &fb, &offs, n + 1);
            if n % 16 == 15 {
                buf.refresh_zmax();
            }
        }
        FORCE_PLAIN.with(|f| f.set(false));
        let npx = 64 * 64;
        let colour = buf.color.iter().flatten().flatten().map(|v| v.to_bits());
        let depth = buf.depth[..npx].iter().flatten().map(|v| v.to_bits());
        colour
            .chain(depth)
            .chain(buf.rank[..npx].iter().flatten().copied())
            .collect()
    }

    /// The AVX2 scan of narrow quads draws exactly what the plain one draws, to the bit,
    /// at several strand widths; and the comparison can fail (another seed differs).
    #[test]
    fn avx2_quad_scan_matches_the_plain_one() {
        #[cfg(target_arch = "x86_64")]
        if !has_avx2() {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        }
        for (k, half) in [0.5f32, 1.0, 2.5].into_iter().enumerate() {
            let (fast, plain) = (
                draw(false, half, 7 + k as u64),
                draw(true, half, 7 + k as u64),
            );
            let drawn = plain[64 * 64 * 4 * 4 + 64 * 64 * 4..]
                .iter()
                .filter(|&&r| r > 0);
            assert!(
                drawn.count() > 64 * 64,
                "half width {half}: too little drawn to compare"
            );
            let first = fast.iter().zip(&plain).position(|(a, b)| a != b);
            assert_eq!(
                first, None,
                "half width {half}: first difference at word {first:?}"
            );
        }
        assert_ne!(draw(false, 0.5, 7), draw(true, 0.5, 8));
    }

    /// Where `a2c_samples_everywhere` gives a count, every pixel's own count (the lerp of
    /// the ends' alphas at any t, as `Shade::pixel` works it out) is that count, near the
    /// thresholds too; it gives one for most segments; and a pair whose counts differ
    /// along the segment gets none.
    #[test]
    fn one_sample_count_holds_at_every_pixel() {
        let pixel = |a0: f32, a1: f32, t: f32| a2c_count(4, a0 * (1.0 - t) + a1 * t);
        let mut rng = Rng::new(3);
        let (mut some, mut all) = (0, 0);
        for m in 0..20000 {
            // Ends near a threshold (0.125, 0.375, ...) at every other pair.
            let a0 = if m % 2 == 0 {
                0.125 + 0.25 * rng.below(4) as f32 + rng.range_f32(-1e-5, 1e-5)
            } else {
                rng.range_f32(-0.2, 1.3)
            };
            let a1 = a0 + rng.range_f32(-0.03, 0.03);
            all += 1;
            let Some(k) = a2c_samples_everywhere::<4>(a0, a1) else {
                continue;
            };
            some += 1;
            for j in 0..=64 {
                let t = if j < 64 {
                    j as f32 / 64.0
                } else {
                    rng.range_f32(0.0, 1.0)
                };
                assert_eq!(pixel(a0, a1, t), k, "alphas {a0} {a1} at t = {t}");
            }
        }
        assert!(some * 2 > all, "a count for only {some} of {all} segments");
        // 0.37 -> 0.38 crosses 0.375: one sample at one end, two at the other.
        assert_eq!(a2c_samples_everywhere::<4>(0.37, 0.38), None);
        assert_ne!(pixel(0.37, 0.38, 0.0), pixel(0.37, 0.38, 1.0));
        assert_eq!(a2c_samples_everywhere::<4>(f32::NAN, 0.5), None);
        assert_eq!(a2c_samples_everywhere::<4>(0.05, 0.1), Some(0));
    }
}

//! What the four PatchMatch stages (`pm_init`, `pm_cost`, `pm_search`, `pm_vote`) share:
//! the uniform, the per-pixel flags, the packed matching image, the integer hash RNG and the
//! patch distance. The WGSL side is in `wgsl/shared/` (`pm_common.wgsl`, `pm_rand.wgsl`,
//! `pm_ssd.wgsl`, included by the stages); this is their CPU side, written to give
//! bit-identical answers.
//!
//! Matching runs on integers so that the GPU and the CPU agree exactly: each pixel is packed
//! into one u32 as three 10-bit channels of sqrt(linear) (a cheap perceptual encoding, so
//! dark regions are not crushed), and the patch SSD is an exact u32 sum (a 31x31 patch of
//! 3 x 1023² stays below 2³²). Float sums would round differently with and without fused
//! multiply-adds and flip near-ties between the backends.

use crate::gpu::engine::groups;

/// Pixel is to be filled.
pub const HOLE: u32 = 1;
/// The (image-clipped) patch centred here overlaps the hole: it gets a nearest neighbour.
pub const TARGET: u32 = 2;
/// The patch centred here lies inside the image and entirely outside the hole.
pub const SOURCE: u32 = 4;
/// Nearest-neighbour word of a pixel that is not a target.
pub const NONE: u32 = u32::MAX;
/// Bit of a matching word whose colour is not known yet (onion-peel start of the coarsest
/// level); such target pixels are left out of the SSD. The colour uses bits 0..30.
pub const UNKNOWN: u32 = 1 << 31;
/// Flags bits from here up hold the onion-peel layer of a coarsest-level hole pixel (1 =
/// touches a known pixel, 8-connected); 0 elsewhere.
pub const LAYER_SHIFT: u32 = 8;
/// Largest channel value of the packed matching image.
pub const QMAX: u32 = 1023;
/// Largest patch side: 31² x 3 x 1023² < 2³² keeps the SSD in a u32.
pub const MAX_PATCH: u32 = 31;
/// Workgroup side of every PatchMatch stage (8x8 pixels).
pub const WG: u32 = 8;

/// The uniform of every PatchMatch stage; each stage reads the fields it needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, encase::ShaderType)]
pub struct Config {
    pub width: u32,
    pub height: u32,
    /// Patch half-side: patches are (2 radius + 1)².
    pub radius: u32,
    pub seed: u32,
    /// Unique per dispatch, so every pass draws fresh random numbers.
    pub pass_id: u32,
    /// `pm_search`: propagation distance of this pass (0 = no propagation).
    pub step: u32,
    /// `pm_search`: first random-search radius (0 = no random search).
    pub search_radius: u32,
    /// `pm_init`: a valid source (packed), used when random draws keep missing sources.
    pub fallback: u32,
    /// `pm_init`: size of the coarser level whose field is upsampled (0 = random init).
    pub coarse_width: u32,
    pub coarse_height: u32,
    /// `pm_vote`: weight exp(-k (m - m_min)) of a patch with mean SSD m per pixel (0 =
    /// plain average).
    pub vote_k: f32,
    /// `pm_vote`: onion-peel layer to fill (0 = every hole pixel, all colours known).
    pub layer: u32,
}

/// 8x8 workgroups over the level.
pub fn workgroups(cfg: &Config) -> [u32; 3] {
    [groups(cfg.width, WG), groups(cfg.height, WG), 1]
}

/// Chris Wellons' lowbias32 integer hash (the same in WGSL).
#[inline]
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The random word for draw `k` of `pixel` in pass `pass_id` (keyed by the seed).
#[inline]
pub fn rand(seed: u32, pass_id: u32, pixel: u32, k: u32) -> u32 {
    hash(seed ^ hash(pass_id ^ hash(pixel ^ hash(k))))
}

#[inline]
pub fn pack_xy(x: u32, y: u32) -> u32 {
    x | (y << 16)
}

#[inline]
pub fn unpack_xy(v: u32) -> (i32, i32) {
    ((v & 0xffff) as i32, (v >> 16) as i32)
}

/// Linear RGB -> matching word: round(sqrt(clamp(c, 0, 1)) x 1023) per channel, red low.
/// Half-way cases round to even like WGSL's `round`; `sqrt` is correctly rounded on both.
#[inline]
pub fn pack_rgb(c: [f32; 3]) -> u32 {
    let q = |v: f32| {
        let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        (v.sqrt() * QMAX as f32).round_ties_even() as u32
    };
    q(c[0]) | (q(c[1]) << 10) | (q(c[2]) << 20)
}

/// Squared difference of two matching words, summed over the channels; 0 when the target
/// word `a` is [`UNKNOWN`] (sources are always known).
#[inline]
pub fn sq(a: u32, b: u32) -> u32 {
    // Branch-free so the row loop vectorises: all ones for a known word, 0 for UNKNOWN.
    let keep = (a >> 31).wrapping_sub(1);
    let d0 = (a & 1023) as i32 - (b & 1023) as i32;
    let d1 = ((a >> 10) & 1023) as i32 - ((b >> 10) & 1023) as i32;
    let d2 = ((a >> 20) & 1023) as i32 - (b >> 20) as i32;
    (d0 * d0 + d1 * d1 + d2 * d2) as u32 & keep
}

/// Sum of [`sq`] over 8 words (lanes past `n` masked off): written over fixed-size arrays
/// so that it compiles to vector code.
#[inline]
fn sq8(a: &[u32; 8], b: &[u32; 8], n: usize) -> u32 {
    let mut s = [0u32; 8];
    for k in 0..8 {
        s[k] = sq(a[k], b[k]) & 0u32.wrapping_sub((k < n) as u32);
    }
    s.iter().sum()
}

/// SSD of the first `n` words of two rows, eight at a time where the slices allow.
#[inline]
fn row_ssd(t: &[u32], s: &[u32], n: usize) -> u32 {
    let mut acc = 0;
    let mut k = 0;
    while k < n {
        match (t.get(k..k + 8), s.get(k..k + 8)) {
            (Some(a), Some(b)) => {
                acc += sq8(
                    a.try_into().expect("8 words"),
                    b.try_into().expect("8 words"),
                    n - k,
                );
            }
            _ => {
                acc += t[k..n]
                    .iter()
                    .zip(&s[k..n])
                    .map(|(&a, &b)| sq(a, b))
                    .sum::<u32>();
                break;
            }
        }
        k += 8;
    }
    acc
}

/// The level a CPU mirror works on.
#[derive(Clone, Copy)]
pub struct Geom {
    pub w: i32,
    pub h: i32,
    pub r: i32,
}

impl Geom {
    pub fn new(cfg: &Config) -> Self {
        Geom {
            w: cfg.width as i32,
            h: cfg.height as i32,
            r: cfg.radius as i32,
        }
    }

    /// Whether a source centre may be tried at all (its patch inside the image).
    #[inline]
    pub fn in_source_box(&self, x: i32, y: i32) -> bool {
        x >= self.r && y >= self.r && x < self.w - self.r && y < self.h - self.r
    }

    /// Pixels of the image-clipped patch centred at (x, y).
    #[inline]
    pub fn patch_count(&self, x: i32, y: i32) -> u32 {
        let nx = (x + self.r).min(self.w - 1) - (x - self.r).max(0) + 1;
        let ny = (y + self.r).min(self.h - 1) - (y - self.r).max(0) + 1;
        (nx * ny) as u32
    }

    /// SSD between the known pixels of the image-clipped patch at target (x, y) and the
    /// patch at source (sx, sy) (inside the image by construction). Returns early, with a partial sum that
    /// is already >= `limit`, once the candidate cannot win; callers only test `< limit`,
    /// so the decision is the same as with the full sum.
    #[inline]
    pub fn ssd(&self, px: &[u32], x: i32, y: i32, sx: i32, sy: i32, limit: u32) -> u32 {
        let (w, r) = (self.w, self.r);
        let (x0, x1) = ((-r).max(-x), r.min(w - 1 - x));
        let (y0, y1) = ((-r).max(-y), r.min(self.h - 1 - y));
        let n = (x1 - x0 + 1) as usize;
        let mut acc = 0u32;
        for dy in y0..=y1 {
            let t = ((y + dy) * w + x + x0) as usize;
            let s = ((sy + dy) * w + sx + x0) as usize;
            acc += row_ssd(&px[t..], &px[s..], n);
            if acc >= limit {
                return acc;
            }
        }
        acc
    }
}

/// A target patch of side <= 7 unpacked once for the many candidates a CPU pass compares
/// it with: per row, eight i16 lanes per channel and a lane mask (0 past the clipped patch
/// and on unknown pixels). [`TargetPatch::ssd`] returns exactly [`Geom::ssd`].
pub struct TargetPatch {
    ch: [[[i16; 8]; 3]; 7],
    mask: [[i16; 8]; 7],
    rows: usize,
    /// Offsets of the first row and lane from the patch centre.
    y0: i32,
    x0: i32,
}

impl TargetPatch {
    /// Whether patches of this level fit (side <= 7); else use [`Geom::ssd`].
    pub fn fits(g: &Geom) -> bool {
        g.r <= 3
    }

    /// The patch at (x, y); needs [`TargetPatch::fits`].
    pub fn new(g: &Geom, px: &[u32], x: i32, y: i32) -> TargetPatch {
        let r = g.r;
        let (x0, x1) = ((-r).max(-x), r.min(g.w - 1 - x));
        let (y0, y1) = ((-r).max(-y), r.min(g.h - 1 - y));
        let mut tp = TargetPatch {
            ch: [[[0; 8]; 3]; 7],
            mask: [[0; 8]; 7],
            rows: (y1 - y0 + 1) as usize,
            y0,
            x0,
        };
        for k in 0..tp.rows {
            for l in 0..(x1 - x0 + 1) as usize {
                let v = px[((y + y0 + k as i32) * g.w + x + x0 + l as i32) as usize];
                if v & UNKNOWN != 0 {
                    continue;
                }
                tp.ch[k][0][l] = (v & 1023) as i16;
                tp.ch[k][1][l] = ((v >> 10) & 1023) as i16;
                tp.ch[k][2][l] = ((v >> 20) & 1023) as i16;
                tp.mask[k][l] = -1;
            }
        }
        tp
    }

    /// The same sum as [`Geom::ssd`] for the patch at source (sx, sy), with the same early
    /// return once it reaches `limit`.
    #[inline]
    pub fn ssd(&self, g: &Geom, px: &[u32], sx: i32, sy: i32, limit: u32) -> u32 {
        let mut acc = 0u32;
        for k in 0..self.rows {
            let s = ((sy + self.y0 + k as i32) * g.w + sx + self.x0) as usize;
            // Lanes past the patch are masked, so reading past it is harmless; at the very
            // end of the image they are padded instead.
            let mut src = [0u32; 8];
            match px.get(s..s + 8) {
                Some(v) => src.copy_from_slice(v),
                None => {
                    let v = &px[s..];
                    src[..v.len().min(8)].copy_from_slice(&v[..v.len().min(8)]);
                }
            }
            let (t, m) = (&self.ch[k], &self.mask[k]);
            let mut row = 0i32;
            for l in 0..8 {
                let d0 = (t[0][l] - (src[l] & 1023) as i16) & m[l];
                let d1 = (t[1][l] - ((src[l] >> 10) & 1023) as i16) & m[l];
                let d2 = (t[2][l] - ((src[l] >> 20) & 1023) as i16) & m[l];
                row += d0 as i32 * d0 as i32 + d1 as i32 * d1 as i32 + d2 as i32 * d2 as i32;
            }
            acc += row as u32;
            if acc >= limit {
                return acc;
            }
        }
        acc
    }
}

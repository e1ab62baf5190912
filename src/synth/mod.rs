//! Synthetic portraits with exact hair-orientation ground truth.
//!
//! A cartoon portrait (background, shoulders, face with eyes, brows, nose and mouth) whose hair
//! is drawn as thousands of thin anti-aliased strands integrated through a known analytic 2-D
//! growth field. The field itself, sampled at every hair pixel centre, is the ground truth
//! for the orientation stage; the strokes follow it too, so direction resolution can be
//! tested as well. Everything is deterministic for a (style, seed, size).
//!
//! Coordinates follow `annot`: pixel (i, j) has its centre at (i + 0.5, j + 0.5), x right,
//! y down. Orientation angles are measured from +x towards +y (clockwise on screen).

mod draw;
mod field;
mod scene;
pub mod synth3d;
pub mod texture;
pub mod video;

// Drawing helpers and looks shared with `synth3d`.
pub(crate) use draw::*;
use scene::Scene;
pub use texture::Texture;

use crate::base::rng::Rng;
use crate::error::{Error, Result};
use crate::io::annot::{Landmarks, Stroke, StrokeKind, Strokes};
use image::{GrayImage, RgbImage};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f32::consts::PI;
use std::path::Path;
use std::str::FromStr;

/// Hair style of a synthetic portrait.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Style {
    /// Centre part, hair flowing over the head and falling below the shoulders.
    Long,
    /// Short-ish cap spiralling out of a crown whorl (one singular point inside the mask).
    Whorl,
    /// Side part: orientation continuous across the part, growth direction flips there.
    SidePart,
    /// Crew-cut-like short strands radiating from the crown.
    Short,
    /// A fringe swept sideways across the forehead over side hair that falls from the crown:
    /// the orientation jumps by ≥ 45° along a known seam inside the hair (CZ06 Fig. 10); see
    /// [`seam`]. 2D only (not in [`Style::ALL`], no 3D or video version).
    Fringe,
}

impl Style {
    /// The styles every 2D, 3D and video test iterates over.
    pub const ALL: [Style; 4] = [Style::Long, Style::Whorl, Style::SidePart, Style::Short];
    /// Further 2D styles, named and parsed like the others but kept out of [`Style::ALL`] so
    /// the figures of the tests over it stay what they were.
    pub const EXTRA: [Style; 1] = [Style::Fringe];

    pub fn name(self) -> &'static str {
        match self {
            Style::Long => "long",
            Style::Whorl => "whorl",
            Style::SidePart => "sidepart",
            Style::Short => "short",
            Style::Fringe => "fringe",
        }
    }

    /// Whether the 3D synth (and so the synthetic video) has this style.
    pub fn has_3d(self) -> bool {
        Style::ALL.contains(&self)
    }
}

impl std::fmt::Display for Style {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Style {
    type Err = Error;
    fn from_str(s: &str) -> Result<Style> {
        Style::ALL
            .iter()
            .chain(Style::EXTRA.iter())
            .copied()
            .find(|st| st.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Style::ALL
                    .iter()
                    .chain(Style::EXTRA.iter())
                    .map(|st| st.name())
                    .collect();
                Error::Invalid(format!(
                    "unknown style \"{s}\" (expected one of {})",
                    names.join(", ")
                ))
            })
    }
}

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SynthParams {
    pub style: Style,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
}

impl SynthParams {
    pub const DEFAULT_SIZE: u32 = 512;
    /// The smallest size that still leaves room for strands between the face features.
    pub const MIN_SIZE: u32 = 64;

    /// `style` and `seed` at the default 512x512 size.
    pub fn new(style: Style, seed: u64) -> Self {
        Self::square(style, seed, Self::DEFAULT_SIZE)
    }

    /// `style` and `seed` at `size`x`size`.
    pub fn square(style: Style, seed: u64, size: u32) -> Self {
        SynthParams {
            style,
            seed,
            width: size,
            height: size,
        }
    }
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams::new(Style::Long, 1)
    }
}

/// A generated portrait and its ground truth.
#[derive(Clone, Debug)]
pub struct SynthCase {
    pub image: RgbImage,
    /// 255 = hair, 0 otherwise.
    pub mask: GrayImage,
    pub strokes: Strokes,
    pub landmarks: Landmarks,
    /// H*W, row-major: strand orientation in [0, pi), tangent (cos t, sin t) with x right and
    /// y down; NaN off hair.
    pub gt_theta: Vec<f32>,
    /// H*W*2, row-major: unit growth direction (root -> tip); NaN off hair.
    pub gt_dir: Vec<f32>,
    pub width: u32,
    pub height: u32,
}

impl SynthCase {
    /// Writes image.png, mask.png, strokes.json, landmarks.json, gt_theta.npy (H, W) and
    /// gt_dir.npy (H, W, 2) into `dir`, creating it; every file is written atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        crate::io::ensure_dir(dir)?;
        let (w, h) = (self.width as usize, self.height as usize);
        crate::io::write_png(&dir.join("image.png"), &self.image)?;
        crate::io::write_png(&dir.join("mask.png"), &self.mask)?;
        self.strokes.save(&dir.join("strokes.json"))?;
        self.landmarks.save(&dir.join("landmarks.json"))?;
        crate::io::npy::write_f32(&dir.join("gt_theta.npy"), &[h, w], &self.gt_theta)?;
        crate::io::npy::write_f32(&dir.join("gt_dir.npy"), &[h, w, 2], &self.gt_dir)?;
        Ok(())
    }

    /// Whether pixel (x, y) is hair.
    pub fn is_hair(&self, x: u32, y: u32) -> bool {
        self.mask.get_pixel(x, y)[0] > 127
    }
}

/// Pixels of `mask` (value > 127) whose distance to every non-mask pixel, and to the outside
/// of the image, is at least `min_dist` pixel-centre spacings. Row-major, W*H.
pub fn mask_interior(mask: &GrayImage, min_dist: f32) -> Vec<bool> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let hair: Vec<bool> = mask.as_raw().iter().map(|&v| v > 127).collect();
    // Offsets strictly closer than `min_dist`: any non-hair pixel there disqualifies.
    let offs = crate::base::mask::disc(min_dist, true);
    crate::base::mask::erode_by(&hair, w, h, &offs, false)
}

/// The seam of a style with an orientation discontinuity inside the hair ([`Style::Fringe`]).
#[derive(Clone, Debug)]
pub struct Seam {
    /// W*H: hair pixels on the fringe's side of the seam.
    pub fringe: Vec<bool>,
    /// W*H: the seam's pixels: hair pixels with a 4-neighbour hair pixel on the other side.
    pub on: Vec<bool>,
    /// W*H: distance from each hair pixel's centre to the nearest seam pixel's centre, px
    /// (0 on the seam); NaN off hair.
    pub distance: Vec<f32>,
}

/// The seam of `p`'s portrait (the case [`synth`] makes from the same params), or None for
/// styles without one.
pub fn seam(p: &SynthParams) -> Option<Seam> {
    if p.style != Style::Fringe {
        return None;
    }
    let [mut geo_rng, mut look_rng, ..] = streams(p, style_salt(p.style));
    let scene = Scene::new(p, &Texture::default(), &mut geo_rng, &mut look_rng);
    let (w, h) = (p.width as usize, p.height as usize);
    let mut hair = vec![false; w * h];
    let mut fringe = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let k = y * w + x;
            hair[k] = scene.hair_sdf(px, py) < 0.0;
            fringe[k] = hair[k] && scene.field.in_fringe(px, py);
        }
    }
    let mut on = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            if !hair[k] {
                continue;
            }
            let nb = [
                (x > 0).then(|| k - 1),
                (x + 1 < w).then(|| k + 1),
                (y > 0).then(|| k - w),
                (y + 1 < h).then(|| k + w),
            ];
            on[k] = nb
                .into_iter()
                .flatten()
                .any(|j| hair[j] && fringe[j] != fringe[k]);
        }
    }
    let d = distance_to(&on, w, h);
    let distance = (0..w * h)
        .map(|k| if hair[k] { d[k] } else { f32::NAN })
        .collect();
    Some(Seam {
        fringe,
        on,
        distance,
    })
}

/// Exact Euclidean distance from every pixel centre to the nearest pixel of `set` (W*H,
/// row-major), px; +∞ everywhere when `set` is empty (Felzenszwalb and Huttenlocher's
/// separable transform).
pub fn distance_to(set: &[bool], w: usize, h: usize) -> Vec<f32> {
    assert_eq!(set.len(), w * h, "set has the image's size");
    const INF: f64 = 1e20;
    // Squared distances along each column, then along each row.
    let mut d2: Vec<f64> = set.iter().map(|&s| if s { 0.0 } else { INF }).collect();
    let mut col = vec![0.0f64; h];
    for x in 0..w {
        for y in 0..h {
            col[y] = d2[y * w + x];
        }
        let out = dt_1d(&col);
        for y in 0..h {
            d2[y * w + x] = out[y];
        }
    }
    for y in 0..h {
        let out = dt_1d(&d2[y * w..(y + 1) * w]);
        d2[y * w..(y + 1) * w].copy_from_slice(&out);
    }
    d2.iter()
        .map(|&v| {
            if v >= INF {
                f32::INFINITY
            } else {
                v.sqrt() as f32
            }
        })
        .collect()
}

/// 1D squared distance transform: min over q of (p − q)² + f(q) (lower envelope of parabolas).
fn dt_1d(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut out = vec![f64::INFINITY; n];
    // Parabolas with a finite apex only: an all-infinite line stays infinite.
    let finite: Vec<usize> = (0..n).filter(|&q| f[q] < 1e20).collect();
    if finite.is_empty() {
        return f.to_vec();
    }
    let mut v = vec![0usize; finite.len()];
    let mut z = vec![0.0f64; finite.len() + 1];
    let mut k = 0usize;
    v[0] = finite[0];
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let inter = |q: usize, p: usize| -> f64 {
        let (qf, pf) = (q as f64, p as f64);
        ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf))
    };
    for &q in &finite[1..] {
        let mut s = inter(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = inter(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (p, o) in out.iter_mut().enumerate() {
        while z[k + 1] < p as f64 {
            k += 1;
        }
        let d = p as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
    out
}

/// Smallest angle between two orientations (mod pi), in degrees.
pub fn orientation_error_deg(a: f32, b: f32) -> f32 {
    crate::eval::metrics::orient_diff(a, b).to_degrees()
}

/// Generates the portrait. Panics if a side is below [`SynthParams::MIN_SIZE`].
pub fn synth(p: &SynthParams) -> SynthCase {
    synth_textured(p, &Texture::default())
}

/// [`synth`] with a texture variation; the default texture gives [`synth`]'s portrait.
pub fn synth_textured(p: &SynthParams, t: &Texture) -> SynthCase {
    let [mut geo_rng, mut look_rng, mut strand_rng, mut stroke_rng] =
        streams(p, style_salt(p.style));

    let scene = Scene::new(p, t, &mut geo_rng, &mut look_rng);
    let (w, h) = (p.width as usize, p.height as usize);

    // Mask and ground truth: the analytic region and field at pixel centres.
    let mut mask = vec![0u8; w * h];
    let mut gt_theta = vec![f32::NAN; w * h];
    let mut gt_dir = vec![f32::NAN; w * h * 2];
    mask.par_chunks_mut(w)
        .zip(gt_theta.par_chunks_mut(w))
        .zip(gt_dir.par_chunks_mut(2 * w))
        .enumerate()
        .for_each(|(y, ((mrow, trow), drow))| {
            let py = y as f32 + 0.5;
            for x in 0..w {
                let px = x as f32 + 0.5;
                if scene.hair_sdf(px, py) < 0.0 {
                    mrow[x] = 255;
                    let d = scene.field.dir(px, py);
                    drow[2 * x] = d[0];
                    drow[2 * x + 1] = d[1];
                    trow[x] = theta_of(d);
                }
            }
        });

    let mut rgb = scene.render_base();
    scene.draw_hair(&mut rgb, &mask, &mut strand_rng);
    let strokes = scene.make_strokes(&mask, &gt_dir, &mut stroke_rng);

    // Its own stream, so noise leaves the strands and strokes as they were.
    let mut noise_rng = Rng::new(p.seed ^ style_salt(p.style) ^ 0x6e6f_6973_6500);
    texture::degrade(&mut rgb, w, h, t, &mut noise_rng);
    let mut image = to_image(&rgb, p.width, p.height);
    if t.jpeg > 0 {
        image = texture::jpeg_round_trip(&image, t.jpeg);
    }
    SynthCase {
        image,
        mask: GrayImage::from_raw(p.width, p.height, mask).expect("mask size"),
        strokes,
        landmarks: scene.landmarks(),
        gt_theta,
        gt_dir,
        width: p.width,
        height: p.height,
    }
}

/// The longest prefix of a stroke whose points are hair (`mask` > 0) and whose segments agree
/// with the ground truth `gt_dir` within 12° at their midpoints, so sampling on the pixel grid
/// cannot contradict it. `unit` turns a segment into its direction (how each synth treats a
/// degenerate segment).
pub(crate) fn checked_prefix(
    pts: Vec<[f32; 2]>,
    mask: &[u8],
    gt_dir: &[f32],
    w: usize,
    h: usize,
    unit: impl Fn([f32; 2]) -> [f32; 2],
) -> Vec<[f32; 2]> {
    let at = |p: [f32; 2]| -> Option<usize> {
        let (ix, iy) = (p[0].floor() as i64, p[1].floor() as i64);
        (ix >= 0 && iy >= 0 && (ix as usize) < w && (iy as usize) < h)
            .then(|| iy as usize * w + ix as usize)
            .filter(|&i| mask[i] > 0)
    };
    let mut out: Vec<[f32; 2]> = Vec::new();
    for p in pts {
        if at(p).is_none() {
            break;
        }
        if let Some(&q) = out.last() {
            let m = [(p[0] + q[0]) * 0.5, (p[1] + q[1]) * 0.5];
            let Some(i) = at(m) else { break };
            let seg = unit([p[0] - q[0], p[1] - q[1]]);
            if seg[0] * gt_dir[2 * i] + seg[1] * gt_dir[2 * i + 1] < 12f32.to_radians().cos() {
                break;
            }
        }
        out.push(p);
    }
    out
}

/// The portrait's random streams (geometry, look, strands, strokes), forked from one root
/// salted per style, so that changing how one part draws numbers leaves the others alone.
/// Panics if a side is below [`SynthParams::MIN_SIZE`].
pub(crate) fn streams(p: &SynthParams, salt: u64) -> [Rng; 4] {
    assert!(
        p.width >= SynthParams::MIN_SIZE && p.height >= SynthParams::MIN_SIZE,
        "synthetic portraits need at least {0}x{0} pixels, got {1}x{2}",
        SynthParams::MIN_SIZE,
        p.width,
        p.height
    );
    let mut root = Rng::new(p.seed ^ salt);
    [1, 2, 3, 4].map(|k| root.fork(k))
}

fn style_salt(s: Style) -> u64 {
    // Different styles with the same seed should not share faces and colours exactly.
    match s {
        Style::Long => 0x4c6f_6e67,
        Style::Whorl => 0x5768_6f72,
        Style::SidePart => 0x5369_6465,
        Style::Short => 0x5368_6f72,
        Style::Fringe => 0x4672_696e,
    }
}

/// Orientation in [0, pi) of a direction.
pub(crate) fn theta_of(d: [f32; 2]) -> f32 {
    let t = (d[1] as f64)
        .atan2(d[0] as f64)
        .rem_euclid(std::f64::consts::PI) as f32;
    // Rounding to f32 can produce exactly pi; that orientation is 0.
    if t >= PI {
        0.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests;

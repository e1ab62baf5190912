//! Dense growth direction over the hair (issue 3, C13 §2.1): the directed 2D curves and the
//! user strokes are splatted as known directions, then Jacobi sweeps of `dir_diffuse` spread
//! them over the hair mask while keeping every pixel's direction on ± its image orientation.

use crate::base::sentinel::SENTINEL;
use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::stages::dir_diffuse;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DirectionParams {
    /// Jacobi sweeps. Information travels one pixel per sweep, so this bounds the distance
    /// from the nearest curve at which a direction is still found.
    pub iterations: u32,
    /// Pull of a known direction against its neighbours' average.
    pub lambda: f32,
    /// Confidence of a user stroke relative to a traced curve (C13's w_m).
    pub stroke_weight: f32,
}

impl Default for DirectionParams {
    fn default() -> Self {
        DirectionParams {
            iterations: 400,
            lambda: 10.0,
            stroke_weight: 10.0,
        }
    }
}

/// Known directions splatted from polylines (points root→tip): per pixel the summed unit
/// tangent (interleaved x, y) and the summed weight.
pub fn splat_polylines(
    width: u32,
    height: u32,
    lines: &[(&[[f32; 2]], f32)],
) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (width as usize, height as usize);
    let mut known = vec![0.0f32; 2 * w * h];
    let mut weight = vec![0.0f32; w * h];
    for &(pts, wt) in lines {
        for seg in pts.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = dx.hypot(dy);
            if len.is_nan() || len <= 1e-6 {
                continue;
            }
            let (tx, ty) = (dx / len, dy / len);
            // Half-pixel steps: every pixel the segment crosses is touched at least once.
            let n = (len * 2.0).ceil() as usize;
            let mut last = usize::MAX;
            for k in 0..=n {
                let f = k as f32 / n as f32;
                let (x, y) = (a[0] + f * dx, a[1] + f * dy);
                if !(x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32) {
                    continue;
                }
                let i = y as usize * w + x as usize;
                if i == last {
                    continue;
                }
                last = i;
                known[2 * i] += wt * tx;
                known[2 * i + 1] += wt * ty;
                weight[i] += wt;
            }
        }
    }
    // Keep a unit direction per pixel; the weight says how sure it is.
    for i in 0..w * h {
        let (x, y) = (known[2 * i], known[2 * i + 1]);
        let m = x.hypot(y);
        if m > 0.0 {
            known[2 * i] = x / m;
            known[2 * i + 1] = y / m;
        } else {
            weight[i] = 0.0;
        }
    }
    (known, weight)
}

/// Where a field lives: its size, its mask (nonzero inside) and, optionally, the orientation
/// (radians, NaN off hair) the field must stay on.
#[derive(Clone, Copy, Debug)]
pub struct Domain<'a> {
    pub width: u32,
    pub height: u32,
    pub mask: &'a [u8],
    pub theta: Option<&'a [f32]>,
}

/// Runs `iterations` constrained sweeps; returns the raw field (interleaved x, y).
pub fn diffuse(
    engine: &Engine,
    d: &Domain,
    known: &[f32],
    known_w: &[f32],
    iterations: u32,
    lambda: f32,
) -> Result<Vec<f32>> {
    let (width, height, mask, theta) = (d.width, d.height, d.mask, d.theta);
    let n = width as u64 * height as u64;
    if n == 0 {
        return Err(Error::Invalid("the image is empty (0 pixels)".into()));
    }
    let mut rec = Recording::default();
    let cfg = dir_diffuse::Config {
        width,
        height,
        lambda,
        use_orient: theta.is_some() as u32,
    };
    let u = rec.uniform("coif.dir.cfg", &cfg);
    let tangent = match theta {
        Some(t) => dir_diffuse::tangents(t),
        None => vec![0.0f32; 2 * n as usize],
    };
    let tb = rec.upload("coif.dir.tangent", &tangent);
    let mask32: Vec<u32> = mask.iter().map(|&m| (m != 0) as u32).collect();
    let mb = rec.upload("coif.dir.mask", &mask32);
    let kb = rec.upload("coif.dir.known", known);
    let wb = rec.upload("coif.dir.known_w", known_w);
    let init: Vec<f32> = known
        .iter()
        .enumerate()
        .map(|(j, &v)| if known_w[j / 2] > 0.0 { v } else { 0.0 })
        .collect();
    let mut a = rec.upload("coif.dir.a", &init);
    let mut b = rec.alloc("coif.dir.b", 8 * n, SENTINEL);
    for _ in 0..iterations {
        rec.dispatch(
            &dir_diffuse::STAGE,
            dir_diffuse::workgroups(&cfg),
            &[u, tb, mb, kb, wb, a, b],
            &[],
        );
        std::mem::swap(&mut a, &mut b);
    }
    rec.download(a);
    Ok(engine.run(rec)?.get::<f32>(a))
}

/// Dense unit growth direction (H x W x 2, x right, y down; NaN off hair and where no curve
/// reaches) from directed curves and strokes, each a polyline root→tip.
pub fn dense_direction(
    engine: &Engine,
    d: &Domain,
    curves: &[Vec<[f32; 2]>],
    strokes: &[Vec<[f32; 2]>],
    p: &DirectionParams,
) -> Result<Vec<f32>> {
    if d.mask.len() != (d.width * d.height) as usize {
        return Err(Error::Invalid(format!(
            "mask has {} pixels, the image {}",
            d.mask.len(),
            d.width * d.height
        )));
    }
    let mut lines: Vec<(&[[f32; 2]], f32)> = curves.iter().map(|c| (c.as_slice(), 1.0)).collect();
    lines.extend(strokes.iter().map(|s| (s.as_slice(), p.stroke_weight)));
    let (known, known_w) = splat_polylines(d.width, d.height, &lines);
    let v = diffuse(engine, d, &known, &known_w, p.iterations, p.lambda)?;
    let mut out = vec![f32::NAN; v.len()];
    for i in 0..d.mask.len() {
        let (x, y) = (v[2 * i], v[2 * i + 1]);
        let m = x.hypot(y);
        if d.mask[i] != 0 && m > 1e-12 {
            out[2 * i] = x / m;
            out[2 * i + 1] = y / m;
        }
    }
    Ok(out)
}

//! Camera fits: from the photo's landmarks (Procrustes, then Gauss-Newton) or a default framing.

use super::{Head, WeakPerspective};
use crate::error::{Error, Result};
use crate::io::annot::{Landmarks, REQUIRED_LANDMARKS};
use glam::{DMat3, DVec2, DVec3, Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// How a camera was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FitMethod {
    Landmarks,
    Default,
}

/// Outcome of a camera fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    pub method: FitMethod,
    /// Landmark names used (sorted), empty for the default fit.
    pub points: Vec<String>,
    /// Root-mean-square and largest reprojection error, pixels (landmark fits only).
    pub rms_px: Option<f32>,
    pub max_px: Option<f32>,
    /// Levenberg-Marquardt iterations after the linear initialisation.
    pub iterations: u32,
}

/// Fits a weak-perspective camera (scale, full 3D rotation, 2D translation) to the
/// landmarks: every name the head knows is used, other names are ignored.
///
/// Method: the affine camera minimising the squared reprojection error is linear least
/// squares (two 4-vectors); its 2x3 linear part, with the image-y row negated, is replaced
/// by the nearest scaled matrix with orthonormal rows (polar decomposition of a 2x3 matrix
/// through the eigen-decomposition of its 2x2 Gram matrix, scale = mean singular value), the
/// third row is their cross product (a proper rotation), and Levenberg-Marquardt on
/// (log s, rotation increment, t) then minimises the true reprojection error.
///
/// Errors (`Error::Invalid`): zero image size, landmarks failing
/// [`Landmarks::validate`] (missing required names, non-finite values, points outside the
/// image), and degenerate layouts (coincident or nearly collinear points), for which no
/// rotation can be recovered.
pub fn fit_landmarks(
    head: &Head,
    lm: &Landmarks,
    size: (u32, u32),
) -> Result<(WeakPerspective, FitReport)> {
    let (w, h) = size;
    if w == 0 || h == 0 {
        return Err(Error::Invalid(format!(
            "landmark fit: image size {w}x{h} is empty"
        )));
    }
    lm.validate(Some(size))
        .map_err(|m| Error::Invalid(format!("landmark fit: {m}")))?;
    let mut names = Vec::new();
    let mut model = Vec::new();
    let mut image = Vec::new();
    for (name, q) in &lm.landmarks {
        if let Some(p) = head.landmark(name) {
            names.push(name.clone());
            model.push(p.as_dvec3());
            image.push(DVec2::new(q[0] as f64, q[1] as f64));
        }
    }
    debug_assert!(names.len() >= REQUIRED_LANDMARKS.len());
    check_spread(&image, w.max(h) as f64)?;
    let (out, rms, max, iterations) = fit_cam(&model, &image)?;
    Ok((
        out,
        FitReport {
            method: FitMethod::Landmarks,
            points: names,
            rms_px: Some(rms as f32),
            max_px: Some(max as f32),
            iterations,
        },
    ))
}

/// Fits a weak-perspective camera to any model points and their image positions (at least
/// four, spread in the image). With `init`, Levenberg-Marquardt starts from that camera
/// (a video's previous frame): a nearly flat point set, like features on a face, fits a
/// turn either way about as well (the depth reversal of affine cameras), and only a start
/// on the right side keeps the right one. Without it, the linear start of
/// [`fit_landmarks`]. Returns the camera and the per-point reprojection errors (px).
pub fn fit_points(
    model: &[Vec3],
    image: &[Vec2],
    size: (u32, u32),
    init: Option<&WeakPerspective>,
) -> Result<(WeakPerspective, Vec<f32>)> {
    if model.len() != image.len() || model.len() < 4 {
        return Err(Error::Invalid(format!(
            "camera fit: {} model points and {} image points (at least 4 pairs needed)",
            model.len(),
            image.len()
        )));
    }
    if model.iter().any(|p| !p.is_finite()) || image.iter().any(|q| !q.is_finite()) {
        return Err(Error::Invalid(
            "camera fit: a point is NaN or infinite".into(),
        ));
    }
    let model: Vec<DVec3> = model.iter().map(|p| p.as_dvec3()).collect();
    let image: Vec<DVec2> = image.iter().map(|q| q.as_dvec2()).collect();
    check_spread(&image, size.0.max(size.1) as f64)?;
    let cam = match init {
        Some(c) => {
            let mut cam = Cam64 {
                s: c.s as f64,
                r: c.r.as_dmat3(),
                t: c.t.as_dvec2(),
            };
            refine(&mut cam, &model, &image);
            let out = cam.to_f32();
            out.validate()
                .map_err(|_| Error::Invalid("camera fit did not converge".into()))?;
            out
        }
        None => fit_cam(&model, &image)?.0,
    };
    let res = model
        .iter()
        .zip(&image)
        .map(|(p, q)| {
            let r = cam.project(p.as_vec3());
            (Vec2::new(r.x, r.y) - q.as_vec2()).length()
        })
        .collect();
    Ok((cam, res))
}

/// Linear affine fit, nearest scaled rotation, then Levenberg-Marquardt; returns the camera,
/// the RMS and largest reprojection error and the iterations.
fn fit_cam(model: &[DVec3], image: &[DVec2]) -> Result<(WeakPerspective, f64, f64, u32)> {
    // Affine camera by linear least squares, centred for conditioning.
    let pm = model.iter().sum::<DVec3>() / model.len() as f64;
    let qm = image.iter().sum::<DVec2>() / image.len() as f64;
    let mut m = DMat3::ZERO;
    let (mut bx, mut by) = (DVec3::ZERO, DVec3::ZERO);
    for (p, q) in model.iter().zip(image) {
        let (p, q) = (*p - pm, *q - qm);
        m += DMat3::from_cols(p * p.x, p * p.y, p * p.z);
        bx += p * q.x;
        by += p * q.y;
    }
    if m.determinant().abs() < 1e-18 {
        // The head's own landmarks are coplanar: a parameter problem, not the user's.
        return Err(Error::Invalid(
            "landmark fit: the head model's landmarks are coplanar".into(),
        ));
    }
    let mi = m.inverse();
    let a0 = mi * bx;
    let a1 = mi * by;
    let (s, r) = nearest_scaled_rotation(a0, -a1).ok_or_else(|| {
        Error::Invalid("landmark fit: the landmarks are degenerate (rank < 2)".into())
    })?;
    let mut cam = Cam64 {
        s,
        r,
        t: DVec2::ZERO,
    };
    cam.t = optimal_t(&cam, model, image);
    let iterations = refine(&mut cam, model, image);
    let res: Vec<f64> = model
        .iter()
        .zip(image)
        .map(|(p, q)| (cam.project(*p) - *q).length())
        .collect();
    let rms = (res.iter().map(|e| e * e).sum::<f64>() / res.len() as f64).sqrt();
    let max = res.iter().fold(0.0f64, |a, &b| a.max(b));
    let out = cam.to_f32();
    if out.validate().is_err() || !rms.is_finite() {
        return Err(Error::Invalid(
            "landmark fit did not converge to a valid camera".into(),
        ));
    }
    Ok((out, rms, max, iterations))
}

/// Hair thickness assumed beside the skull by [`fit_default`], metres per side.
pub const DEFAULT_HAIR_SIDE_M: f32 = 0.04;
/// Hair thickness assumed above the vertex by [`fit_default`], metres.
pub const DEFAULT_HAIR_TOP_M: f32 = 0.04;

/// Camera without landmarks, from a hair mask (W·H bytes, row-major, > 127 = hair).
///
/// Heuristic: a frontal camera (no rotation). From the top mask row downwards the widest
/// horizontal extent of the mask is tracked until the scan is 0.65 of that width (and at
/// least max(8, H/32) rows) below the top (a hair cap's widest row, near the skull centre, lies about 0.55-0.67 widths down);
/// that width is taken as the skull width plus [`DEFAULT_HAIR_SIDE_M`] on each side, which
/// gives the scale; the head is centred on the midpoint of that widest row, and the vertex
/// is placed [`DEFAULT_HAIR_TOP_M`] below the mask top. Errors on a size mismatch or an
/// empty mask.
pub fn fit_default(
    head: &Head,
    mask: &[u8],
    width: u32,
    height: u32,
) -> Result<(WeakPerspective, FitReport)> {
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 || mask.len() != w * h {
        return Err(Error::Invalid(format!(
            "default fit: mask has {} bytes, expected {width}x{height} = {}",
            mask.len(),
            w * h
        )));
    }
    let span = |y: usize| {
        let row = &mask[y * w..(y + 1) * w];
        let l = row.iter().position(|&v| v > 127)?;
        let r = row.iter().rposition(|&v| v > 127)?;
        Some((l, r))
    };
    let y_top = (0..h)
        .find(|&y| span(y).is_some())
        .ok_or_else(|| Error::Invalid("default fit: the hair mask is empty".into()))?;
    let (mut best_w, mut best_c) = (0usize, 0.0f64);
    for y in y_top..h {
        if let Some((l, r)) = span(y) {
            let wd = r + 1 - l;
            if wd > best_w {
                best_w = wd;
                best_c = 0.5 * (l + r + 1) as f64;
            }
        }
        // The minimum depth keeps a stray pixel above the hair from ending the scan.
        let depth = y - y_top;
        if depth as f64 > 0.65 * best_w as f64 && depth >= (h / 32).max(8) {
            break;
        }
    }
    let skull_w = head.params.skull_width + 2.0 * DEFAULT_HAIR_SIDE_M;
    let s = best_w as f32 / skull_w;
    // Vertex image y = −s·top.y + t.y must equal y_top + s·hair_top.
    let ty = y_top as f32 + s * DEFAULT_HAIR_TOP_M + s * head.top().y;
    let tx = best_c as f32 - s * head.top().x;
    let cam = WeakPerspective::frontal(s, Vec2::new(tx, ty));
    cam.validate()?;
    Ok((
        cam,
        FitReport {
            method: FitMethod::Default,
            points: Vec::new(),
            rms_px: None,
            max_px: None,
            iterations: 0,
        },
    ))
}

/// Rejects coincident or (nearly) collinear image points: the smaller principal spread
/// must be at least 5% of the larger one and at least 1e-3 of the image size.
fn check_spread(image: &[DVec2], img_size: f64) -> Result<()> {
    let n = image.len() as f64;
    let c = image.iter().sum::<DVec2>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for q in image {
        let d = *q - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let (l1, l2) = sym2_eigen(sxx / n, sxy / n, syy / n).0;
    let (big, small) = (l1.max(0.0).sqrt(), l2.max(0.0).sqrt());
    if big < 1e-3 * img_size || small < 0.05 * big || small < 1e-3 * img_size {
        return Err(Error::Invalid(format!(
            "landmark fit: the landmarks are degenerate (coincident or collinear: principal \
             spreads {big:.3} and {small:.3} px); need a face seen at most moderately from \
             the side"
        )));
    }
    Ok(())
}

/// Eigenvalues (descending) and the unit eigenvector of the larger one for [[a, b], [b, c]].
fn sym2_eigen(a: f64, b: f64, c: f64) -> ((f64, f64), DVec2) {
    let m = 0.5 * (a + c);
    let d = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = (m + d, m - d);
    let v = if b.abs() > 1e-300 {
        DVec2::new(l1 - c, b).normalize()
    } else if a >= c {
        DVec2::X
    } else {
        DVec2::Y
    };
    ((l1, l2), v)
}

/// Nearest s·[r0; r1] (orthonormal rows, s > 0) to the 2x3 matrix [b0; b1] in Frobenius
/// norm, completed to a rotation. None when the matrix has rank < 2.
fn nearest_scaled_rotation(b0: DVec3, b1: DVec3) -> Option<(f64, DMat3)> {
    let ((l1, l2), e1) = sym2_eigen(b0.dot(b0), b0.dot(b1), b1.dot(b1));
    let (s1, s2) = (l1.max(0.0).sqrt(), l2.max(0.0).sqrt());
    if s2 <= 1e-9 * s1 || !s1.is_finite() || s2.is_nan() {
        return None;
    }
    let e2 = DVec2::new(-e1.y, e1.x);
    // G^{-1/2} with G the Gram matrix [[b0·b0, b0·b1], [b0·b1, b1·b1]].
    let g = |i: usize, j: usize| e1[i] * e1[j] / s1 + e2[i] * e2[j] / s2;
    let r0 = b0 * g(0, 0) + b1 * g(0, 1);
    let r1 = b0 * g(1, 0) + b1 * g(1, 1);
    // Re-orthonormalise against rounding.
    let r0 = r0.normalize();
    let r1 = (r1 - r0 * r0.dot(r1)).normalize();
    let r2 = r0.cross(r1);
    Some((0.5 * (s1 + s2), DMat3::from_cols(r0, r1, r2).transpose()))
}

#[derive(Clone, Copy)]
struct Cam64 {
    s: f64,
    r: DMat3,
    t: DVec2,
}

impl Cam64 {
    fn project(&self, p: DVec3) -> DVec2 {
        let v = self.r * p;
        DVec2::new(self.s * v.x + self.t.x, -self.s * v.y + self.t.y)
    }
    fn to_f32(self) -> WeakPerspective {
        WeakPerspective {
            s: self.s as f32,
            r: self.r.as_mat3(),
            t: self.t.as_vec2(),
        }
    }
    fn cost(&self, model: &[DVec3], image: &[DVec2]) -> f64 {
        model
            .iter()
            .zip(image)
            .map(|(p, q)| (self.project(*p) - *q).length_squared())
            .sum()
    }
}

/// Translation minimising the reprojection error for a fixed scale and rotation.
fn optimal_t(cam: &Cam64, model: &[DVec3], image: &[DVec2]) -> DVec2 {
    let zero = Cam64 {
        t: DVec2::ZERO,
        ..*cam
    };
    model
        .iter()
        .zip(image)
        .map(|(p, q)| *q - zero.project(*p))
        .sum::<DVec2>()
        / model.len() as f64
}

/// Levenberg-Marquardt on (log s, ω, t), R ← exp(ω)·R. Returns the iterations taken.
fn refine(cam: &mut Cam64, model: &[DVec3], image: &[DVec2]) -> u32 {
    let mut cost = cam.cost(model, image);
    let mut lambda = 1e-3;
    let mut it = 0;
    while it < 50 {
        it += 1;
        let mut jtj = [[0.0f64; 6]; 6];
        let mut jtr = [0.0f64; 6];
        for (p, q) in model.iter().zip(image) {
            let v = cam.r * *p;
            let e = cam.project(*p) - *q;
            let s = cam.s;
            // d(view)/dω = ω × v  =>  rows of −[v]×.
            let jx = [s * v.x, 0.0, s * v.z, -s * v.y, 1.0, 0.0];
            let jy = [-s * v.y, s * v.z, 0.0, -s * v.x, 0.0, 1.0];
            for (j, r) in [(jx, e.x), (jy, e.y)] {
                for a in 0..6 {
                    jtr[a] += j[a] * r;
                    for b in 0..6 {
                        jtj[a][b] += j[a] * j[b];
                    }
                }
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for (k, row) in a.iter_mut().enumerate() {
                row[k] += lambda * (jtj[k][k] + 1e-12);
            }
            let Some(d) = solve6(a, jtr.map(|x| -x)) else {
                lambda *= 10.0;
                continue;
            };
            let w = DVec3::new(d[1], d[2], d[3]);
            let rot = if w.length() > 0.0 {
                DMat3::from_axis_angle(w.normalize(), w.length())
            } else {
                DMat3::IDENTITY
            };
            let trial = Cam64 {
                s: cam.s * d[0].clamp(-1.0, 1.0).exp(),
                r: rot * cam.r,
                t: cam.t + DVec2::new(d[4], d[5]),
            };
            let c = trial.cost(model, image);
            if c < cost {
                let gain = cost - c;
                *cam = trial;
                cost = c;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                if gain < 1e-12 * (1.0 + cost) {
                    return it;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    // Keep R orthonormal after many small updates.
    let (r0, r1) = (cam.r.row(0).normalize(), cam.r.row(1));
    let r1 = (r1 - r0 * r0.dot(r1)).normalize();
    cam.r = DMat3::from_cols(r0, r1, r0.cross(r1)).transpose();
    it
}

/// Gaussian elimination with partial pivoting for a 6x6 system.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for c in 0..6 {
        let piv = (c..6).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[piv][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        for r in c + 1..6 {
            let f = a[r][c] / a[c][c];
            let pivot_row = a[c];
            for (x, p) in a[r][c..].iter_mut().zip(&pivot_row[c..]) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; 6];
    for c in (0..6).rev() {
        let s: f64 = (c + 1..6).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

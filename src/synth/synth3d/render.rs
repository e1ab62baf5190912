//! Rendering of the 3D portrait: body, face, strand footprint, mask, gt_dir, painted strands.

use super::body::Body;
use super::grow::StrandVar;
use super::StrandHit;
use crate::base::mask;
use crate::hair::head::{Head, WeakPerspective};
use crate::synth::{
    blend, cov, draw_eye, draw_mouth, draw_nostrils, mix3, poly_dist, scale3, smoothstep, Look,
};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::VecDeque;

/// The body seen through one pixel.
#[derive(Clone, Copy, Debug)]
pub(super) struct BodyPix {
    /// Depth (px) of the first hit, -inf on a miss.
    pub(super) depth: f32,
    /// Pixel coverage (1 on a hit, an edge ramp from the closest approach on a miss).
    pub(super) cover: f32,
    pub(super) normal: Vec3,
    pub(super) cloth: bool,
}

/// Sphere-traces the body along the view direction at every pixel centre.
pub(super) fn render_body(body: &Body, cam: &WeakPerspective, w: usize, h: usize) -> Vec<BodyPix> {
    let dir = (-cam.r.row(2)).as_dvec3();
    let (lo, hi) = body.bounds();
    let s = cam.s as f64;
    let miss = BodyPix {
        depth: f32::NEG_INFINITY,
        cover: 0.0,
        normal: Vec3::Z,
        cloth: false,
    };
    let mut out = vec![miss; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            // Origin 1 m in front of the model origin's depth.
            let org = cam
                .unproject(Vec3::new(x as f32 + 0.5, y as f32 + 0.5, cam.s))
                .as_dvec3();
            // Slab test against the bounds.
            let (mut t0, mut t1) = (0.0f64, 3.0f64);
            for k in 0..3 {
                if dir[k].abs() < 1e-12 {
                    if org[k] < lo[k] || org[k] > hi[k] {
                        t1 = -1.0;
                    }
                    continue;
                }
                let (a, b) = ((lo[k] - org[k]) / dir[k], (hi[k] - org[k]) / dir[k]);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
            if t0 > t1 {
                continue;
            }
            let mut t = t0;
            let (mut dmin, mut tmin) = (f64::INFINITY, t0);
            let mut hit = None;
            for _ in 0..300 {
                let q = org + dir * t;
                let d = body.sdf64(q);
                if d < dmin {
                    dmin = d;
                    tmin = t;
                }
                if d < 2e-5 {
                    hit = Some(t);
                    break;
                }
                // The ellipsoid terms are estimates, not bounds: step a little short.
                t += (0.8 * d).max(2e-5);
                if t > t1 {
                    break;
                }
            }
            let (t, cover) = match hit {
                Some(t) => (t, 1.0),
                None => (tmin, cov((dmin * s) as f32)),
            };
            if cover <= 0.0 {
                continue;
            }
            let q = org + dir * t;
            let qf = q.as_vec3();
            *o = BodyPix {
                depth: if hit.is_some() {
                    cam.project(qf).z
                } else {
                    f32::NEG_INFINITY
                },
                cover,
                normal: body.normal(qf),
                cloth: body.torso_sdf(q) < body.head.sdf64(q),
            };
        }
    });
    out
}

/// Background, shoulders, head and face features.
pub(super) fn render_base(
    look: &Look,
    cam: &WeakPerspective,
    head: &Head,
    body: &[BodyPix],
    w: usize,
    h: usize,
    s: f32,
) -> Vec<[f32; 3]> {
    let light = Vec3::new(-0.35, 0.45, 0.82).normalize();
    let lm = |n: &str| {
        let q = cam.project(head.landmark(n).unwrap_or(Vec3::ZERO));
        [q.x, q.y]
    };
    // Brows as points of the head's surface, so that they move as the head turns (a video's
    // ground truth) rather than as a flat drawing pinned to the eyes.
    let (la, lb) = (head.params().landmark_a, head.params().landmark_b);
    let brows = [("left_eye", -1.0f32), ("right_eye", 1.0)].map(|(n, side)| {
        let e = head.landmark(n).unwrap_or(Vec3::ZERO);
        [(-side * 0.23, 0.19), (0.0, 0.25), (side * 0.23, 0.19)].map(|(dx, dy)| {
            let q = head.project_to_surface(e + Vec3::new(dx * la, dy * lb, 0.0));
            let q = cam.project(q);
            [q.x, q.y]
        })
    });
    let feat = Features {
        a: head.params().landmark_a * s,
        b: head.params().landmark_b * s,
        brows,
        eyes: [lm("left_eye"), lm("right_eye")],
        nose: lm("nose_tip"),
        mouth: [lm("mouth_left"), lm("mouth_right")],
        px: s / 1000.0,
    };
    let mut out = vec![[0.0f32; 3]; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, c) in row.iter_mut().enumerate() {
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            let (u, v) = (fx / w as f32, fy / h as f32);
            let mut col = mix3(look.bg_top, look.bg_bot, v);
            let n = look.noise.sample(u, v) - 0.5;
            let vig = (u - 0.5).powi(2) + (v - 0.45).powi(2);
            col = scale3(col, (1.0 + 0.25 * n) * (1.0 - 0.35 * vig));
            let b = &body[y * w + x];
            if b.cover > 0.0 {
                let lam = b.normal.dot(light).max(0.0);
                let sc = if b.cloth {
                    scale3(look.cloth, 0.55 + 0.45 * lam)
                } else {
                    scale3(look.skin, 0.72 + 0.3 * lam)
                };
                blend(&mut col, sc, b.cover);
                if !b.cloth && b.depth.is_finite() {
                    feat.draw(&mut col, fx, fy, look);
                }
            }
            *c = col;
        }
    });
    out
}

/// The cartoon face features of `crate::synth` (`Scene::features`), placed relative to the
/// projected landmarks instead of a face ellipse.
pub(super) struct Features {
    pub(super) a: f32,
    pub(super) b: f32,
    /// Three points of each brow (image px), projected from the head's surface.
    pub(super) brows: [[[f32; 2]; 3]; 2],
    pub(super) eyes: [[f32; 2]; 2],
    pub(super) nose: [f32; 2],
    pub(super) mouth: [[f32; 2]; 2],
    /// Length unit: 1 at 1000 px/m.
    pub(super) px: f32,
}

impl Features {
    pub(super) fn draw(&self, c: &mut [f32; 3], x: f32, y: f32, look: &Look) {
        let (a, b, s) = (self.a, self.b, self.px);
        let p = [x, y];
        // Quick reject: far from every feature.
        let near = |q: [f32; 2], r: f32| (x - q[0]).abs() < r && (y - q[1]).abs() < r;
        let r = 0.5 * b;
        let nearby = [
            self.eyes[0],
            self.eyes[1],
            self.nose,
            self.mouth[0],
            self.mouth[1],
        ];
        if !nearby.iter().any(|&q| near(q, r)) {
            return;
        }
        let brow = scale3(look.hair, 0.6);
        for i in 0..2 {
            blend(c, brow, 0.9 * cov(poly_dist(p, &self.brows[i]) - 0.035 * b));
            draw_eye(c, p, self.eyes[i], a, b, s, look.iris);
        }
        draw_nostrils(c, p, self.nose, a, b, look.skin);
        let (ml, mr) = (self.mouth[0], self.mouth[1]);
        let (mcx, my) = (0.5 * (ml[0] + mr[0]), 0.5 * (ml[1] + mr[1]));
        let mw = 0.5 * (mr[0] - ml[0]).abs().max(1e-3);
        draw_mouth(c, p, [mcx, my], mw, b, s, look.lips);
    }
}

/// Per-vertex strand colour: the strand's base colour, Kajiya-Kay diffuse and specular
/// terms from its 3D tangent (a highlight band across the crown), darker deep in the hair.
pub(super) fn shade_strand(st: &[Vec3], v: &StrandVar, look: &Look, view: Vec3) -> Vec<[f32; 3]> {
    let light = Vec3::new(-0.3, 0.6, 0.75).normalize();
    let half = (light + view).normalize();
    let lum = 0.3 * look.hair[0] + 0.59 * look.hair[1] + 0.11 * look.hair[2];
    // A grey sheen keeps dark hair's strands visible, as on real black hair.
    let sheen = 0.16 * (1.0 - lum);
    let base: [f32; 3] = std::array::from_fn(|k| (look.hair[k] + sheen) * v.bright * v.tint[k]);
    let depth = 0.75 + 0.25 * smoothstep(0.0015, 0.012, v.layer);
    let hl = mix3(look.hair, [1.0, 0.97, 0.9], 0.6);
    (0..st.len())
        .map(|i| {
            let (a, b) = (st[i.saturating_sub(1)], st[(i + 1).min(st.len() - 1)]);
            let t = (b - a).normalize_or_zero();
            let tl = t.dot(light);
            let diffuse = (1.0 - tl * tl).max(0.0).sqrt();
            let th = t.dot(half);
            let spec = (1.0 - th * th).max(0.0).powf(30.0);
            let f = depth * (0.55 + 0.45 * diffuse);
            std::array::from_fn(|k| base[k] * f + 0.3 * spec * hl[k])
        })
        .collect()
}

/// Front-most visible strand per pixel: a z-buffer over pixel centres within `radius` px of
/// a projected segment, with the body hiding what lies behind it.
pub(super) struct Footprint {
    pub(super) depth: Vec<f32>,
    pub(super) dir: Vec<[f32; 2]>,
    /// The material point the depth and direction were taken from (a video's true flow
    /// follows it).
    pub(super) hit: Vec<Option<StrandHit>>,
}

impl Footprint {
    pub(super) fn new(
        proj: &[Vec<Vec3>],
        body_depth: &[f32],
        w: usize,
        h: usize,
        r: f32,
        tol: f32,
    ) -> Self {
        let mut depth = vec![f32::NEG_INFINITY; w * h];
        let mut dir = vec![[f32::NAN; 2]; w * h];
        let mut hit = vec![None; w * h];
        for (si, st) in proj.iter().enumerate() {
            for (j, seg) in st.windows(2).enumerate() {
                let (a, b) = (seg[0], seg[1]);
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let l2 = dx * dx + dy * dy;
                // Segments seen end-on have no image direction.
                if l2 < 1e-6 {
                    continue;
                }
                let l = l2.sqrt();
                let u = [dx / l, dy / l];
                let x0 = (a.x.min(b.x) - r).floor().max(0.0) as usize;
                let x1 = ((a.x.max(b.x) + r).ceil().max(0.0) as usize).min(w);
                let y0 = (a.y.min(b.y) - r).floor().max(0.0) as usize;
                let y1 = ((a.y.max(b.y) + r).ceil().max(0.0) as usize).min(h);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let (px, py) = (x as f32 + 0.5 - a.x, y as f32 + 0.5 - a.y);
                        let t = ((px * dx + py * dy) / l2).clamp(0.0, 1.0);
                        if (px - t * dx).hypot(py - t * dy) > r {
                            continue;
                        }
                        let k = y * w + x;
                        let z = a.z + t * (b.z - a.z);
                        if z < body_depth[k] - tol || z <= depth[k] {
                            continue;
                        }
                        depth[k] = z;
                        dir[k] = u;
                        hit[k] = Some(StrandHit {
                            strand: si as u32,
                            segment: j as u32,
                            t,
                        });
                    }
                }
            }
        }
        Footprint { depth, dir, hit }
    }

    pub(super) fn covered(&self) -> Vec<bool> {
        self.depth.iter().map(|d| d.is_finite()).collect()
    }
}

/// Morphological closing (disc of radius r; outside the image counts as hair for the
/// erosion, so hair reaching the border stays), then small holes (< 1% of the image) filled.
/// Returns 255 / 0 bytes.
pub(super) fn close_mask(raw: &[bool], w: usize, h: usize, r: f32) -> Vec<u8> {
    let offs = mask::disc(r, false);
    let mut m = mask::erode_by(&mask::dilate_by(raw, w, h, &offs, false), w, h, &offs, true);
    mask::fill_holes(&mut m, w, h, 0.01);
    m.iter().map(|&b| if b { 255 } else { 0 }).collect()
}

/// gt_dir over the mask: the footprint's direction where a strand passes, elsewhere (gaps
/// the closing filled) that of the nearest covered pixel (breadth-first inside the mask).
/// Mask pixels no covered pixel reaches are dropped from the mask.
pub(super) fn fill_dir(
    fp: &Footprint,
    mut mask: Vec<u8>,
    w: usize,
    h: usize,
) -> (Vec<f32>, Vec<u8>) {
    let mut dir = vec![f32::NAN; 2 * w * h];
    let mut queue = VecDeque::new();
    for k in 0..w * h {
        if mask[k] != 0 && fp.depth[k].is_finite() {
            dir[2 * k] = fp.dir[k][0];
            dir[2 * k + 1] = fp.dir[k][1];
            queue.push_back(k);
        }
    }
    while let Some(k) = queue.pop_front() {
        let (x, y) = ((k % w) as i64, (k / w) as i64);
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            if mask[j] != 0 && dir[2 * j].is_nan() {
                dir[2 * j] = dir[2 * k];
                dir[2 * j + 1] = dir[2 * k + 1];
                queue.push_back(j);
            }
        }
    }
    for k in 0..w * h {
        if dir[2 * k].is_nan() {
            mask[k] = 0;
        }
    }
    (dir, mask)
}

/// Dark base colour of the hair under the mask (soft-edged), so no skin or background
/// shows through gaps between strands.
pub(super) fn base_fill(rgb: &mut [[f32; 3]], mask: &[u8], look: &Look, w: usize, h: usize) {
    let base = scale3(look.hair, 0.4);
    for y in 0..h {
        for x in 0..w {
            let mut sum = 0.0;
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (
                        (x as i64 + dx).clamp(0, w as i64 - 1) as usize,
                        (y as i64 + dy).clamp(0, h as i64 - 1) as usize,
                    );
                    sum += mask[ny * w + nx] as f32 / 255.0;
                }
            }
            let a = if mask[y * w + x] != 0 { 1.0 } else { sum / 9.0 };
            blend(&mut rgb[y * w + x], base, a);
        }
    }
}

/// Draws the strands in painter's order over pieces of 12 segments (sorted by mean depth,
/// far first). Within a piece each pixel keeps its largest coverage, so a strand does not
/// darken its own pixels twice; the body hides what lies behind it.
#[allow(clippy::too_many_arguments)]
pub(super) fn draw_strands(
    rgb: &mut [[f32; 3]],
    proj: &[Vec<Vec3>],
    colors: &[Vec<[f32; 3]>],
    vars: &[StrandVar],
    body_depth: &[f32],
    tol: f32,
    sc: f32,
    w: usize,
    h: usize,
) {
    const PIECE: usize = 12;
    // Arc length (projected px) at every vertex, for the tapers.
    let arcs: Vec<Vec<f32>> = proj
        .iter()
        .map(|st| {
            let mut acc = 0.0;
            let mut a = vec![0.0];
            for q in st.windows(2) {
                acc += (q[1].x - q[0].x).hypot(q[1].y - q[0].y);
                a.push(acc);
            }
            a
        })
        .collect();
    let mut pieces: Vec<(f32, u32, u32)> = Vec::new();
    for (si, st) in proj.iter().enumerate() {
        let nseg = st.len().saturating_sub(1);
        let mut i = 0;
        while i < nseg {
            let j = (i + PIECE).min(nseg);
            let z = st[i..=j].iter().map(|q| q.z).sum::<f32>() / (j - i + 1) as f32;
            pieces.push((z, si as u32, i as u32));
            i = j;
        }
    }
    pieces.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));

    let mut stamp = vec![0u32; w * h];
    let mut cover = vec![0.0f32; w * h];
    let mut col = vec![[0.0f32; 3]; w * h];
    let mut zs = vec![0.0f32; w * h];
    let mut touched = Vec::new();
    let wscale = sc.clamp(0.75, 1.5);
    for (id, &(_, si, i0)) in pieces.iter().enumerate() {
        let id = id as u32 + 1;
        let (si, i0) = (si as usize, i0 as usize);
        let st = &proj[si];
        let arc = &arcs[si];
        let total = *arc.last().unwrap_or(&0.0);
        let v = &vars[si];
        let width = v.width * wscale;
        let half = 0.5 * width;
        let tip_taper = (4.0 * sc).min(0.4 * total).max(1e-3);
        let root_taper = (2.0 * sc).min(0.35 * total).max(1e-3);
        touched.clear();
        let i1 = (i0 + PIECE).min(st.len() - 1);
        for i in i0..i1 {
            let (a, b) = (st[i], st[i + 1]);
            let mid = 0.5 * (arc[i] + arc[i + 1]);
            let taper = smoothstep(0.0, root_taper, mid) * smoothstep(0.0, tip_taper, total - mid);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            let l2 = dx * dx + dy * dy;
            let pad = half + 1.0;
            let x0 = (a.x.min(b.x) - pad).floor().max(0.0) as usize;
            let x1 = ((a.x.max(b.x) + pad).ceil().max(0.0) as usize).min(w);
            let y0 = (a.y.min(b.y) - pad).floor().max(0.0) as usize;
            let y1 = ((a.y.max(b.y) + pad).ceil().max(0.0) as usize).min(h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (px, py) = (x as f32 + 0.5 - a.x, y as f32 + 0.5 - a.y);
                    let t = if l2 > 0.0 {
                        ((px * dx + py * dy) / l2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let d = (px - t * dx).hypot(py - t * dy);
                    let c = (half + 0.5 - d).clamp(0.0, 1.0).min(width) * taper;
                    if c <= 0.0 {
                        continue;
                    }
                    let k = y * w + x;
                    if stamp[k] != id {
                        stamp[k] = id;
                        cover[k] = 0.0;
                        touched.push(k);
                    }
                    if c > cover[k] {
                        cover[k] = c;
                        zs[k] = a.z + t * (b.z - a.z);
                        col[k] = mix3(colors[si][i], colors[si][i + 1], t);
                    }
                }
            }
        }
        for &k in &touched {
            if zs[k] >= body_depth[k] - tol {
                blend(&mut rgb[k], col[k], v.alpha * cover[k]);
            }
        }
    }
}

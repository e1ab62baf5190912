//! Drawing primitives shared with `synth3d`: distances, colour mixing, noise, strands on a canvas.

use crate::base::rng::Rng;

pub(crate) fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Approximate signed distance to an axis-aligned ellipse centred at the origin (first-order,
/// exact on the axes and good near the boundary, which is where anti-aliasing needs it).
pub(crate) fn ellipse_sdf(x: f32, y: f32, rx: f32, ry: f32) -> f32 {
    let k0 = ((x / rx).powi(2) + (y / ry).powi(2)).sqrt();
    let k1 = ((x / (rx * rx)).powi(2) + (y / (ry * ry)).powi(2)).sqrt();
    if k1 < 1e-12 {
        return -rx.min(ry);
    }
    (k0 - 1.0) * k0 / k1
}

pub(crate) fn seg_dist(p: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let (abx, aby) = (b[0] - a[0], b[1] - a[1]);
    let (apx, apy) = (p[0] - a[0], p[1] - a[1]);
    let l2 = abx * abx + aby * aby;
    let t = if l2 > 0.0 {
        ((apx * abx + apy * aby) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (apx - t * abx).hypot(apy - t * aby)
}

/// Distance to a polyline.
pub(crate) fn poly_dist(p: [f32; 2], pts: &[[f32; 2]]) -> f32 {
    pts.windows(2)
        .map(|s| seg_dist(p, s[0], s[1]))
        .fold(f32::INFINITY, f32::min)
}

/// Pixel coverage of a shape from its signed distance (box filter, 1 px wide ramp).
pub(crate) fn cov(d: f32) -> f32 {
    (0.5 - d).clamp(0.0, 1.0)
}

pub(crate) fn blend(c: &mut [f32; 3], col: [f32; 3], a: f32) {
    if a > 0.0 {
        for k in 0..3 {
            c[k] += (col[k] - c[k]) * a;
        }
    }
}

pub(crate) fn scale3(c: [f32; 3], s: f32) -> [f32; 3] {
    c.map(|v| v * s)
}

pub(crate) fn mix3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

pub(crate) fn jitter3(c: [f32; 3], rng: &mut Rng, amount: f32) -> [f32; 3] {
    c.map(|v| (v * (1.0 + amount * rng.range_f32(-1.0, 1.0))).clamp(0.0, 1.0))
}

pub(crate) fn pick<T: Copy>(rng: &mut Rng, xs: &[T]) -> T {
    xs[rng.below(xs.len() as u32) as usize]
}

/// Smooth value noise on a coarse random lattice, for the background.
pub(crate) struct Noise {
    n: usize,
    v: Vec<f32>,
}

impl Noise {
    pub(crate) fn new(n: usize, rng: &mut Rng) -> Self {
        Noise {
            n,
            v: (0..(n + 1) * (n + 1)).map(|_| rng.next_f32()).collect(),
        }
    }

    /// u, v in [0, 1]; result in [0, 1].
    pub(crate) fn sample(&self, u: f32, v: f32) -> f32 {
        let fx = (u.clamp(0.0, 1.0) * self.n as f32).min(self.n as f32 - 1e-3);
        let fy = (v.clamp(0.0, 1.0) * self.n as f32).min(self.n as f32 - 1e-3);
        let (ix, iy) = (fx as usize, fy as usize);
        let (tx, ty) = (
            smoothstep(0.0, 1.0, fx.fract()),
            smoothstep(0.0, 1.0, fy.fract()),
        );
        let at = |x: usize, y: usize| self.v[y * (self.n + 1) + x];
        let top = at(ix, iy) + (at(ix + 1, iy) - at(ix, iy)) * tx;
        let bot = at(ix, iy + 1) + (at(ix + 1, iy + 1) - at(ix, iy + 1)) * tx;
        top + (bot - top) * ty
    }
}

/// Points every `step` px of arc length along a dense path, plus its end.
pub(crate) fn resample(path: &[[f32; 2]], step: f32) -> Vec<[f32; 2]> {
    let mut out = Vec::new();
    let Some(&first) = path.first() else {
        return out;
    };
    out.push(first);
    let mut since = 0.0;
    for q in path.windows(2) {
        since += (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]);
        if since >= step {
            out.push(q[1]);
            since = 0.0;
        }
    }
    let last = *path.last().unwrap_or(&first);
    // Finish at the path's end unless that would leave a stub of a segment.
    if since > 0.4 * step {
        out.push(last);
    }
    out
}

pub(super) fn mark_disk(occ: &mut [bool], w: usize, h: usize, p: [f32; 2], r: f32) {
    let (x0, x1) = (
        (p[0] - r).floor().max(0.0) as usize,
        ((p[0] + r).ceil() as usize).min(w),
    );
    let (y0, y1) = (
        (p[1] - r).floor().max(0.0) as usize,
        ((p[1] + r).ceil() as usize).min(h),
    );
    for y in y0..y1 {
        for x in x0..x1 {
            let (dx, dy) = (x as f32 + 0.5 - p[0], y as f32 + 0.5 - p[1]);
            if dx * dx + dy * dy <= r * r {
                occ[y * w + x] = true;
            }
        }
    }
}

/// Per-strand coverage buffer: each pixel keeps the largest coverage of any segment of the
/// current strand, so overlapping segments do not darken the strand's own pixels twice.
pub(super) struct StrandCanvas {
    w: usize,
    h: usize,
    stamp: Vec<u32>,
    cov: Vec<f32>,
    touched: Vec<usize>,
    id: u32,
}

impl StrandCanvas {
    pub(super) fn new(w: usize, h: usize) -> Self {
        StrandCanvas {
            w,
            h,
            stamp: vec![0; w * h],
            cov: vec![0.0; w * h],
            touched: Vec::new(),
            id: 0,
        }
    }

    /// Rasterises a polyline (root -> tip) of the given width, tapering at both ends but
    /// those `cut` ([root, tip]: hidden there by an occluding layer, so drawn at full width).
    pub(super) fn draw(&mut self, pts: &[[f32; 2]], width: f32, s: f32, cut: [bool; 2]) {
        self.id += 1;
        self.touched.clear();
        let mut arc = Vec::with_capacity(pts.len());
        let mut acc = 0.0f32;
        arc.push(0.0);
        for q in pts.windows(2) {
            acc += (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]);
            arc.push(acc);
        }
        let total = acc;
        // Short fades: longer ones leave more of the hair as flat base fill, which costs more
        // orientation signal than the strand ends do.
        let tip_taper = if cut[1] {
            1e-3
        } else {
            (4.0 * s).min(0.4 * total).max(1e-3)
        };
        let root_taper = if cut[0] {
            1e-3
        } else {
            (2.0 * s).min(0.35 * total).max(1e-3)
        };
        let half = 0.5 * width;
        for (i, q) in pts.windows(2).enumerate() {
            let (a, b) = (q[0], q[1]);
            let mid_arc = 0.5 * (arc[i] + arc[i + 1]);
            let taper =
                smoothstep(0.0, root_taper, mid_arc) * smoothstep(0.0, tip_taper, total - mid_arc);
            let pad = half + 1.0;
            let x0 = (a[0].min(b[0]) - pad).floor().max(0.0) as usize;
            let x1 = ((a[0].max(b[0]) + pad).ceil() as usize).min(self.w);
            let y0 = (a[1].min(b[1]) - pad).floor().max(0.0) as usize;
            let y1 = ((a[1].max(b[1]) + pad).ceil() as usize).min(self.h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let d = seg_dist([x as f32 + 0.5, y as f32 + 0.5], a, b);
                    // Coverage of a pixel by a line of this width (box filter approximation).
                    let c = (half + 0.5 - d).clamp(0.0, 1.0).min(width) * taper;
                    if c <= 0.0 {
                        continue;
                    }
                    let k = y * self.w + x;
                    if self.stamp[k] != self.id {
                        self.stamp[k] = self.id;
                        self.cov[k] = c;
                        self.touched.push(k);
                    } else if c > self.cov[k] {
                        self.cov[k] = c;
                    }
                }
            }
        }
    }

    /// Alpha-composites the last drawn strand; `paint(x, y)` gives colour and opacity.
    pub(super) fn composite(
        &self,
        rgb: &mut [[f32; 3]],
        paint: impl Fn(f32, f32) -> ([f32; 3], f32),
    ) {
        for &k in &self.touched {
            let (x, y) = ((k % self.w) as f32 + 0.5, (k / self.w) as f32 + 0.5);
            let (col, alpha) = paint(x, y);
            blend(&mut rgb[k], col, alpha * self.cov[k]);
        }
    }
}

// Palettes the looks pick from.
const SKINS: [[f32; 3]; 6] = [
    [0.96, 0.80, 0.69],
    [0.92, 0.74, 0.62],
    [0.86, 0.66, 0.52],
    [0.76, 0.55, 0.40],
    [0.58, 0.40, 0.28],
    [0.44, 0.30, 0.21],
];
const HAIRS: [[f32; 3]; 8] = [
    [0.17, 0.14, 0.13],
    [0.30, 0.20, 0.13],
    [0.44, 0.29, 0.17],
    [0.55, 0.26, 0.12],
    [0.80, 0.64, 0.40],
    [0.72, 0.40, 0.18],
    [0.62, 0.60, 0.60],
    [0.36, 0.26, 0.20],
];
const IRISES: [[f32; 3]; 4] = [
    [0.36, 0.22, 0.12],
    [0.25, 0.42, 0.62],
    [0.30, 0.48, 0.30],
    [0.50, 0.38, 0.20],
];

/// Colours and background noise of a portrait, drawn in this order from the look stream
/// (the 2D and 3D portraits share them, so their looks match).
pub(crate) struct Look {
    pub(crate) skin: [f32; 3],
    pub(crate) hair: [f32; 3],
    pub(crate) iris: [f32; 3],
    pub(crate) lips: [f32; 3],
    pub(crate) cloth: [f32; 3],
    pub(crate) bg_top: [f32; 3],
    pub(crate) bg_bot: [f32; 3],
    pub(crate) noise: Noise,
}

impl Look {
    pub(crate) fn new(look: &mut Rng) -> Look {
        let bg_top = mix3(
            [look.next_f32(), look.next_f32(), look.next_f32()],
            [0.75, 0.75, 0.75],
            0.55,
        );
        let bg_bot = scale3(bg_top, look.range_f32(0.55, 0.8));
        Look {
            skin: jitter3(pick(look, &SKINS), look, 0.04),
            hair: jitter3(pick(look, &HAIRS), look, 0.08),
            iris: jitter3(pick(look, &IRISES), look, 0.1),
            lips: jitter3([0.72, 0.36, 0.36], look, 0.1),
            cloth: mix3(
                [look.next_f32(), look.next_f32(), look.next_f32()],
                [0.3, 0.3, 0.3],
                0.4,
            ),
            bg_top,
            bg_bot,
            noise: Noise::new(6, look),
        }
    }
}

// Face features, sized by the face ellipse's semi-axes a (half width) and b (half height)
// and the length unit s; `p` is the pixel centre being shaded.

/// An eye centred at `e`: sclera, iris, pupil, glint and upper lid.
pub(crate) fn draw_eye(
    c: &mut [f32; 3],
    p: [f32; 2],
    e: [f32; 2],
    a: f32,
    b: f32,
    s: f32,
    iris_col: [f32; 3],
) {
    let ([x, y], [ex, ey]) = (p, e);
    let scl = ellipse_sdf(x - ex, y - ey, 0.18 * a, 0.075 * b);
    blend(c, [0.95, 0.94, 0.92], cov(scl));
    let iris = ((x - ex).hypot(y - ey) - 0.065 * b).max(scl);
    blend(c, iris_col, cov(iris));
    let pupil = (x - ex).hypot(y - ey) - 0.03 * b;
    blend(c, [0.03, 0.03, 0.03], cov(pupil));
    let glint = (x - ex - 0.02 * b).hypot(y - ey + 0.02 * b) - 0.012 * b;
    blend(c, [1.0, 1.0, 1.0], 0.9 * cov(glint));
    let lid = (scl.abs() - 0.9 * s).max(y - ey);
    blend(c, [0.12, 0.08, 0.07], cov(lid));
}

/// Two nostrils beside and just below the nose tip `n`.
pub(crate) fn draw_nostrils(
    c: &mut [f32; 3],
    p: [f32; 2],
    n: [f32; 2],
    a: f32,
    b: f32,
    skin: [f32; 3],
) {
    let ([x, y], [nx, ny]) = (p, n);
    for side in [-1.0f32, 1.0] {
        let nos = ellipse_sdf(
            x - (nx + side * 0.09 * a),
            y - (ny + 0.015 * b),
            0.05 * a,
            0.022 * b,
        );
        blend(c, scale3(skin, 0.5), cov(nos));
    }
}

/// Lips centred at `m` with half width `mw`, and the line between them, smiling slightly.
pub(crate) fn draw_mouth(
    c: &mut [f32; 3],
    p: [f32; 2],
    m: [f32; 2],
    mw: f32,
    b: f32,
    s: f32,
    lips_col: [f32; 3],
) {
    let ([x, y], [mx, my]) = (p, m);
    let lips = ellipse_sdf(x - mx, y - (my + 0.01 * b), mw * 1.02, 0.065 * b);
    blend(c, lips_col, cov(lips));
    let line = [
        [mx - mw, my],
        [mx - 0.5 * mw, my + 0.02 * b],
        [mx, my + 0.025 * b],
        [mx + 0.5 * mw, my + 0.02 * b],
        [mx + mw, my],
    ];
    blend(c, [0.3, 0.1, 0.1], cov(poly_dist(p, &line) - 0.7 * s));
}

/// Linear [0, 1] RGB to 8-bit pixels (clamped, rounded).
pub(crate) fn to_image(rgb: &[[f32; 3]], width: u32, height: u32) -> image::RgbImage {
    let mut image = image::RgbImage::new(width, height);
    for (px, c) in image.pixels_mut().zip(rgb) {
        *px = image::Rgb(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
    }
    image
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn to_image_clamps_and_rounds() {
        let img = to_image(&[[-0.5, 0.5, 2.0], [0.2, 0.0, 1.0]], 2, 1);
        assert_eq!(img.get_pixel(0, 0).0, [0, 128, 255]);
        assert_eq!(img.get_pixel(1, 0).0, [51, 0, 255]);
    }

    /// A strand hidden at its tip by an occluding layer ends at full width; a free tip fades.
    #[test]
    fn a_cut_end_is_drawn_at_full_width_and_a_free_end_tapers() {
        // 20 px along y = 10.5 from x = 4 to x = 24.
        let pts: Vec<[f32; 2]> = (0..=40).map(|i| [4.0 + 0.5 * i as f32, 10.5]).collect();
        let cov = |cut: [bool; 2]| {
            let mut c = StrandCanvas::new(32, 21);
            c.draw(&pts, 1.2, 1.0, cut);
            // Half a pixel inside the tip, and the middle.
            (c.cov[10 * 32 + 23], c.cov[10 * 32 + 14])
        };
        let (free_tip, mid) = cov([false, false]);
        let (cut_tip, mid_cut) = cov([false, true]);
        assert_eq!(mid, mid_cut);
        assert!(mid > 0.9, "{mid}");
        assert!(cut_tip >= 0.9 * mid, "cut tip {cut_tip} against {mid}");
        assert!(free_tip < 0.5 * mid, "free tip {free_tip} against {mid}");
    }

    #[test]
    fn look_is_deterministic_and_near_its_palettes() {
        let a = Look::new(&mut Rng::new(5));
        let b = Look::new(&mut Rng::new(5));
        assert_eq!((a.skin, a.hair, a.bg_bot), (b.skin, b.hair, b.bg_bot));
        let near = |c: [f32; 3], p: &[[f32; 3]]| {
            p.iter()
                .any(|q| (0..3).all(|k| (c[k] - q[k]).abs() <= 0.08 + 1e-6))
        };
        assert!(near(a.skin, &SKINS) && near(a.hair, &HAIRS) && near(a.iris, &IRISES));
    }

    #[test]
    fn face_features_paint_near_their_centres_only() {
        let (a, b, s) = (60.0, 80.0, 1.0);
        let paint = |f: &dyn Fn(&mut [f32; 3], [f32; 2])| {
            [[100.0, 100.0], [300.0, 300.0]].map(|p| {
                let mut c = [0.5; 3];
                f(&mut c, p);
                c
            })
        };
        let eye = paint(&|c, p| draw_eye(c, p, [100.0, 100.0], a, b, s, [0.0, 1.0, 0.0]));
        assert!(eye[0].iter().all(|&v| v < 0.1), "pupil {:?}", eye[0]);
        let nose = paint(&|c, p| draw_nostrils(c, p, [100.0 - 5.4, 98.8], a, b, [0.8; 3]));
        assert_eq!(nose[0], [0.4; 3]);
        let mouth = paint(&|c, p| draw_mouth(c, p, [100.0, 99.2], 30.0, b, s, [1.0, 0.0, 0.0]));
        assert!(mouth[0][0] > mouth[0][1]);
        for c in [eye[1], nose[1], mouth[1]] {
            assert_eq!(c, [0.5; 3]);
        }
    }
}

//! The 2D portrait's scene: face, body, hair region and looks, and how it draws hair and strokes.

use super::draw::{mark_disk, StrandCanvas};
use super::field::{normalize, Field};
use super::texture::{Curl, Texture};
use super::*;

#[derive(Clone, Debug)]
enum Region {
    /// Rounded top over the head, then a curtain widening down to `y_bot`.
    Long {
        rx: f32,
        ry: f32,
        hw_bot: f32,
        y_bot: f32,
    },
    /// A cap over the skull ellipse, cut at `y_cut`; with a fringe, the face above the fringe
    /// line is hair too.
    Cap {
        rx: f32,
        ry: f32,
        y_cut: f32,
        fringe: Option<Fringe>,
    },
}

#[derive(Clone, Debug)]
struct Fringe {
    x_near: f32,
    x_far: f32,
    y_near: f32,
    y_far: f32,
}

impl Fringe {
    fn y(&self, x: f32) -> f32 {
        self.y_near + (self.y_far - self.y_near) * smoothstep(self.x_near, self.x_far, x)
    }
}

pub(super) struct Scene {
    w: f32,
    h: f32,
    /// Length unit: 1 at 512 px.
    s: f32,
    /// Face ellipse.
    cx: f32,
    cy: f32,
    a: f32,
    b: f32,
    /// Head (skull) centre.
    hx: f32,
    hy: f32,
    region: Region,
    pub(super) field: Field,
    /// Whorl centre, kept clear of strokes.
    singular: Option<[f32; 2]>,
    look: Look,
    /// Strand lengths (min, max), px.
    strand_len: (f32, f32),
    /// No strand starts closer than this to an earlier one, px; neighbouring strands end up
    /// one to two times this apart.
    spacing: f32,
    /// Strand width and contrast factors of the texture.
    width_scale: f32,
    contrast: f32,
}

impl Scene {
    pub(super) fn new(p: &SynthParams, t: &Texture, g: &mut Rng, look: &mut Rng) -> Scene {
        let (w, h) = (p.width as f32, p.height as f32);
        let s = w.min(h) / 512.0;
        let a = 84.0 * s * (1.0 + 0.05 * g.range_f32(-1.0, 1.0));
        let b = a * g.range_f32(1.25, 1.36);
        let cx = w * 0.5 + g.range_f32(-0.025, 0.025) * w.min(h);
        let cy = h * 0.5 + g.range_f32(0.0, 0.025) * h.min(w);
        let (hx, hy) = (cx, cy - 0.3 * b);
        let side = if g.next_f32() < 0.5 { -1.0 } else { 1.0 };

        let (region, field, singular, strand_len, spacing) = match p.style {
            Style::Long => {
                let y_bot = cy + b * g.range_f32(2.25, 2.4);
                let field = Field::Part {
                    px: cx + g.range_f32(-0.06, 0.06) * a,
                    hy,
                    rx_l: a,
                    rx_r: a,
                    ry: b,
                    amax_l: 0.8 * PI,
                    amax_r: 0.8 * PI,
                    wave_amp: g.range_f32(0.08, 0.16),
                    wave_k: std::f32::consts::TAU / (g.range_f32(90.0, 140.0) * s),
                    wave_phase: g.range_f32(0.0, std::f32::consts::TAU),
                    flare: g.range_f32(0.05, 0.15),
                    y_low: cy - 0.2 * b,
                    y_bottom: y_bot,
                };
                let region = Region::Long {
                    rx: a * g.range_f32(1.55, 1.62),
                    ry: b * g.range_f32(1.28, 1.36),
                    hw_bot: a * g.range_f32(2.3, 2.5),
                    y_bot,
                };
                (region, field, None, (90.0 * s, 260.0 * s), 3.0 * s.max(0.5))
            }
            Style::SidePart => {
                let px = cx + side * a * g.range_f32(0.38, 0.5);
                // The big side sweeps flatter across the forehead.
                let (big_rx, small_rx) = (a * g.range_f32(1.5, 1.8), a * 0.8);
                let (rx_l, rx_r, amax_l, amax_r) = if side < 0.0 {
                    (small_rx, big_rx, 0.8 * PI, PI)
                } else {
                    (big_rx, small_rx, PI, 0.8 * PI)
                };
                let field = Field::Part {
                    px,
                    hy,
                    rx_l,
                    rx_r,
                    ry: 0.7 * b,
                    amax_l,
                    amax_r,
                    wave_amp: 0.0,
                    wave_k: 0.0,
                    wave_phase: 0.0,
                    flare: g.range_f32(0.0, 0.1),
                    y_low: cy - 0.3 * b,
                    y_bottom: cy + 0.4 * b,
                };
                let region = Region::Cap {
                    rx: a * g.range_f32(1.3, 1.38),
                    ry: b * g.range_f32(1.32, 1.4),
                    y_cut: cy + g.range_f32(0.1, 0.25) * b,
                    fringe: Some(Fringe {
                        x_near: px + side * -0.2 * a,
                        x_far: cx - side * 0.9 * a,
                        y_near: cy - 1.0 * b,
                        y_far: cy - g.range_f32(0.42, 0.5) * b,
                    }),
                };
                (region, field, None, (40.0 * s, 130.0 * s), 3.0 * s.max(0.5))
            }
            Style::Whorl => {
                let ry = b * g.range_f32(1.32, 1.4);
                let wx = cx + g.range_f32(-0.3, 0.3) * a + 0.27;
                let wy = hy - ry * g.range_f32(0.62, 0.72) + 0.31;
                let field = Field::Whorl {
                    wx,
                    wy,
                    twist: side * g.range_f32(0.8, 1.15),
                    fall: g.range_f32(0.45, 0.6),
                    r0: 0.25 * b,
                    r1: 1.2 * b,
                };
                let region = Region::Cap {
                    rx: a * g.range_f32(1.28, 1.36),
                    ry,
                    y_cut: cy - g.range_f32(0.05, 0.15) * b,
                    fringe: None,
                };
                (
                    region,
                    field,
                    Some([wx, wy]),
                    (25.0 * s, 75.0 * s),
                    3.0 * s.max(0.5),
                )
            }
            Style::Short => {
                let ry = b * g.range_f32(1.26, 1.32);
                let field = Field::Radial {
                    ox: cx + g.range_f32(-0.25, 0.25) * a,
                    oy: hy - ry - g.range_f32(0.1, 0.2) * b,
                    twist: side * g.range_f32(0.05, 0.2),
                };
                let region = Region::Cap {
                    rx: a * g.range_f32(1.22, 1.3),
                    ry,
                    y_cut: cy - g.range_f32(0.1, 0.2) * b,
                    fringe: None,
                };
                (region, field, None, (15.0 * s, 40.0 * s), 3.0 * s.max(0.5))
            }
            Style::Fringe => {
                let ry = b * g.range_f32(1.32, 1.4);
                // The side hair falls from a crown well above the head, so it is steep
                // (≥ 60° from horizontal) all along the seam, while the fringe sweeps within
                // 16° of horizontal: the orientation jumps by ≥ 45° across the seam.
                let rest = Field::Radial {
                    ox: cx + g.range_f32(-0.15, 0.15) * a,
                    oy: hy - ry - g.range_f32(0.5, 0.7) * b,
                    twist: side * g.range_f32(0.0, 0.08),
                };
                // The fringe's ellipse is widest at the lowest point of the fringe line and
                // no wider than the face there, so below it the ellipse lies inside the bare
                // face: the fringe ends on the face, with no thin strip of it running down
                // beside the face (where the seam would be a few pixels from the edge).
                let ey = cy - 0.4 * b;
                let face_half = a * (1.0 - ((ey - cy) / b).powi(2)).sqrt();
                let field = Field::Fringe {
                    ex: cx,
                    ey,
                    erx: 0.98 * face_half,
                    ery: b * g.range_f32(0.53, 0.58),
                    sweep: side,
                    beta0: g.range_f32(6.0, 10.0).to_radians(),
                    beta1: g.range_f32(3.0, 6.0).to_radians(),
                    rest: Box::new(rest),
                };
                // The fringe covers the forehead down to a line that drops towards the side
                // it sweeps to.
                let region = Region::Cap {
                    rx: a * g.range_f32(1.28, 1.36),
                    ry,
                    y_cut: cy + g.range_f32(0.1, 0.25) * b,
                    fringe: Some(Fringe {
                        x_near: cx - side * 0.9 * a,
                        x_far: cx + side * 0.9 * a,
                        y_near: cy - g.range_f32(0.55, 0.62) * b,
                        y_far: cy - g.range_f32(0.4, 0.46) * b,
                    }),
                };
                (region, field, None, (30.0 * s, 100.0 * s), 3.0 * s.max(0.5))
            }
        };

        // Drawn last, and only with curl, so the default texture keeps every draw it had.
        let field = match Curl::new(t, s, g) {
            Some(curl) => Field::Curled {
                base: Box::new(field),
                curl,
            },
            None => field,
        };
        let look = Look::new(look);
        Scene {
            w,
            h,
            s,
            cx,
            cy,
            a,
            b,
            hx,
            hy,
            region,
            field,
            singular,
            look,
            strand_len,
            spacing,
            width_scale: t.width,
            contrast: t.contrast,
        }
    }

    /// Signed distance (approximate, px) to the hair region; negative on hair.
    pub(super) fn hair_sdf(&self, x: f32, y: f32) -> f32 {
        let (cx, cy, a, b) = (self.cx, self.cy, self.a, self.b);
        let face = ellipse_sdf(x - cx, y - cy, a, b);
        match &self.region {
            Region::Long {
                rx,
                ry,
                hw_bot,
                y_bot,
            } => {
                let dx = (x - cx).abs();
                let env = if y < self.hy {
                    ellipse_sdf(x - self.hx, y - self.hy, *rx, *ry)
                } else {
                    let hw = rx + (hw_bot - rx) * smoothstep(self.hy, *y_bot, y);
                    // Ends lowest in the middle of each side, like combed-down long hair.
                    let mid = (dx - 1.3 * a) / (0.9 * a);
                    let bottom = y_bot - 0.25 * b * mid * mid;
                    (dx - hw).max(y - bottom)
                };
                env.max(-face).max(-self.body_band_sdf(x, y))
            }
            Region::Cap {
                rx,
                ry,
                y_cut,
                fringe,
            } => {
                let env = ellipse_sdf(x - self.hx, y - self.hy, *rx, *ry).max(y - y_cut);
                let bare_face = match fringe {
                    None => face,
                    Some(f) => face.max(f.y(x) - y),
                };
                env.max(-bare_face)
            }
        }
    }

    /// The neck, and lower down the chest, which long hair leaves visible.
    fn body_band_sdf(&self, x: f32, y: f32) -> f32 {
        let (cy, a, b) = (self.cy, self.a, self.b);
        let hw = 0.4 * a + 0.7 * a * smoothstep(cy + 1.5 * b, cy + 2.4 * b, y);
        ((x - self.cx).abs() - hw).max(cy + 0.3 * b - y)
    }

    fn eye(&self, side: f32) -> [f32; 2] {
        [self.cx + side * 0.4 * self.a, self.cy - 0.1 * self.b]
    }
    fn nose_tip(&self) -> [f32; 2] {
        [self.cx, self.cy + 0.3 * self.b]
    }
    fn mouth(&self, side: f32) -> [f32; 2] {
        [self.cx + side * 0.32 * self.a, self.cy + 0.56 * self.b]
    }
    fn chin(&self) -> [f32; 2] {
        [self.cx, self.cy + self.b]
    }

    pub(super) fn landmarks(&self) -> Landmarks {
        let mut m = BTreeMap::new();
        m.insert("left_eye".into(), self.eye(-1.0));
        m.insert("right_eye".into(), self.eye(1.0));
        m.insert("nose_tip".into(), self.nose_tip());
        m.insert("mouth_left".into(), self.mouth(-1.0));
        m.insert("mouth_right".into(), self.mouth(1.0));
        m.insert("chin".into(), self.chin());
        Landmarks::new(m)
    }

    /// Brightness factor for hair: a highlight ring on the crown, darker further down and
    /// near the edges of the hair. Slowly varying, so it adds almost no gradient energy.
    fn hair_shade(&self, x: f32, y: f32, sdf: f32) -> f32 {
        let (rx, ry) = match &self.region {
            Region::Long { rx, ry, .. } | Region::Cap { rx, ry, .. } => (*rx, *ry),
        };
        let q = ((x - self.hx) / rx).hypot((y - self.hy) / ry);
        let upper = if y < self.hy {
            1.0
        } else {
            (-((y - self.hy) / (0.5 * self.b)).powi(2)).exp()
        };
        let ring = (-((q - 0.72) / 0.13).powi(2)).exp() * upper;
        let low = smoothstep(self.hy, self.hy + 2.5 * self.b, y);
        let edge = 1.0 - smoothstep(0.0, 10.0 * self.s, -sdf);
        0.85 + 0.4 * ring - 0.2 * low - 0.2 * edge
    }

    /// Everything but the strands: background, body, face and the base fill of the hair.
    pub(super) fn render_base(&self) -> Vec<[f32; 3]> {
        let (w, h) = (self.w as usize, self.h as usize);
        let mut out = vec![[0.0f32; 3]; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, c) in row.iter_mut().enumerate() {
                *c = self.base_pixel(x as f32 + 0.5, y as f32 + 0.5);
            }
        });
        out
    }

    fn base_pixel(&self, x: f32, y: f32) -> [f32; 3] {
        let (cx, cy, a, b, s) = (self.cx, self.cy, self.a, self.b, self.s);
        let (u, v) = (x / self.w, y / self.h);
        let mut c = mix3(self.look.bg_top, self.look.bg_bot, v);
        let n = self.look.noise.sample(u, v) - 0.5;
        let vig = (u - 0.5).powi(2) + (v - 0.45).powi(2);
        c = scale3(c, (1.0 + 0.25 * n) * (1.0 - 0.35 * vig));

        // Shoulders and neck.
        let torso = ellipse_sdf(x - cx, y - (cy + 3.25 * b), 2.7 * a, 1.75 * b);
        let shade = 0.8 + 0.2 * smoothstep(cy + 1.5 * b, cy + 2.4 * b, y);
        blend(&mut c, scale3(self.look.cloth, shade), cov(torso));
        let neck = ((x - cx).abs() - 0.4 * a).max(cy + 0.3 * b - y).max(-torso);
        let neck_shade = 0.72 + 0.16 * smoothstep(cy + b, cy + 1.35 * b, y);
        blend(&mut c, scale3(self.look.skin, neck_shade), cov(neck));
        // Collar line where neck meets clothing.
        blend(
            &mut c,
            scale3(self.look.cloth, 0.6),
            cov(torso.abs() - 1.0 * s) * cov((x - cx).abs() - 0.55 * a),
        );

        // Ears, then the face.
        for side in [-1.0f32, 1.0] {
            let e = ellipse_sdf(
                x - (cx + side * 0.97 * a),
                y - (cy + 0.02 * b),
                0.16 * a,
                0.22 * b,
            );
            blend(&mut c, scale3(self.look.skin, 0.88), cov(e));
        }
        let face = ellipse_sdf(x - cx, y - cy, a, b);
        if face < 1.0 {
            let q2 = ((x - cx) / a).powi(2) + ((y - cy) / b).powi(2);
            let mut fc = scale3(self.look.skin, 0.9 + 0.1 * (1.0 - q2).max(0.0));
            for side in [-1.0f32, 1.0] {
                let ch = ((x - (cx + side * 0.55 * a)) / (0.2 * a)).powi(2)
                    + ((y - (cy + 0.3 * b)) / (0.12 * b)).powi(2);
                blend(&mut fc, [0.9, 0.45, 0.45], 0.18 * (-ch).exp());
            }
            blend(&mut c, fc, cov(face));
            self.features(&mut c, x, y);
        }

        // Dark base fill of the hair: strands go on top, and no background shows through gaps.
        let hs = self.hair_sdf(x, y);
        if hs < 1.0 {
            let shade = self.hair_shade(x, y, hs);
            blend(&mut c, scale3(self.look.hair, 0.4 * shade), cov(hs));
        }
        c
    }

    fn features(&self, c: &mut [f32; 3], x: f32, y: f32) {
        let (cx, cy, a, b, s) = (self.cx, self.cy, self.a, self.b, self.s);
        let p = [x, y];
        let brow = scale3(self.look.hair, 0.6);
        for side in [-1.0f32, 1.0] {
            // Eyebrow: a thick arc.
            let pts = [
                [cx + side * 0.17 * a, cy - 0.29 * b],
                [cx + side * 0.4 * a, cy - 0.35 * b],
                [cx + side * 0.63 * a, cy - 0.29 * b],
            ];
            blend(c, brow, 0.9 * cov(poly_dist(p, &pts) - 0.035 * b));

            draw_eye(c, p, self.eye(side), a, b, s, self.look.iris);
        }

        // Nose: a soft side shadow and two nostrils.
        let [nx, ny] = self.nose_tip();
        let bridge = [
            [cx + 0.07 * a, cy - 0.05 * b],
            [nx + 0.09 * a, ny - 0.04 * b],
        ];
        blend(
            c,
            scale3(self.look.skin, 0.75),
            0.5 * cov(poly_dist(p, &bridge) - 1.2 * s),
        );
        draw_nostrils(c, p, [nx, ny], a, b, self.look.skin);

        // Mouth: lips and the line between them, smiling slightly.
        let [ml, my] = self.mouth(-1.0);
        draw_mouth(c, p, [cx, my], cx - ml, b, s, self.look.lips);
    }

    // -----------------------------------------------------------------------------------------
    // Strands.

    /// Follows the field (sign +1) or against it (-1) from `start` for up to `len` px with
    /// RK4 steps of `h`, stopping at the hair boundary and where the field jumps (a part) or
    /// turns too fast (the whorl centre). Returns the points after `start`.
    fn trace(&self, start: [f32; 2], sign: f32, len: f32, h: f32, keep_in: f32) -> Vec<[f32; 2]> {
        self.trace_cut(start, sign, len, h, keep_in).0
    }

    /// [`Self::trace`], and whether the strand was cut by the fringe's seam (stopped at the
    /// discontinuity there).
    pub(super) fn trace_cut(
        &self,
        start: [f32; 2],
        sign: f32,
        len: f32,
        h: f32,
        keep_in: f32,
    ) -> (Vec<[f32; 2]>, bool) {
        let f = |p: [f32; 2]| {
            let d = self.field.dir(p[0], p[1]);
            [sign * d[0], sign * d[1]]
        };
        let dot = |a: [f32; 2], b: [f32; 2]| a[0] * b[0] + a[1] * b[1];
        let mut out = Vec::new();
        let mut p = start;
        let mut prev = f(p);
        let mut travelled = 0.0;
        while travelled + 0.5 * h < len {
            let k1 = f(p);
            let k2 = f([p[0] + 0.5 * h * k1[0], p[1] + 0.5 * h * k1[1]]);
            let k3 = f([p[0] + 0.5 * h * k2[0], p[1] + 0.5 * h * k2[1]]);
            let ahead = [p[0] + h * k3[0], p[1] + h * k3[1]];
            let k4 = f(ahead);
            // Stages that disagree mean a discontinuity within the step: stop before it.
            // Where it is the fringe's seam the strand is cut there, not ended: the side
            // hair passes under the fringe, and the fringe's edge hides where its own strands
            // go on, so that end is drawn at full width, as an occluding edge is in a photo
            // (tapered, both layers faded into the seam and the image hardly showed it).
            if dot(k1, k2) < 0.8 || dot(k1, k3) < 0.8 || dot(k1, k4) < 0.8 || dot(k1, prev) < 0.8 {
                let seam =
                    self.field.in_fringe(p[0], p[1]) != self.field.in_fringe(ahead[0], ahead[1]);
                return (out, seam);
            }
            let d = [
                (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]) / 6.0,
                (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]) / 6.0,
            ];
            let q = [p[0] + h * d[0], p[1] + h * d[1]];
            let inside = q[0] >= keep_in
                && q[1] >= keep_in
                && q[0] < self.w - keep_in
                && q[1] < self.h - keep_in
                && self.hair_sdf(q[0], q[1]) < -keep_in;
            if !inside {
                break;
            }
            travelled += h * d[0].hypot(d[1]);
            out.push(q);
            p = q;
            prev = k1;
        }
        (out, false)
    }

    /// Draws the strands over `rgb`: seeds at random over the hair, each accepted only where
    /// no strand passes within `spacing` yet, so the hair is covered evenly.
    pub(super) fn draw_hair(&self, rgb: &mut [[f32; 3]], mask: &[u8], rng: &mut Rng) {
        let (w, h) = (self.w as usize, self.h as usize);
        // Candidate seeds: one jittered point per 2x2 cell, in random order.
        let mut seeds = Vec::new();
        for gy in (0..h).step_by(2) {
            for gx in (0..w).step_by(2) {
                let p = [
                    gx as f32 + rng.range_f32(0.0, 2.0),
                    gy as f32 + rng.range_f32(0.0, 2.0),
                ];
                let (ix, iy) = (p[0] as usize, p[1] as usize);
                if ix < w && iy < h && mask[iy * w + ix] > 0 {
                    seeds.push(p);
                }
            }
        }
        for i in (1..seeds.len()).rev() {
            seeds.swap(i, rng.below(i as u32 + 1) as usize);
        }

        let mut occ = vec![false; w * h];
        let mut canvas = StrandCanvas::new(w, h);
        let step = 0.5;
        let r_occ = self.spacing;
        for seed in seeds {
            let (ix, iy) = (seed[0] as usize, seed[1] as usize);
            if occ[iy * w + ix] {
                continue;
            }
            let len = rng.range_f32(self.strand_len.0, self.strand_len.1);
            let back = len * rng.next_f32();
            let (mut pts, cut_root) = self.trace_cut(seed, -1.0, back, step, 0.0);
            pts.reverse();
            pts.push(seed);
            let (fwd, cut_tip) = self.trace_cut(seed, 1.0, len - back, step, 0.0);
            pts.extend(fwd);

            // Keep the strand's neighbourhood from seeding parallel copies of it.
            mark_disk(&mut occ, w, h, seed, r_occ);
            for q in &pts {
                mark_disk(&mut occ, w, h, *q, r_occ);
            }
            if pts.len() < 3 {
                continue;
            }
            let bright =
                1.0 + self.contrast * ((1.0 + 0.4 * rng.normal_f32()).clamp(0.55, 1.6) - 1.0);
            let tint = [
                1.0 + 0.05 * rng.range_f32(-1.0, 1.0),
                1.0 + 0.05 * rng.range_f32(-1.0, 1.0),
                1.0 + 0.05 * rng.range_f32(-1.0, 1.0),
            ];
            // A grey sheen keeps dark hair's strands visible, as on real black hair.
            let lum = 0.3 * self.look.hair[0] + 0.59 * self.look.hair[1] + 0.11 * self.look.hair[2];
            let sheen = 0.16 * (1.0 - lum);
            let col = [
                (self.look.hair[0] + sheen) * bright * tint[0],
                (self.look.hair[1] + sheen) * bright * tint[1],
                (self.look.hair[2] + sheen) * bright * tint[2],
            ];
            let width = rng.range_f32(1.0, 1.5) * self.s.clamp(0.75, 1.5) * self.width_scale;
            let alpha = rng.range_f32(0.6, 0.95) * self.contrast;
            canvas.draw(&pts, width, self.s, [cut_root, cut_tip]);
            canvas.composite(rgb, |x, y| {
                let sd = self.hair_sdf(x, y);
                (scale3(col, self.hair_shade(x, y, sd)), alpha)
            });
        }
        self.draw_parting(rgb, mask);
    }

    /// A parting shows a thin line of scalp where the hair leaves it both ways; it is what
    /// tells a viewer (and the 2D tracer) that the strands on either side are not one curve.
    fn draw_parting(&self, rgb: &mut [[f32; 3]], mask: &[u8]) {
        let Field::Part { px, hy, .. } = self.field else {
            return;
        };
        let (w, h) = (self.w as usize, self.h as usize);
        let half = 0.9 * self.s.max(0.75);
        let scalp = scale3(self.look.skin, 0.8);
        let x0 = ((px - half - 1.0).floor().max(0.0)) as usize;
        let x1 = ((px + half + 1.0).ceil() as usize).min(w - 1);
        for y in 0..(hy.max(0.0) as usize).min(h) {
            for x in x0..=x1 {
                let i = y * w + x;
                if mask[i] == 0 {
                    continue;
                }
                // Box-filtered coverage of the band |x - px| < half by the pixel.
                let cover =
                    ((x as f32 + 1.0).min(px + half) - (x as f32).max(px - half)).clamp(0.0, 1.0);
                for c in 0..3 {
                    rgb[i][c] += cover * (scalp[c] - rgb[i][c]);
                }
            }
        }
    }

    // -----------------------------------------------------------------------------------------
    // Strokes.

    /// 4-6 direction strokes along the true field, well inside the hair, spread out; for
    /// fields with a part at least one on each side.
    pub(super) fn make_strokes(&self, mask: &[u8], gt_dir: &[f32], rng: &mut Rng) -> Strokes {
        // Thin hair at a small size (short hair at 128²) has no room for strokes that keep
        // the full margin from the edge: then a smaller margin, rather than no strokes.
        let mut strokes = Strokes::new(Vec::new());
        for margin_scale in [1.0, 0.5, 0.25] {
            strokes = self.make_strokes_with(mask, gt_dir, rng, margin_scale);
            if !strokes.strokes.is_empty() {
                break;
            }
        }
        strokes
    }

    fn make_strokes_with(
        &self,
        mask: &[u8],
        gt_dir: &[f32],
        rng: &mut Rng,
        margin_scale: f32,
    ) -> Strokes {
        let (w, h) = (self.w as usize, self.h as usize);
        let s = self.s;
        let want = 4 + rng.below(3) as usize;
        let margin = 7.0 * s.max(0.6) * margin_scale;
        // Deep hair points, as candidate starting places.
        let mut cands = Vec::new();
        for _ in 0..4000 {
            let p = [rng.range_f32(0.0, self.w), rng.range_f32(0.0, self.h)];
            let (ix, iy) = (p[0] as usize, p[1] as usize);
            if mask[iy * w + ix] == 0 || self.hair_sdf(p[0], p[1]) > -1.8 * margin {
                continue;
            }
            if let Some(c) = self.singular {
                if (p[0] - c[0]).hypot(p[1] - c[1]) < 20.0 * s {
                    continue;
                }
            }
            cands.push(p);
        }
        let mut strokes: Vec<Stroke> = Vec::new();
        let mut used: Vec<[f32; 2]> = Vec::new();
        let mut sides_needed: Vec<i32> = match self.field {
            Field::Part { .. } => vec![-1, 1],
            _ => vec![],
        };
        // Where a user starts a stroke on each side of a part: just beside the part line,
        // near the top of the hair, drawn away from it. Both sides then have a stroke where
        // their curves meet head-on, which is what decides the sign of curves near a part.
        let part_anchor = |sd: i32| -> Option<[f32; 2]> {
            let Field::Part { px, .. } = self.field else {
                return None;
            };
            let x = px + sd as f32 * 14.0 * s;
            let top = cands
                .iter()
                .filter(|p| (p[0] - x).abs() < 12.0 * s)
                .map(|p| p[1])
                .fold(f32::INFINITY, f32::min);
            top.is_finite().then_some([x, top])
        };
        let anchors = [part_anchor(-1), part_anchor(1)];
        let mut tries = 0;
        while strokes.len() < want && !cands.is_empty() && tries < 200 {
            tries += 1;
            // Farthest from what is already drawn, restricted to a needed part side first.
            let side = sides_needed.first().copied();
            let anchor = side.and_then(|sd| anchors[(sd > 0) as usize]);
            let best = cands
                .iter()
                .enumerate()
                .filter(|(_, p)| side.is_none_or(|sd| self.field.side(p[0]) == sd))
                .map(|(i, p)| {
                    if let Some(a) = anchor {
                        return (i, -(p[0] - a[0]).hypot(p[1] - a[1]));
                    }
                    let d = used
                        .iter()
                        .map(|q| (p[0] - q[0]).hypot(p[1] - q[1]))
                        .fold(f32::INFINITY, f32::min);
                    // A little randomness so seeds differ in where strokes go.
                    (i, d * rng.range_f32(0.8, 1.0))
                })
                .max_by(|x, y| x.1.total_cmp(&y.1));
            let Some((i, _)) = best else {
                sides_needed.remove(0);
                continue;
            };
            let start = cands.swap_remove(i);
            let len = rng.range_f32(70.0, 150.0) * s.max(0.5);
            let back = if anchor.is_some() {
                0.0
            } else {
                len * rng.range_f32(0.3, 0.6)
            };
            // The narrow side of a part leaves little room: a user follows it closer to
            // the edge there.
            let keep_in = if anchor.is_some() {
                0.35 * margin
            } else {
                margin
            };
            let mut path = self.trace(start, -1.0, back, 0.5, keep_in);
            path.reverse();
            path.push(start);
            path.extend(self.trace(start, 1.0, len - back, 0.5, keep_in));
            let pts = resample(&path, 10.0 * s.max(0.5));
            let pts = checked_prefix(pts, mask, gt_dir, w, h, normalize);
            let total: f32 = pts
                .windows(2)
                .map(|q| (q[1][0] - q[0][0]).hypot(q[1][1] - q[0][1]))
                .sum();
            if pts.len() < 2 || total < 40.0 * s.max(0.5) {
                used.push(start);
                continue;
            }
            if let Some(sd) = side {
                // Accept for the needed side only if the whole stroke stays on it.
                if pts.iter().all(|q| self.field.side(q[0]) == sd) {
                    sides_needed.remove(0);
                } else {
                    continue;
                }
            }
            used.extend(pts.iter().copied());
            strokes.push(Stroke::new(StrokeKind::Direction, pts));
        }
        Strokes::new(strokes)
    }
}

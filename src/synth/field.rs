//! The analytic 2D growth field the synthetic hair follows (the orientation ground truth).

use super::smoothstep;
use super::texture::Curl;
use std::f32::consts::FRAC_PI_2;

#[derive(Clone, Debug)]
pub(super) enum Field {
    /// Hair parted along the vertical line x = px above the head centre (hx, hy): on each side
    /// it leaves the part horizontally and turns down following an elliptic angle around the
    /// head centre, so orientation is continuous across the part while direction flips.
    Part {
        px: f32,
        hy: f32,
        rx_l: f32,
        rx_r: f32,
        ry: f32,
        amax_l: f32,
        amax_r: f32,
        /// Gentle waves and an outward flare of the falling hair, both below `y_low`.
        wave_amp: f32,
        wave_k: f32,
        wave_phase: f32,
        flare: f32,
        y_low: f32,
        y_bottom: f32,
    },
    /// A spiral out of the whorl point, bending downwards further away.
    Whorl {
        wx: f32,
        wy: f32,
        twist: f32,
        fall: f32,
        r0: f32,
        r1: f32,
    },
    /// Straight out of a crown point above the head silhouette (so no singularity on hair),
    /// turned by a small twist.
    Radial { ox: f32, oy: f32, twist: f32 },
    /// A fringe lying over side hair (CZ06 Fig. 10): inside the ellipse centred (ex, ey) with
    /// radii (erx, ery) the hair sweeps sideways across the forehead, towards x·`sweep`
    /// (±1), at β0 + β1·u below the horizontal (u = sweep·(x − ex)/erx); outside it, the
    /// `rest` field. The ellipse's arc inside the hair is the seam, where the orientation
    /// jumps.
    Fringe {
        ex: f32,
        ey: f32,
        erx: f32,
        ery: f32,
        sweep: f32,
        beta0: f32,
        beta1: f32,
        rest: Box<Field>,
    },
    /// `base` turned by the curl's smooth angle: wavy strands whose ground truth is the
    /// turned field itself. Turning keeps unit length, so no singular point is added, and a
    /// part stays a part (both sides turn alike).
    Curled { base: Box<Field>, curl: Curl },
}

impl Field {
    /// Unit growth direction (root -> tip) at (x, y).
    pub(super) fn dir(&self, x: f32, y: f32) -> [f32; 2] {
        match *self {
            Field::Part {
                px,
                hy,
                rx_l,
                rx_r,
                ry,
                amax_l,
                amax_r,
                wave_amp,
                wave_k,
                wave_phase,
                flare,
                y_low,
                y_bottom,
            } => {
                let u = x - px;
                let right = u >= 0.0;
                let (rx, amax) = if right {
                    (rx_r, amax_r)
                } else {
                    (rx_l, amax_l)
                };
                // 0 straight above the head centre, pi straight below.
                let alpha = (u.abs() / rx).atan2(-(y - hy) / ry);
                let t = (alpha / amax).min(1.0);
                // Linear near the part (so orientation is smooth across it), flat at pi/2.
                let mut beta = FRAC_PI_2 * t * (2.0 - t);
                let low = smoothstep(y_low, y_low + 0.5 * (y_bottom - y_low), y);
                beta += low * (wave_amp * (wave_k * y + wave_phase).sin() - flare);
                let s = if right { 1.0 } else { -1.0 };
                [s * beta.cos(), beta.sin()]
            }
            Field::Whorl {
                wx,
                wy,
                twist,
                fall,
                r0,
                r1,
            } => {
                let (rx, ry) = (x - wx, y - wy);
                let d = rx.hypot(ry);
                if d < 1e-6 {
                    return [1.0, 0.0];
                }
                let (s, c) = twist.sin_cos();
                let tx = (rx * c - ry * s) / d;
                let ty = (rx * s + ry * c) / d;
                // fall < 1 keeps the sum away from zero, so the field has no second singularity.
                let g = fall * smoothstep(r0, r1, d);
                normalize([tx, ty + g])
            }
            Field::Radial { ox, oy, twist } => {
                let (rx, ry) = (x - ox, y - oy);
                let (s, c) = twist.sin_cos();
                normalize([rx * c - ry * s, rx * s + ry * c])
            }
            Field::Fringe {
                ex,
                erx,
                sweep,
                beta0,
                beta1,
                ref rest,
                ..
            } => {
                if !self.in_fringe(x, y) {
                    return rest.dir(x, y);
                }
                let u = (sweep * (x - ex) / erx).clamp(-1.5, 1.5);
                let beta = beta0 + beta1 * u;
                [sweep * beta.cos(), beta.sin()]
            }
            Field::Curled { ref base, ref curl } => {
                let d = base.dir(x, y);
                let (s, c) = curl.angle(x, y).sin_cos();
                [d[0] * c - d[1] * s, d[0] * s + d[1] * c]
            }
        }
    }

    /// Whether (x, y) lies on the fringe's side of its seam (false for other fields).
    pub(super) fn in_fringe(&self, x: f32, y: f32) -> bool {
        match *self {
            Field::Fringe {
                ex, ey, erx, ery, ..
            } => ((x - ex) / erx).powi(2) + ((y - ey) / ery).powi(2) < 1.0,
            Field::Curled { ref base, .. } => base.in_fringe(x, y),
            _ => false,
        }
    }

    /// Which side of a part a point is on (+1 / -1); 0 for fields without a part.
    pub(super) fn side(&self, x: f32) -> i32 {
        match *self {
            Field::Part { px, .. } => {
                if x >= px {
                    1
                } else {
                    -1
                }
            }
            Field::Curled { ref base, .. } => base.side(x),
            _ => 0,
        }
    }
}

pub(super) fn normalize(v: [f32; 2]) -> [f32; 2] {
    let l = v[0].hypot(v[1]);
    if l > 0.0 {
        [v[0] / l, v[1] / l]
    } else {
        [1.0, 0.0]
    }
}

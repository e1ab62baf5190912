//! Style rules and strand growth: the combing field, per-strand variation, bounded turns.

use super::body::Body;
use crate::base::rng::Rng;
use crate::hair::head::{Head, ScalpPoint};
use crate::synth::smoothstep;
use crate::synth::Style;
use glam::Vec3;
use std::f32::consts::PI;
/// Step between strand vertices, metres.
pub(super) const STEP: f32 = 0.002;
/// Largest turn per step near the surface and in free fall.
pub(super) const SURF_TURN: f32 = 12.0 * PI / 180.0;
pub(super) const FREE_TURN: f32 = 5.0 * PI / 180.0;
/// Hard limit: a strand that would bend more to stay outside the body stops there.
pub(super) const MAX_TURN: f32 = 14.5 * PI / 180.0;
/// No vertex after the root comes closer than this to the body, metres.
pub(super) const MIN_CLEAR: f32 = 0.0005;
/// Above its layer by this much a strand no longer feels the surface, metres.
pub(super) const BAND: f32 = 0.015;

#[derive(Clone, Debug)]
pub(super) enum Rule {
    /// Hair parted along x = px from the front hairline to the crown: each side combed away
    /// from the parting, sideways and down over the skull, then falling. `back_big/small`:
    /// how strongly hair in front is combed backwards on each side (a side part's big side
    /// sweeps across the forehead instead); `big` = the big side's sign (0 for a centre part).
    Part {
        px: f32,
        big: f32,
        back_big: f32,
        back_small: f32,
        flare: f32,
        wave: bool,
    },
    /// Spiral out of a crown point on the scalp, falling further away.
    Whorl {
        crown: Vec3,
        twist: f32,
        fall: f32,
        r0: f32,
        r1: f32,
    },
    /// Straight out of an apex above the vertex, turned by a small twist.
    Radial { apex: Vec3, twist: f32 },
}

pub(super) struct StyleSpec {
    pub(super) rule: Rule,
    /// Strand length range, metres.
    pub(super) len: (f32, f32),
    /// Largest height of a strand's layer above the surface (the hair's volume), metres.
    pub(super) layer_max: f32,
    /// Cut line: strands stop below `cut_side` (y, metres) and, in front of the face,
    /// below `cut_front` (a fringe above the brows).
    pub(super) cut_side: f32,
    pub(super) cut_front: f32,
}

impl StyleSpec {
    pub(super) fn new(style: Style, head: &Head, g: &mut Rng) -> StyleSpec {
        let side = if g.next_f32() < 0.5 { -1.0 } else { 1.0 };
        match style {
            Style::Long => StyleSpec {
                rule: Rule::Part {
                    px: g.range_f32(-0.004, 0.004),
                    big: 0.0,
                    back_big: 0.9,
                    back_small: 0.9,
                    flare: g.range_f32(0.15, 0.3),
                    wave: true,
                },
                len: (g.range_f32(0.28, 0.32), g.range_f32(0.40, 0.45)),
                layer_max: 0.025,
                cut_side: -1.0,
                cut_front: 0.03,
            },
            Style::SidePart => StyleSpec {
                rule: Rule::Part {
                    px: side * g.range_f32(0.03, 0.045),
                    big: -side,
                    back_big: g.range_f32(0.15, 0.3),
                    back_small: 1.0,
                    flare: g.range_f32(0.0, 0.08),
                    wave: false,
                },
                len: (0.10, 0.22),
                layer_max: 0.02,
                cut_side: g.range_f32(-0.065, -0.045),
                cut_front: g.range_f32(0.012, 0.025),
            },
            Style::Whorl => {
                let uv = [0.5 + g.range_f32(-0.08, 0.08), g.range_f32(0.14, 0.22)];
                let crown = head
                    .scalp(uv)
                    .map(|sp| sp.pos)
                    .unwrap_or_else(|| head.top());
                StyleSpec {
                    rule: Rule::Whorl {
                        crown,
                        twist: side * g.range_f32(0.8, 1.1),
                        fall: g.range_f32(0.6, 0.9),
                        r0: 0.03,
                        r1: 0.12,
                    },
                    len: (0.05, 0.11),
                    layer_max: 0.015,
                    cut_side: g.range_f32(-0.03, -0.015),
                    cut_front: g.range_f32(0.02, 0.032),
                }
            }
            Style::Short => {
                let top = head.top();
                StyleSpec {
                    rule: Rule::Radial {
                        apex: top
                            + Vec3::new(
                                g.range_f32(-0.02, 0.02),
                                g.range_f32(0.03, 0.05),
                                g.range_f32(-0.03, 0.0),
                            ),
                        twist: side * g.range_f32(0.05, 0.2),
                    },
                    len: (0.015, 0.035),
                    layer_max: 0.008,
                    cut_side: g.range_f32(-0.02, -0.01),
                    cut_front: 0.03,
                }
            }
            Style::Fringe => unreachable!("2D only, refused by Synth3dScene::new"),
        }
    }

    /// The y below which a strand at `p` is cut.
    pub(super) fn cut(&self, p: Vec3) -> f32 {
        let front = smoothstep(0.0, 0.05, p.z) * (1.0 - smoothstep(0.06, 0.09, p.x.abs()));
        self.cut_side + (self.cut_front - self.cut_side) * front
    }
}

/// Per-strand variation.
#[derive(Clone, Debug)]
pub(super) struct StrandVar {
    /// Side of the parting the root is on (±1; +1 without a parting).
    pub(super) side: f32,
    pub(super) len: f32,
    /// Height above the surface the strand settles at, metres.
    pub(super) layer: f32,
    pub(super) lean: Vec3,
    pub(super) cut_jit: f32,
    pub(super) wave_amp: f32,
    pub(super) wave_k: f32,
    pub(super) wave_phase: f32,
    /// Colour factors: brightness, tint, opacity, width (px at 512).
    pub(super) bright: f32,
    pub(super) tint: [f32; 3],
    pub(super) alpha: f32,
    pub(super) width: f32,
}

impl StrandVar {
    pub(super) fn new(root: &ScalpPoint, spec: &StyleSpec, r: &mut Rng) -> StrandVar {
        let side = match spec.rule {
            Rule::Part { px, .. } => {
                if root.pos.x >= px {
                    1.0
                } else {
                    -1.0
                }
            }
            _ => 1.0,
        };
        StrandVar {
            side,
            len: r.range_f32(spec.len.0, spec.len.1),
            // Denser near the scalp, as a hair volume is.
            layer: 0.0015 + (spec.layer_max - 0.0015) * r.next_f32().powf(1.3),
            lean: Vec3::new(
                r.range_f32(-1.0, 1.0),
                r.range_f32(-1.0, 1.0),
                r.range_f32(-1.0, 1.0),
            ) * 0.1,
            cut_jit: r.range_f32(-0.004, 0.004),
            wave_amp: r.range_f32(0.1, 0.25),
            wave_k: std::f32::consts::TAU / r.range_f32(0.05, 0.09),
            wave_phase: r.range_f32(0.0, std::f32::consts::TAU),
            bright: (1.0 + 0.35 * r.normal_f32()).clamp(0.55, 1.6),
            tint: [0; 3].map(|_| 1.0 + 0.05 * r.range_f32(-1.0, 1.0)),
            alpha: r.range_f32(0.6, 0.95),
            width: r.range_f32(1.0, 1.5),
        }
    }
}

/// The style's combing vector at `p` (not unit). `n` is the body normal when `surf` > 0
/// (how much the strand still feels the surface, 0..1), `arc` the length grown so far.
pub(super) fn comb(spec: &StyleSpec, p: Vec3, n: Vec3, surf: f32, v: &StrandVar, arc: f32) -> Vec3 {
    let free = 1.0 - surf;
    let c = match spec.rule {
        Rule::Part {
            big,
            back_big,
            back_small,
            flare,
            wave,
            ..
        } => {
            // How far forward (towards the face) and how far behind the crown p is: behind
            // it the parting ends and hair just falls.
            let front = smoothstep(-0.02, 0.06, p.z);
            let behind = smoothstep(-0.03, -0.09, p.z);
            let back_w = if v.side == big { back_big } else { back_small };
            let lateral = v.side * (1.0 - 0.7 * behind) * (surf + free * flare);
            let mut c = Vec3::new(lateral, -(0.5 + 0.5 * free), -front * back_w);
            if wave {
                c.x += free * v.side * v.wave_amp * (v.wave_k * arc + v.wave_phase).sin();
            }
            c
        }
        Rule::Whorl {
            crown,
            twist,
            fall,
            r0,
            r1,
        } => {
            let rv = p - crown;
            let rt = rv - n * rv.dot(n) * surf;
            let rh = rt.normalize_or_zero();
            let t = rh * twist.cos() + n.cross(rh) * twist.sin() * surf;
            let g = fall * smoothstep(r0, r1, rv.length());
            let front = smoothstep(0.0, 0.06, p.z);
            t * (1.0 - 0.7 * free) - Vec3::Y * (g + free) - Vec3::Z * 0.3 * front * free
        }
        Rule::Radial { apex, twist } => {
            let rh = (p - apex).normalize_or_zero();
            let t = rh + n.cross(rh) * twist * surf;
            t - Vec3::Y * free
        }
    };
    c + v.lean
}

/// Rotates unit `d` towards unit `t` by at most `max` radians.
pub(super) fn turn_towards(d: Vec3, t: Vec3, max: f32) -> Vec3 {
    let ang = d.dot(t).clamp(-1.0, 1.0).acos();
    if ang <= max {
        return t;
    }
    let axis = d.cross(t);
    let axis = if axis.length_squared() > 1e-12 {
        axis.normalize()
    } else {
        d.any_orthonormal_vector()
    };
    glam::Quat::from_axis_angle(axis, max) * d
}

pub(super) fn grow_strand(
    body: &Body,
    spec: &StyleSpec,
    root: &ScalpPoint,
    v: &StrandVar,
) -> Vec<Vec3> {
    let mut p = root.pos;
    let n0 = root.normal;
    let c0 = comb(spec, p, n0, 1.0, v, 0.0);
    let t0 = (c0 - n0 * c0.dot(n0))
        .try_normalize()
        .unwrap_or_else(|| n0.any_orthonormal_vector());
    // Leave the scalp at about 30°.
    let mut d = (t0 + n0 * 0.6).normalize();
    let mut pts = vec![p];
    let mut arc = 0.0;
    while arc + 0.5 * STEP < v.len {
        let dist = body.sdf(p);
        let surf = 1.0 - smoothstep(v.layer, v.layer + BAND, dist);
        let n = if surf > 0.0 { body.normal(p) } else { Vec3::Y };
        let mut c = comb(spec, p, n, surf, v, arc);
        if surf > 0.0 {
            // The surface carries the hair: no inward part, and a pull up to the layer.
            let cn = c.dot(n);
            if cn < 0.0 {
                c -= n * cn * surf;
            }
            if dist < v.layer {
                c += n * (1.5 * (v.layer - dist) / v.layer) * c.length();
            }
        }
        let Some(target) = c.try_normalize() else {
            break;
        };
        let max = FREE_TURN + (SURF_TURN - FREE_TURN) * surf;
        let nd = turn_towards(d, target, max);
        let mut q = p + nd * STEP;
        let dq = body.sdf(q);
        if dq < MIN_CLEAR {
            q += body.normal(q) * (MIN_CLEAR - dq);
            q = p + (q - p).normalize() * STEP;
            if body.sdf(q) < MIN_CLEAR * 0.5 {
                break;
            }
        }
        let nd = (q - p).normalize();
        if pts.len() >= 2 && nd.dot(d).clamp(-1.0, 1.0).acos() > MAX_TURN {
            break;
        }
        // Hair rooted below the cut line (the nape under a bob) is trimmed to a stub.
        if pts.len() > 4 && q.y < spec.cut(q) + v.cut_jit {
            break;
        }
        d = nd;
        pts.push(q);
        p = q;
        arc += STEP;
    }
    pts
}

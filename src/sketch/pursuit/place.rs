//! An occluding line's place across its axis, to a quarter pixel. The chain puts a curve's
//! centres on integer starts, 15° axes and 5 px steps, so along a bending seam its axis lies
//! a pixel or so off the edge where one flow's strands stop under the other's; within that
//! pixel the sketch paints the wrong flow, and a seam's error is mostly there. Each
//! occluding primitive may lie up to ±2 px off its chain in ¼ px steps: at each offset the
//! pixels within [`REACH`] of the chain's axis are split there, each side's flow read from
//! its own pixels farther than [`GAP`] from the split (the row whose derivative straddles
//! the edge mixes both flows), and the offset scored by E1 of every pixel of that fixed set
//! under its side's flow: where the two flows agree no offset scores better than another,
//! and a line of pixels neither flow explains costs the same wherever the split goes.
//! The offsets along a curve are chosen by rate and distortion ([`format::rate_shifts`]), so
//! a curve leaves its chain only where the fit pays for the bits. Light and sequential (a few
//! hundred pixels × 17 offsets per primitive): CPU.

use super::Search;
use crate::sketch::format::{self, SHIFT_CODES, SHIFT_QUANTUM, SHIFT_STEPS};
use crate::sketch::{prim, Curve, Kind, Primitive};

/// The pixels a split is scored over: within this far of the chain's axis, px (the largest
/// offset, 2 px, plus the window's half-width, 2.5 px, and a little: at every offset each
/// side keeps a row or two beyond the gap to read its flow from).
const REACH: f32 = 5.0;
/// Each side's flow is read from its pixels at least this far from the split, px.
const GAP: f32 = 1.0;

/// E1 of the pixels within [`REACH`] of `p`'s axis on a w×h image split at each shift code's
/// offset (see the module docs): `data` the pursuit's per-pixel A e^{2iθo}, E1 of a pixel
/// under unit flow z being −data·z.
pub(crate) fn split_costs(
    p: &Primitive,
    w: u32,
    h: u32,
    data: &[[f32; 2]],
    hair: &[bool],
) -> [f32; SHIFT_CODES] {
    let mut px: Vec<(f32, [f32; 2])> = Vec::new();
    prim::across(p, w, h, REACH, |k, c| {
        if hair[k] {
            px.push((c, data[k]));
        }
    });
    std::array::from_fn(|r| {
        let o = (r as i32 - SHIFT_STEPS) as f32 * SHIFT_QUANTUM;
        let mut g = [[0.0f32; 2]; 2];
        for &(c, d) in &px {
            let s = if c >= o + GAP {
                0
            } else if c < o - GAP {
                1
            } else {
                continue;
            };
            g[s][0] += d[0];
            g[s][1] += d[1];
        }
        let z = g.map(|g| {
            let n = g[0].hypot(g[1]);
            if n > 0.0 {
                [g[0] / n, g[1] / n]
            } else {
                [0.0; 2]
            }
        });
        -px.iter()
            .map(|&(c, d)| {
                let z = z[(c < o) as usize];
                d[0] * z[0] + d[1] * z[1]
            })
            .sum::<f32>()
    })
}

/// `p`, a primitive on its chain, placed `code`'s offset off it (to the left for codes
/// above [`format::SHIFT_ZERO`]), where the decoder puts it.
pub(crate) fn shifted(p: &Primitive, code: u8) -> Primitive {
    let [x, y] = format::off_chain(p.x, p.y, p.axis, code);
    Primitive {
        x,
        y,
        shift: format::shift_of(code),
        ..*p
    }
}

impl Search<'_> {
    /// `curves` with their occluding primitives placed across their axes (module docs), the
    /// field painted again from scratch if any moved. Off without a rate (`bit_cost` 0) or
    /// with `place_occluding` off.
    pub(super) fn shift_occluding(&mut self, curves: Vec<Curve>) -> Vec<Curve> {
        if self.p.bit_cost <= 0.0 || !self.p.place_occluding {
            return curves;
        }
        let f = self.f;
        let (w, h) = (f.width, f.height);
        let costs: Vec<Option<Vec<[f32; SHIFT_CODES]>>> = curves
            .iter()
            .map(|c| {
                (c.kind == Kind::Occluding).then(|| {
                    c.prims
                        .iter()
                        .map(|p| split_costs(p, w, h, &f.data, &f.hair))
                        .collect()
                })
            })
            .collect();
        let codes = format::rate_shifts(&costs, self.p.bit_cost);
        if codes.iter().all(Option::is_none) {
            return curves;
        }
        let mut out = curves;
        for (c, codes) in out.iter_mut().zip(&codes) {
            if let Some(codes) = codes {
                for (p, &r) in c.prims.iter_mut().zip(codes) {
                    *p = shifted(p, r);
                }
                self.stats.shifted += codes.iter().filter(|&&r| r != format::SHIFT_ZERO).count();
            }
        }
        self.repaint(&out);
        out
    }

    /// Paints `curves` again on a clean sketch layer (as [`prim::paint`] does: a pixel
    /// belongs to the first primitive reaching it), keeping the free pixels' field as the
    /// next solve's warm start.
    fn repaint(&mut self, curves: &[Curve]) {
        let f = self.f;
        let (w, h) = (f.width, f.height);
        self.log.clear();
        self.epoch += 1;
        self.on.fill(false);
        self.fixed.fill(false);
        self.skrho.fill(false);
        for c in curves {
            let hs = c.kind.hair_sides();
            let sk = self.sk_kind(c.kind);
            for p in &c.prims {
                let z = [0, 1].map(|s| crate::sketch::theta::to_z(p.side_angle(s)));
                prim::window(c.kind, p, w, h, |i, side| {
                    if std::mem::replace(&mut self.on[i], true) {
                        return;
                    }
                    if let Some(k) = side.index() {
                        if hs[k] && f.hair[i] {
                            self.fixed[i] = true;
                            self.skrho[i] = sk;
                            self.z[i] = z[k];
                        }
                    }
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sketch::format::{shift_of, SHIFT_ZERO};

    /// An occluding primitive along +x centred on a pixel corner of a 40×40 image, and each
    /// pixel's offset across its axis (+ left, that is up).
    fn setup() -> (Primitive, Vec<f32>) {
        let p = Primitive {
            x: 20.0,
            y: 20.0,
            axis: 0.0,
            rho: 1.0,
            side: [0.0; 2],
            shift: 0.0,
        };
        let c = (0..1600).map(|i| 20.0 - (i / 40) as f32 - 0.5).collect();
        (p, c)
    }

    #[test]
    fn the_split_is_placed_at_the_edge_between_two_flows() {
        let (p, c) = setup();
        // Flow at 0° above the row edge at +1 px, at 90° below it (data ∝ e^{2iθ}).
        let data: Vec<[f32; 2]> = c
            .iter()
            .map(|&c| if c > 1.0 { [1.0, 0.0] } else { [-1.0, 0.0] })
            .collect();
        let e = split_costs(&p, 40, 40, &data, &[true; 1600]);
        let best = e.iter().copied().fold(f32::INFINITY, f32::min);
        for (r, &v) in e.iter().enumerate() {
            // Every split between the rows at +0.5 and +1.5 px parts the flows exactly.
            let o = shift_of(r as u8);
            if o > 0.5 && o <= 1.5 {
                assert_eq!(v, best, "{o} px");
            } else {
                assert!(v > best + 1.0, "{o} px: {v} vs {best}");
            }
        }
        // On the chain the rows between it and the edge are painted the wrong flow.
        assert!(e[SHIFT_ZERO as usize] > best + 10.0);
    }

    #[test]
    fn a_line_neither_flow_explains_does_not_pull_the_split() {
        let (p, c) = setup();
        // One flow everywhere, and a row at +1.5 px across it (strand ends, say): leaving
        // that row out of the score would draw the split onto it; scored over a fixed set of
        // pixels every offset costs the same.
        let data: Vec<[f32; 2]> = c
            .iter()
            .map(|&c| if c == 1.5 { [-2.0, 0.0] } else { [1.0, 0.0] })
            .collect();
        let e = split_costs(&p, 40, 40, &data, &[true; 1600]);
        for &v in &e {
            assert!((v - e[SHIFT_ZERO as usize]).abs() < 1e-3, "{e:?}");
        }
        let codes = format::rate_shifts(&[Some(vec![e; 6])], 1.0);
        assert_eq!(codes, vec![None]);
    }
}

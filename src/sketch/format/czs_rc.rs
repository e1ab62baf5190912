//! The range-coded tail of `.czs` ([`rc`], adaptive contexts): in versions 3 and 4 the fields
//! of version 2's curves; version 5 puts the colour map (each bin's step from the last) and
//! the region first (its outline's steps as signed exponent-Golomb codes, the sign in the
//! context of the step before), stores the curves
//! sorted by start, each start as the gap to the previous one's row and its column (the
//! gap to the previous column on the same row), and then their paint order ([`order`]).
//! Sequential (each symbol's context is the one before): CPU.

use super::czs::{
    bits_for, check_placement, fixed_dirs, kind_of, signed_code, signed_of, unzigzag, zigzag,
};
use super::order;
use super::rc;
use super::*;
use crate::sketch::Region;

/// The adaptive contexts of the version-3 curve section: each field's probabilities are
/// conditioned on what precedes it on the curve (the previous primitive's turn, side codes
/// and contrast; on a two-sided kind the first side's codes for the second side's).
struct CurveModel {
    /// Exponent-Golomb counts, by what they count ([`Count`]).
    count_exp: [[rc::Prob; 48]; Count::N],
    count_mant: Vec<rc::Prob>,
    kind: [rc::Prob; 8],
    label: [[rc::Prob; 4]; 16],
    start: [[rc::Prob; 32]; 2],
    axis: [rc::Prob; 32],
    turn: [[rc::Prob; 4]; 4],
    /// Side codes, by context q (see [`SideCtx`]): the dictionary index equals the
    /// prediction's; the index; the refinement's step from the prediction (zigzag); the
    /// refinement itself where there is no prediction to step from.
    same_dict: [rc::Prob; 5],
    dict: [[rc::Prob; 4]; 5],
    step: [[rc::Prob; 32]; 5],
    refine: [[rc::Prob; 16]; 5],
    rho: [[rc::Prob; 16]; 17],
    /// Version 5: whether the paint order is the one the overlapping pairs' bits give
    /// ([`order`]), and those bits; a region step's sign, by coordinate and the previous
    /// step's sign (−, 0, +) there.
    ordered: rc::Prob,
    precede: [rc::Prob; 3],
    step_sign: [[rc::Prob; 3]; 2],
    /// Version 7: whether an occluding curve lies off its chain, and then each primitive's
    /// shift code as the step from the previous one's (zigzag; the first from the chain).
    shifted: rc::Prob,
    shift_step: [rc::Prob; 64],
}

/// What an exponent-Golomb count of [`rc_count`] counts: each has its own contexts.
#[derive(Clone, Copy)]
enum Count {
    Curves,
    Prims,
    /// Version 5: a start's row gap, its column gap on the same row.
    RowGap,
    ColGap,
    /// Version 5: the region's polygons and vertices, and the size of its steps in x and y.
    Polygons,
    Vertices,
    StepX,
    StepY,
    /// Version 5: the colour map's steps from bin to bin in u and v.
    ColourU,
    ColourV,
}

impl Count {
    const N: usize = 10;
}

/// Codes of a colour map coordinate (6 bits).
const COLOUR_CODES: u32 = 64;

impl CurveModel {
    fn new() -> Box<Self> {
        let h = rc::HALF;
        Box::new(CurveModel {
            count_exp: [[h; 48]; Count::N],
            count_mant: vec![h; Count::N * 48 * 48],
            kind: [h; 8],
            label: [[h; 4]; 16],
            start: [[h; 32]; 2],
            axis: [h; 32],
            turn: [[h; 4]; 4],
            same_dict: [h; 5],
            dict: [[h; 4]; 5],
            step: [[h; 32]; 5],
            refine: [[h; 16]; 5],
            rho: [[h; 16]; 17],
            ordered: h,
            precede: [h; 3],
            step_sign: [[h; 3]; 2],
            shifted: h,
            shift_step: [h; 64],
        })
    }
}

/// What side `s`'s codes on a primitive are predicted from, and the context they are coded
/// in. Side 1 of a two-sided kind mirrors this primitive's side 0 (refinement 16 − r₀: the
/// flow runs on through the line); otherwise a side follows itself on the previous
/// primitive, its refinement moved by 4 steps (15°) with the axis's turn (the flow keeps its
/// heading while the axis turns); a curve's first side has no prediction.
struct SideCtx {
    q: usize,
    pred: Option<(u8, i32)>,
}

fn side_ctx(
    kind: Kind,
    s: usize,
    turn: i8,
    this: &[(u8, u8); 2],
    prev: Option<&[(u8, u8); 2]>,
    hair: [bool; 2],
) -> SideCtx {
    let stream = (kind == Kind::Stream) as usize;
    if s == 1 && hair[0] {
        return SideCtx {
            q: stream,
            pred: Some((this[0].0, 16 - this[0].1 as i32)),
        };
    }
    match prev {
        Some(p) => SideCtx {
            q: 2 + stream,
            pred: Some((p[s].0, p[s].1 as i32 + 4 * turn as i32)),
        },
        None => SideCtx { q: 4, pred: None },
    }
}

fn rc_side(e: &mut rc::Encoder, m: &mut CurveModel, c: &SideCtx, v: (u8, u8), refine: bool) {
    let same = c.pred.is_some_and(|(d, _)| d == v.0);
    if c.pred.is_some() {
        e.bit(&mut m.same_dict[c.q], same);
    }
    if !same {
        e.tree(&mut m.dict[c.q], 2, v.0 as u32);
    }
    if refine {
        match c.pred {
            Some((_, r)) if same => {
                let step = v.1 as i64 - r.clamp(0, 15) as i64;
                e.tree(&mut m.step[c.q], 5, zigzag(step) as u32);
            }
            _ => e.tree(&mut m.refine[c.q], 4, v.1 as u32),
        }
    }
}

fn un_rc_side(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
    c: &SideCtx,
    refine: bool,
    at: &str,
) -> std::result::Result<(u8, u8), String> {
    let same = c.pred.is_some() && d.bit(&mut m.same_dict[c.q]);
    let dict = match c.pred {
        Some((p, _)) if same => p,
        _ => d.tree(&mut m.dict[c.q], 2) as u8,
    };
    if !refine {
        return Ok((dict, 8));
    }
    let r = match c.pred {
        Some((_, r)) if same => {
            let v = r.clamp(0, 15) as i64 + unzigzag(d.tree(&mut m.step[c.q], 5) as u64);
            if !(0..16).contains(&v) {
                return Err(format!("corrupted: {at} has a side refinement of {v}"));
            }
            v as u8
        }
        _ => d.tree(&mut m.refine[c.q], 4) as u8,
    };
    Ok((dict, r))
}

fn rc_count(e: &mut rc::Encoder, m: &mut CurveModel, which: Count, v: u64) {
    let which = which as usize;
    let n = 64 - v.leading_zeros() as usize;
    for i in 0..n - 1 {
        e.bit(&mut m.count_exp[which][i.min(47)], false);
    }
    e.bit(&mut m.count_exp[which][(n - 1).min(47)], true);
    for i in (0..n - 1).rev() {
        let k = (which * 48 + n.min(47)) * 48 + i.min(47);
        e.bit(&mut m.count_mant[k], (v >> i) & 1 == 1);
    }
}

fn un_rc_count(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
    which: Count,
    what: &str,
) -> std::result::Result<u64, String> {
    let which = which as usize;
    let mut n = 1usize;
    while !d.bit(&mut m.count_exp[which][(n - 1).min(47)]) {
        n += 1;
        if n > 40 {
            return Err(format!("corrupted: {what} is out of range"));
        }
    }
    let mut v = 1u64;
    for i in (0..n - 1).rev() {
        let k = (which * 48 + n.min(47)) * 48 + i.min(47);
        v = (v << 1) | d.bit(&mut m.count_mant[k]) as u64;
    }
    Ok(v)
}

/// The range-coded tail for `.czs` `version` 3 to 5: version 3's curve fields, range coded
/// with [`CurveModel`]; version 4 the same with probabilities that learn fast at first (on
/// the synthetic styles, the fur crops and the astronaut 6% fewer bytes in all, while finer
/// contexts, turns by the side's drift or the second side by its offset from the mirror,
/// cost more to learn than they saved); version 5 as 4 with the colour map and the
/// region first and the curves sorted by start and their paint order (see the module
/// docs). Returns the tail and, when `measure`, the bytes of it the colour map and the
/// region take (0 otherwise, and before version 5, where they are bit-packed).
pub(super) fn rc_curves(
    c: &Codes,
    refine: bool,
    undecided: bool,
    version: u8,
    measure: bool,
) -> (Vec<u8>, [usize; 2]) {
    let tail = rc_tail(c, refine, undecided, version, [true; 2], false).0;
    // A part's share: what leaving it out saves (its contexts are its own).
    let share = |keep: [bool; 2]| {
        tail.len()
            .saturating_sub(rc_tail(c, refine, undecided, version, keep, false).0.len())
    };
    let shares = if measure && version >= 5 {
        [share([false, true]), share([true, false])]
    } else {
        [0; 2]
    };
    (tail, shares)
}

/// What the bits of the range-coded tail code, as [`curve_ledger`] splits them.
#[derive(Clone, Copy)]
enum Field {
    Colour,
    Region,
    /// The number of curves.
    Curves,
    Kind,
    /// The directions of a curve's free sides.
    Labels,
    /// The number of primitives of a curve.
    Prims,
    Start,
    Axis,
    Turn,
    /// The side codes: dictionary angle and refinement.
    Side,
    Contrast,
    /// The paint order of overlapping curves.
    Order,
    /// Occluding lines' offsets off their chains.
    Shift,
}

impl Field {
    const ALL: [(Field, &'static str); 13] = [
        (Field::Colour, "colour"),
        (Field::Region, "region"),
        (Field::Curves, "curve_count"),
        (Field::Kind, "kind"),
        (Field::Labels, "directions"),
        (Field::Prims, "primitive_count"),
        (Field::Start, "start"),
        (Field::Axis, "axis"),
        (Field::Turn, "turn"),
        (Field::Side, "side"),
        (Field::Contrast, "contrast"),
        (Field::Order, "order"),
        (Field::Shift, "shift"),
    ];
}

/// The range-coded tail's information by what it codes (field name, bits): −log2 of each
/// coded symbol's probability as the adaptive model stood when it was coded, so the fields
/// add up to the tail's length less the coder's flush (a few bytes). Empty before version 3,
/// where nothing is range coded.
pub(super) fn curve_ledger(
    c: &Codes,
    refine: bool,
    undecided: bool,
    version: u8,
) -> Vec<(&'static str, f64)> {
    if version < 3 {
        return Vec::new();
    }
    let (_, ledger) = rc_tail(c, refine, undecided, version, [true; 2], true);
    let ledger = ledger.expect("a measuring encoder keeps its ledger");
    Field::ALL
        .iter()
        .map(|&(f, name)| (name, ledger[f as usize]))
        .collect()
}

/// `parts`: whether to code the colour map and the region (version 5; left out only to
/// measure their shares). `measure`: also return the bits of each [`Field`].
fn rc_tail(
    c: &Codes,
    refine: bool,
    undecided: bool,
    version: u8,
    parts: [bool; 2],
    measure: bool,
) -> (Vec<u8>, Option<Vec<f64>>) {
    let v5 = version >= 5;
    let mut m = CurveModel::new();
    let mut e = if measure {
        rc::Encoder::measuring(version >= 4, Field::ALL.len())
    } else {
        rc::Encoder::new(version >= 4)
    };
    let tag = |e: &mut rc::Encoder, f: Field| e.tag(f as usize);
    if v5 && parts[0] {
        tag(&mut e, Field::Colour);
        rc_colour(&mut e, &mut m, &c.colour);
    }
    if v5 && parts[1] {
        tag(&mut e, Field::Region);
        rc_region(&mut e, &mut m, &c.region, c.width, c.height);
    }
    tag(&mut e, Field::Curves);
    rc_count(&mut e, &mut m, Count::Curves, c.curves.len() as u64 + 1);
    let (xb, yb) = (bits_for(c.width), bits_for(c.height));
    let starts: Vec<[u32; 2]> = c.curves.iter().map(|cv| cv.start).collect();
    let stored = if v5 {
        order::stored_order(&starts)
    } else {
        (0..c.curves.len() as u32).collect()
    };
    let mut last = [0u32; 2];
    for cv in stored.iter().map(|&i| &c.curves[i as usize]) {
        let kc = cv.kind.code() as usize;
        tag(&mut e, Field::Kind);
        e.tree(&mut m.kind, 3, kc as u32);
        tag(&mut e, Field::Labels);
        for &i in free_labels(cv.kind) {
            let ctx = &mut m.label[kc * 2 + i];
            if undecided {
                e.tree(ctx, 2, signed_code(cv.dirs[i]));
            } else {
                e.bit(&mut ctx[1], cv.dirs[i] > 0);
            }
        }
        tag(&mut e, Field::Prims);
        rc_count(&mut e, &mut m, Count::Prims, cv.prims.len() as u64);
        tag(&mut e, Field::Start);
        if v5 {
            let gap = cv.start[1] - last[1];
            rc_count(&mut e, &mut m, Count::RowGap, gap as u64 + 1);
            if gap == 0 {
                rc_count(
                    &mut e,
                    &mut m,
                    Count::ColGap,
                    (cv.start[0] - last[0]) as u64 + 1,
                );
            } else {
                e.uniform(cv.start[0], c.width + 1);
            }
            last = cv.start;
        } else {
            for (k, (v, n)) in [(cv.start[0], xb), (cv.start[1], yb)]
                .into_iter()
                .enumerate()
            {
                for i in (0..n).rev() {
                    e.bit(&mut m.start[k][i as usize], (v >> i) & 1 == 1);
                }
            }
        }
        tag(&mut e, Field::Axis);
        e.tree(&mut m.axis, 5, cv.axis as u32);
        let hair = cv.kind.hair_sides();
        let mut prev_turn = 3usize;
        for (k, p) in cv.prims.iter().enumerate() {
            if k > 0 {
                let t = signed_code(p.turn);
                tag(&mut e, Field::Turn);
                e.tree(&mut m.turn[prev_turn], 2, t);
                prev_turn = t as usize;
            }
            let prev = (k > 0).then(|| &cv.prims[k - 1].side);
            tag(&mut e, Field::Side);
            for s in (0..2).filter(|&s| hair[s]) {
                let c = side_ctx(cv.kind, s, p.turn, &p.side, prev, hair);
                rc_side(&mut e, &mut m, &c, p.side[s], refine);
            }
            let rc_ctx = if k > 0 {
                cv.prims[k - 1].rho as usize
            } else {
                16
            };
            tag(&mut e, Field::Contrast);
            e.tree(&mut m.rho[rc_ctx.min(16)], 4, p.rho as u32);
        }
        if version >= 7 && cv.kind == Kind::Occluding {
            tag(&mut e, Field::Shift);
            rc_shifts(&mut e, &mut m, &cv.prims);
        }
    }
    if v5 {
        tag(&mut e, Field::Order);
        rc_paint_order(&mut e, &mut m, c, &stored);
    }
    let ledger = e.ledger().map(<[f64]>::to_vec);
    (e.finish(), ledger)
}

/// Version 7: an occluding curve's shift codes ([`CurveModel::shifted`]).
fn rc_shifts(e: &mut rc::Encoder, m: &mut CurveModel, prims: &[PrimCodes]) {
    let shifted = prims.iter().any(|p| p.shift != SHIFT_ZERO);
    e.bit(&mut m.shifted, shifted);
    if shifted {
        let mut q = SHIFT_ZERO;
        for p in prims {
            e.tree(
                &mut m.shift_step,
                6,
                zigzag(p.shift as i64 - q as i64) as u32,
            );
            q = p.shift;
        }
    }
}

/// [`rc_shifts`] read back into `prims`.
fn un_rc_shifts(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
    prims: &mut [PrimCodes],
    at: &str,
) -> std::result::Result<(), String> {
    if !d.bit(&mut m.shifted) {
        return Ok(());
    }
    let mut q = SHIFT_ZERO as i64;
    for (k, p) in prims.iter_mut().enumerate() {
        let v = q + unzigzag(d.tree(&mut m.shift_step, 6) as u64);
        if !(0..SHIFT_CODES as i64).contains(&v) {
            return Err(format!(
                "corrupted: {at}, primitive {k} has shift code {v} (0 to {})",
                SHIFT_CODES - 1
            ));
        }
        p.shift = v as u8;
        q = v;
    }
    Ok(())
}

/// Version 5's colour map: each bin's (u, v) codes as the step from the bin before, signed
/// exponent-Golomb (the map is smooth in L*: most steps are 0 to 3 codes), the first bin's
/// as they are.
fn rc_colour(e: &mut rc::Encoder, m: &mut CurveModel, colour: &ColourCodes) {
    for (k, bin) in colour.k.iter().enumerate() {
        for a in 0..2 {
            if k == 0 {
                e.uniform(bin[a] as u32, COLOUR_CODES);
            } else {
                let d = bin[a] as i64 - colour.k[k - 1][a] as i64;
                rc_count(e, m, [Count::ColourU, Count::ColourV][a], zigzag(d) + 1);
            }
        }
    }
}

/// [`rc_colour`] read back.
fn un_rc_colour(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
) -> std::result::Result<ColourCodes, String> {
    let mut k: Vec<[u8; 2]> = Vec::with_capacity(COLOUR_BINS);
    for bin in 0..COLOUR_BINS {
        let mut v = [0u8; 2];
        for a in 0..2 {
            let code = if bin == 0 {
                d.uniform(COLOUR_CODES) as i64
            } else {
                let step =
                    un_rc_count(d, m, [Count::ColourU, Count::ColourV][a], "the colour map")?;
                k[bin - 1][a] as i64 + unzigzag(step - 1)
            };
            if !(0..COLOUR_CODES as i64).contains(&code) {
                return Err(format!("corrupted: colour map bin {bin} has code {code}"));
            }
            v[a] = code as u8;
        }
        k.push(v);
    }
    Ok(ColourCodes { k })
}

/// Version 5's region: the polygon count, and per polygon its vertex count, its first
/// vertex (uniform over the image) and the steps to the next ones.
fn rc_region(e: &mut rc::Encoder, m: &mut CurveModel, region: &Region, w: u32, h: u32) {
    rc_count(e, m, Count::Polygons, region.len() as u64 + 1);
    for poly in region {
        rc_count(e, m, Count::Vertices, poly.len() as u64 - 2);
        e.uniform(poly[0][0], w + 1);
        e.uniform(poly[0][1], h + 1);
        let mut prev = [1usize; 2];
        for pair in poly.windows(2) {
            for a in 0..2 {
                let d = pair[1][a] as i64 - pair[0][a] as i64;
                let count = [Count::StepX, Count::StepY][a];
                rc_count(e, m, count, d.unsigned_abs() + 1);
                if d != 0 {
                    e.bit(&mut m.step_sign[a][prev[a]], d > 0);
                }
                prev[a] = (d.signum() + 1) as usize;
            }
        }
    }
}

/// [`rc_region`] read back, with the checks of version 2's reader.
fn un_rc_region(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
    w: u32,
    h: u32,
) -> std::result::Result<Region, String> {
    // A bound on the vertices a damaged file could claim: far more than an outline of the
    // whole image's pixel corners has.
    let max_vertices = 4 * (w as u64 + 1) * (h as u64 + 1);
    let n = un_rc_count(d, m, Count::Polygons, "the region")? - 1;
    let mut region = Vec::new();
    let mut total = 0u64;
    for pi in 0..n {
        let at = format!("region polygon {pi}");
        let nv = un_rc_count(d, m, Count::Vertices, &at)? + 2;
        total += nv;
        if total > max_vertices {
            return Err(format!(
                "corrupted: {at} takes the region past {max_vertices} vertices"
            ));
        }
        let mut poly = vec![[d.uniform(w + 1), d.uniform(h + 1)]];
        let mut prev = [1usize; 2];
        for _ in 1..nv {
            // Past the data the decoder reads zeros, which may code steps of 0 for ever.
            if d.overrun() > 8 {
                return Err(format!("corrupted: {at} runs past the end of the data"));
            }
            let last = *poly.last().expect("one vertex");
            let mut q = [0u32; 2];
            for a in 0..2 {
                let count = [Count::StepX, Count::StepY][a];
                let mag = un_rc_count(d, m, count, &at)? - 1;
                let up = mag != 0 && d.bit(&mut m.step_sign[a][prev[a]]);
                let v = if up {
                    last[a] as i64 + mag as i64
                } else {
                    last[a] as i64 - mag as i64
                };
                if v < 0 || v > [w, h][a] as i64 {
                    return Err(format!("corrupted: {at} leaves the {w}x{h} image"));
                }
                prev[a] = if mag == 0 {
                    1
                } else if up {
                    2
                } else {
                    0
                };
                q[a] = v as u32;
            }
            poly.push(q);
        }
        region.push(poly);
    }
    Ok(region)
}

/// What [`un_rc_curves`] reads: the curves, and in version 5 the colour map and the region.
pub(super) struct Tail {
    pub curves: Vec<CurveCodes>,
    pub colour: Option<ColourCodes>,
    pub region: Option<Region>,
}

/// Reads [`rc_curves`]' tail, with the checks of version 2's reader: the curves and, in
/// version 5, the colour map and the region.
pub(super) fn un_rc_curves(
    data: &[u8],
    width: u32,
    height: u32,
    refine: bool,
    undecided: bool,
    version: u8,
) -> std::result::Result<Tail, String> {
    // Bounds on counts a damaged file could claim (the coder can code many symbols in few
    // bytes, so the data's length bounds nothing).
    const MAX_CURVES: u64 = 1 << 16;
    const MAX_PRIMS: usize = 1 << 20;
    let v5 = version >= 5;
    let (xb, yb) = (bits_for(width), bits_for(height));
    let mut m = CurveModel::new();
    let mut d = rc::Decoder::new(data, version >= 4);
    let (colour, region) = if v5 {
        let colour = un_rc_colour(&mut d, &mut m)?;
        (
            Some(colour),
            Some(un_rc_region(&mut d, &mut m, width, height)?),
        )
    } else {
        (None, None)
    };
    let n_curves = un_rc_count(&mut d, &mut m, Count::Curves, "the curve count")? - 1;
    if n_curves > MAX_CURVES {
        return Err(format!("corrupted: {n_curves} curves"));
    }
    let mut curves: Vec<CurveCodes> = Vec::new();
    let mut total = 0usize;
    let mut last = [0u32; 2];
    for ci in 0..n_curves {
        if d.overrun() > 8 {
            return Err("corrupted: the curves run past the end of the data".into());
        }
        let at = format!("curve {ci}");
        let code = d.tree(&mut m.kind, 3) as u8;
        let kind = kind_of(code, &at)?;
        let kc = code as usize;
        let mut dirs = [0i8; 2];
        for &i in free_labels(kind) {
            let ctx = &mut m.label[kc * 2 + i];
            dirs[i] = if undecided {
                signed_of(d.tree(ctx, 2), || format!("{at} has label code 3"))?
            } else if d.bit(&mut ctx[1]) {
                1
            } else {
                -1
            };
        }
        let dirs = fixed_dirs(kind, dirs);
        let n = un_rc_count(&mut d, &mut m, Count::Prims, &at)? as usize;
        total += n;
        if total > MAX_PRIMS {
            return Err(format!("corrupted: over {MAX_PRIMS} primitives"));
        }
        let mut start = [0u32; 2];
        if v5 {
            let gap = un_rc_count(&mut d, &mut m, Count::RowGap, &at)? - 1;
            let y = last[1] as u64 + gap;
            let x = if gap == 0 {
                last[0] as u64 + un_rc_count(&mut d, &mut m, Count::ColGap, &at)? - 1
            } else {
                d.uniform(width + 1) as u64
            };
            if x > width as u64 || y > height as u64 {
                return Err(format!(
                    "corrupted: {at} starts outside the {width}x{height} image"
                ));
            }
            start = [x as u32, y as u32];
            last = start;
        } else {
            for (k, nb) in [xb, yb].into_iter().enumerate() {
                for i in (0..nb).rev() {
                    start[k] |= (d.bit(&mut m.start[k][i as usize]) as u32) << i;
                }
            }
        }
        let axis = d.tree(&mut m.axis, 5) as u8;
        check_placement(start, axis, width, height, &at)?;
        let hair = kind.hair_sides();
        let mut prims: Vec<PrimCodes> = Vec::with_capacity(n.min(4096));
        let mut prev_turn = 3usize;
        for k in 0..n {
            let turn = if k == 0 {
                0
            } else {
                let t = d.tree(&mut m.turn[prev_turn], 2);
                prev_turn = t as usize;
                signed_of(t, || format!("{at}, primitive {k} has turn code 3"))?
            };
            let mut side = [(0u8, 8u8); 2];
            for s in (0..2).filter(|&s| hair[s]) {
                let prev = prims.last().map(|p| &p.side);
                let c = side_ctx(kind, s, turn, &side, prev, hair);
                side[s] = un_rc_side(&mut d, &mut m, &c, refine, &at)?;
            }
            let rc_ctx = prims.last().map_or(16, |p| p.rho as usize);
            let rho = d.tree(&mut m.rho[rc_ctx.min(16)], 4) as u8;
            prims.push(PrimCodes {
                turn,
                side,
                rho,
                shift: SHIFT_ZERO,
            });
        }
        if version >= 7 && kind == Kind::Occluding {
            un_rc_shifts(&mut d, &mut m, &mut prims, &at)?;
        }
        curves.push(CurveCodes {
            kind,
            dirs,
            start,
            axis,
            prims,
        });
    }
    if v5 {
        curves = un_rc_paint_order(&mut d, &mut m, curves, width, height)?;
    }
    if d.overrun() > 8 {
        return Err("corrupted: the curves run past the end of the data".into());
    }
    Ok(Tail {
        curves,
        colour,
        region,
    })
}

/// Version 5's paint order of `c`'s curves, stored in `stored` order: a flag, then either a
/// bit per overlapping pair (when the pairs give back the order: [`order::paint_order`]'s
/// output always does) or the permutation, each curve's rank among the stored curves left.
fn rc_paint_order(e: &mut rc::Encoder, m: &mut CurveModel, c: &Codes, stored: &[u32]) {
    let geometry: Vec<Curve> = stored
        .iter()
        .map(|&i| decode_curve(&c.curves[i as usize]))
        .collect();
    let pairs = order::overlap_pairs(&geometry, c.width, c.height);
    let bits = order::precedence(stored, &pairs);
    let given = order::from_precedence(stored.len(), &pairs, &bits).is_some_and(|o| {
        o.iter()
            .enumerate()
            .all(|(k, &s)| stored[s as usize] == k as u32)
    });
    e.bit(&mut m.ordered, given);
    if given {
        for (&pair, b) in pairs.iter().zip(bits) {
            e.bit(&mut m.precede[longer(&geometry, pair)], b);
        }
        return;
    }
    let mut at = vec![0u32; stored.len()];
    for (s, &i) in stored.iter().enumerate() {
        at[i as usize] = s as u32;
    }
    let mut left = order::Ranks::new(stored.len());
    for &s in &at {
        let n = left.len();
        e.uniform(left.take(s), n);
    }
}

/// The context of a pair's precedence bit: which curve has more primitives (0: the first
/// stored, 1: the second, 2: neither). The pursuit gives the strongest curves first, and
/// long curves are strong: on the long synthetic style the longer of a pair paints first
/// 5 times in 6; on the fur crops it varies, and the probability learns it.
fn longer(geometry: &[Curve], [a, b]: [u32; 2]) -> usize {
    let (la, lb) = (
        geometry[a as usize].prims.len(),
        geometry[b as usize].prims.len(),
    );
    match la.cmp(&lb) {
        std::cmp::Ordering::Greater => 0,
        std::cmp::Ordering::Less => 1,
        std::cmp::Ordering::Equal => 2,
    }
}

/// [`rc_paint_order`] read back: `curves` (in stored order) in paint order.
fn un_rc_paint_order(
    d: &mut rc::Decoder,
    m: &mut CurveModel,
    curves: Vec<CurveCodes>,
    w: u32,
    h: u32,
) -> std::result::Result<Vec<CurveCodes>, String> {
    let n = curves.len();
    let paint: Vec<u32> = if d.bit(&mut m.ordered) {
        let geometry: Vec<Curve> = curves.iter().map(decode_curve).collect();
        let pairs = order::overlap_pairs(&geometry, w, h);
        let bits: Vec<bool> = pairs
            .iter()
            .map(|&pair| d.bit(&mut m.precede[longer(&geometry, pair)]))
            .collect();
        order::from_precedence(n, &pairs, &bits)
            .ok_or("corrupted: the curves' paint order has a cycle")?
    } else {
        let mut left = order::Ranks::new(n);
        (0..n)
            .map(|_| {
                let r = d.uniform(left.len());
                left.nth(r)
            })
            .collect()
    };
    let mut slots: Vec<Option<CurveCodes>> = curves.into_iter().map(Some).collect();
    Ok(paint
        .into_iter()
        .map(|s| slots[s as usize].take().expect("a permutation"))
        .collect())
}

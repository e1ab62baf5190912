//! The host side of C13's Eq. (6) (`warp_compose`) and Eq. (7) (`strand_warp`), and the
//! root-to-free-hair weight β of Eq. (7).

use crate::error::{Error, Result};
use crate::gpu::engine::{Engine, Recording};
use crate::hair::head::WeakPerspective;
use crate::hair::strands::StrandSet;
use crate::stages::{strand_warp, warp_compose};

/// Weight of the feature warp in Eq. (6): ½ in the paper.
pub const PAPER_ALPHA: f32 = 0.5;

fn check_field(name: &str, f: &[[f32; 2]], width: u32, height: u32) -> Result<()> {
    if f.len() != (width * height) as usize {
        return Err(Error::Invalid(format!(
            "{name}: {} vectors for a {width}x{height} frame",
            f.len()
        )));
    }
    Ok(())
}

/// One step of Eq. (6): W*_i = α·W†_i + (1 − α)·[W*_{i−1} + V_i(p + W*_{i−1}(p))], fields of
/// `width` x `height` px on the reference frame (V_i on frame i−1).
pub fn compose(
    engine: &Engine,
    wdag: &[[f32; 2]],
    wprev: &[[f32; 2]],
    flow: &[[f32; 2]],
    width: u32,
    height: u32,
    alpha: f32,
) -> Result<Vec<[f32; 2]>> {
    check_field("feature warp W†", wdag, width, height)?;
    check_field("previous warp W*", wprev, width, height)?;
    check_field("flow V", flow, width, height)?;
    if !(0.0..=1.0).contains(&alpha) {
        return Err(Error::Invalid(format!(
            "warp weight α = {alpha} is outside [0, 1]"
        )));
    }
    let bytes = width as u64 * height as u64 * 8;
    if bytes > engine.max_binding_bytes() {
        return Err(Error::TooLarge {
            what: format!("a {width}x{height} warp field"),
            needed: bytes,
            limit: engine.max_binding_bytes(),
            limit_name: "largest buffer binding".into(),
            unit: "bytes",
        });
    }
    let cfg = warp_compose::Config {
        width,
        height,
        alpha,
        _pad0: 0,
    };
    let mut rec = Recording::default();
    let u = rec.uniform("coif.video.compose.cfg", &cfg);
    let a = rec.upload("coif.video.wdag", wdag);
    let b = rec.upload("coif.video.wprev", wprev);
    let c = rec.upload("coif.video.flow", flow);
    let o = rec.alloc("coif.video.wstar", bytes, crate::base::sentinel::SENTINEL);
    rec.dispatch(
        &warp_compose::STAGE,
        warp_compose::workgroups(&cfg),
        &[u, a, b, c, o],
        &[],
    );
    rec.download(o);
    Ok(engine.run(rec)?.get::<[f32; 2]>(o))
}

/// β of Eq. (7) at every vertex: a smoothstep of the arc length from the root, 0 at the
/// root and 1 from `ramp_m` on. Arc length rather than distance to the scalp, so that hair
/// lying along the scalp (a long fringe, a parting) still follows the image motion.
pub fn beta(strands: &StrandSet, ramp_m: f32) -> Vec<f32> {
    let mut out = Vec::with_capacity(strands.points.len());
    for s in strands.strands() {
        for a in crate::base::polyline::arc_lengths(s) {
            let t = if ramp_m > 0.0 {
                (a as f32 / ramp_m).clamp(0.0, 1.0)
            } else {
                1.0
            };
            out.push(t * t * (3.0 - 2.0 * t));
        }
    }
    out
}

/// Eq. (7) for every vertex of `rest` (head model space, the reference frame's strands):
/// the strands of frame i, given the warp W*_i on the reference frame and both cameras.
#[allow(clippy::too_many_arguments)]
pub fn warp_strands(
    engine: &Engine,
    rest: &StrandSet,
    beta: &[f32],
    wstar: &[[f32; 2]],
    width: u32,
    height: u32,
    cam_r: &WeakPerspective,
    cam_i: &WeakPerspective,
) -> Result<StrandSet> {
    check_field("warp W*", wstar, width, height)?;
    if beta.len() != rest.points.len() {
        return Err(Error::Invalid(format!(
            "β has {} values for {} vertices",
            beta.len(),
            rest.points.len()
        )));
    }
    let limit = engine.max_binding_bytes();
    let field_bytes = width as u64 * height as u64 * 8;
    if field_bytes > limit {
        return Err(Error::TooLarge {
            what: format!("a {width}x{height} warp field"),
            needed: field_bytes,
            limit,
            limit_name: "largest buffer binding".into(),
            unit: "bytes",
        });
    }
    // Vertices are independent: tiles of whole vertices keep each binding under the limit.
    let per_tile = ((limit / 12).min(1 << 24) as usize).max(1);
    let mut points = Vec::with_capacity(rest.points.len());
    for (xs, bs) in rest.points.chunks(per_tile).zip(beta.chunks(per_tile)) {
        let cfg = strand_warp::Config::new(width, height, xs.len() as u32, cam_r, cam_i);
        let mut rec = Recording::default();
        let u = rec.uniform("coif.video.strand_warp.cfg", &cfg);
        let x = rec.upload("coif.video.rest", xs);
        let b = rec.upload("coif.video.beta", bs);
        let f = rec.upload("coif.video.wstar", wstar);
        let o = rec.alloc(
            "coif.video.warped",
            xs.len() as u64 * 12,
            crate::base::sentinel::SENTINEL,
        );
        rec.dispatch(
            &strand_warp::STAGE,
            strand_warp::workgroups(&cfg),
            &[u, x, b, f, o],
            &[],
        );
        rec.download(o);
        points.extend(engine.run(rec)?.get::<[f32; 3]>(o));
    }
    let mut out = rest.clone();
    out.points = points;
    Ok(out)
}

//! Eq. (6) and Eq. (7) of C13 (issue 15): `warp_compose` and `strand_warp` (with the shared
//! bilinear field sampler `shared/field_sample.wgsl`) on lavapipe
//! against their CPU mirrors, and the properties the equations promise.

use crate::common;

use coif::gpu::engine::Engine;
use coif::hair::head::WeakPerspective;
use coif::hair::strands::StrandSet;
use coif::video::warp::{beta, compose, warp_strands, PAPER_ALPHA};
use glam::{Mat3, Vec2};

fn field(w: u32, h: u32, seed: u64, amp: f32) -> Vec<[f32; 2]> {
    (0..(w * h) as u64)
        .map(|i| {
            [
                amp * (2.0 * common::hash01(2 * i, seed) - 1.0),
                amp * (2.0 * common::hash01(2 * i + 1, seed) - 1.0),
            ]
        })
        .collect()
}

fn largest(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}

fn flat2(v: &[[f32; 2]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

fn flat3(v: &[[f32; 3]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

/// Strands hanging from a head-sized sphere: `n` strands of 24 vertices, 4 mm apart.
fn strands(n: usize) -> StrandSet {
    let mut pts = Vec::new();
    let mut counts = Vec::new();
    for i in 0..n {
        let a = i as f32 * 2.399;
        let (x0, z0) = (0.09 * a.cos(), 0.09 * a.sin().abs());
        for k in 0..24 {
            let t = k as f32 * 0.004;
            pts.push([x0 * (1.0 + t), 0.05 - t * 1.5, z0 + 0.3 * t * t]);
        }
        counts.push(24);
    }
    StrandSet::new(pts, counts)
}

fn cameras() -> (WeakPerspective, WeakPerspective) {
    let r = WeakPerspective::new(900.0, Mat3::from_rotation_y(0.05), Vec2::new(64.0, 60.0));
    let i = WeakPerspective::new(
        905.0,
        Mat3::from_rotation_y(0.12) * Mat3::from_rotation_x(-0.04),
        Vec2::new(66.5, 58.0),
    );
    (r, i)
}

#[test]
fn warp_compose_parity_on_lavapipe() {
    let (w, h) = (63, 65);
    let (a, b, v) = (
        field(w, h, 1, 3.0),
        field(w, h, 2, 3.0),
        field(w, h, 3, 2.0),
    );
    let cpu = compose(&Engine::cpu(), &a, &b, &v, w, h, PAPER_ALPHA).unwrap();
    let gpu = compose(&common::gpu(), &a, &b, &v, w, h, PAPER_ALPHA).unwrap();
    let d = largest(&flat2(&cpu), &flat2(&gpu));
    println!("warp_compose parity at {w}x{h}: largest difference {d:.2e} px");
    assert!(d <= 1e-4, "{d} px");
}

#[test]
fn strand_warp_parity_on_lavapipe() {
    let (w, h) = (128, 120);
    let s = strands(300);
    let bt = beta(&s, 0.03);
    let f = field(w, h, 4, 4.0);
    let (cr, ci) = cameras();
    let cpu = warp_strands(&Engine::cpu(), &s, &bt, &f, w, h, &cr, &ci).unwrap();
    let gpu = warp_strands(&common::gpu(), &s, &bt, &f, w, h, &cr, &ci).unwrap();
    let d = largest(&flat3(&cpu.points), &flat3(&gpu.points));
    println!(
        "strand_warp parity, {} vertices: largest difference {d:.2e} m",
        s.points.len()
    );
    assert!(d <= 1e-6, "{d} m");
}

/// Eq. (6) with α = 0 is the flow chained from frame to frame; with α = 1 the features.
#[test]
fn compose_chains_flow_and_averages_features() {
    let (w, h) = (40, 30);
    let e = Engine::cpu();
    let zero = vec![[0.0f32; 2]; (w * h) as usize];
    let step = vec![[0.75f32, -0.5]; (w * h) as usize];
    let dag = vec![[10.0f32, 4.0]; (w * h) as usize];
    let mut acc = zero.clone();
    for _ in 0..4 {
        acc = compose(&e, &dag, &acc, &step, w, h, 0.0).unwrap();
    }
    assert!(acc
        .iter()
        .all(|v| (v[0] - 3.0).abs() < 1e-5 && (v[1] + 2.0).abs() < 1e-5));
    let f = compose(&e, &dag, &acc, &step, w, h, 1.0).unwrap();
    assert!(f.iter().all(|v| *v == [10.0, 4.0]));
    let half = compose(&e, &dag, &zero, &step, w, h, 0.5).unwrap();
    assert!(half.iter().all(|v| *v == [5.375, 1.75]));
    // A mismatched field is refused, not read out of bounds.
    assert!(compose(&e, &dag[1..], &zero, &step, w, h, 0.5).is_err());
    assert!(compose(&e, &dag, &zero, &step, w, h, 1.5).is_err());
}

/// Eq. (7): a warp that is exactly the head's rigid image motion leaves the strands where
/// they are in head space; roots (β = 0) never move; a pure image translation on top moves
/// free hair by the lifted amount and keeps depth.
#[test]
fn strand_warp_separates_head_and_hair_motion() {
    let (w, h) = (128, 120);
    let e = Engine::cpu();
    let s = strands(50);
    let bt = beta(&s, 0.03);
    let (cr, ci) = cameras();
    // W* = p'_i − p_r at every pixel a vertex projects to: build it per vertex by warping a
    // field that is the rigid motion of the nearest point, then check the per-vertex result.
    let rigid: Vec<[f32; 2]> = (0..(w * h))
        .map(|k| {
            let (x, y) = ((k % w) as f32, (k / w) as f32);
            // The rigid motion depends on depth, which a pixel does not know; use a plane
            // through the strands' mean depth so the test isolates the arithmetic.
            let p = cr.unproject(glam::Vec3::new(
                x,
                y,
                cr.project(glam::Vec3::new(0.0, 0.0, 0.06)).z,
            ));
            let q = ci.project(p);
            [q.x - x, q.y - y]
        })
        .collect();
    let out = warp_strands(&e, &s, &bt, &rigid, w, h, &cr, &ci).unwrap();
    let mut worst_root = 0.0f32;
    for (i, st) in out.strands().enumerate() {
        let r0 = s.strands().nth(i).unwrap()[0];
        worst_root = worst_root.max(largest(&st[0], &r0));
    }
    println!("rigid-only warp: roots moved {worst_root:.1e} m");
    assert!(worst_root == 0.0);
    let zero = vec![[0.0f32; 2]; (w * h) as usize];
    let shift: Vec<[f32; 2]> = vec![[3.0, -2.0]; (w * h) as usize];
    let still = warp_strands(&e, &s, &bt, &zero, w, h, &cr, &cr).unwrap();
    assert_eq!(still.points, s.points, "no motion, no change");
    let moved = warp_strands(&e, &s, &bt, &shift, w, h, &cr, &cr).unwrap();
    for ((a, b), bk) in s.points.iter().zip(&moved.points).zip(&bt) {
        let (pa, pb) = (cr.project((*a).into()), cr.project((*b).into()));
        assert!(
            (pb.x - pa.x - 3.0 * bk).abs() < 1e-3,
            "{} vs {}",
            pb.x - pa.x,
            3.0 * bk
        );
        assert!((pb.y - pa.y + 2.0 * bk).abs() < 1e-3);
        assert!((pb.z - pa.z).abs() < 1e-3, "depth kept");
    }
}

#[test]
fn beta_rises_from_the_root() {
    let s = strands(3);
    let b = beta(&s, 0.03);
    assert_eq!(b[0], 0.0);
    assert!(b[1] > 0.0 && b[1] < 0.2, "{}", b[1]);
    assert!((b[23] - 1.0).abs() < 1e-6);
    assert!(b.windows(2).take(23).all(|w| w[1] >= w[0]));
}

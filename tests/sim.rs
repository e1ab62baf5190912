//! Simulation (issue 14): figures on real strands grown on the parametric head, and the
//! sim_step pass against its CPU mirror on lavapipe.

use coif::gpu::engine::Engine;
use coif::hair::head::Head;
use coif::hair::strands::StrandSet;
use coif::sim::{max_displacement, HeadTrack, Sim, SimParams};
use coif::synth::synth3d::{synth3d_with, Synth3dOptions};
use coif::synth::{Style, SynthParams};

/// Strands of the 3D ground-truth synth (long style), on the default head.
fn strands(n: usize) -> (StrandSet, Head) {
    let c = synth3d_with(
        &SynthParams {
            style: Style::Long,
            seed: 1,
            width: 128,
            height: 128,
        },
        &Synth3dOptions {
            strands: n,
            max_yaw_deg: 0.0,
        },
    );
    (c.gt, c.head)
}

#[test]
fn strong_wind_keeps_lengths_roots_and_the_head_out() {
    let (s, head) = strands(300);
    let p = SimParams {
        wind: 3.0,
        substeps: 10,
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    let rest = sim.x.clone();
    let mut worst_p99 = 0.0f64;
    let mut worst_len = 0.0f64;
    let mut worst_root = 0.0f64;
    let mut deepest = f32::INFINITY;
    for _ in 0..10 {
        sim.advance(&e, 100).unwrap();
        let f = sim.figures();
        worst_p99 = worst_p99.max(f.stretch_p99);
        worst_len = worst_len.max(f.length_max);
        worst_root = worst_root.max(f.root_error_max);
        deepest = deepest.min(f.min_head_distance);
        println!("{f:?}");
    }
    let moved = max_displacement(&rest, &sim.x);
    println!(
        "1000 steps, wind 3 m/s: stretch p99 {:.3}%, length {:.3}%, roots {:.1e} m, deepest {:.2} mm, moved {:.1} mm",
        100.0 * worst_p99,
        100.0 * worst_len,
        worst_root,
        deepest * 1e3,
        moved * 1e3
    );
    assert!(moved > 0.01, "the wind should move the hair: {moved} m");
    assert!(worst_p99 <= 0.01, "stretch p99 {worst_p99}");
    assert!(worst_len <= 0.005, "strand length {worst_len}");
    assert!(worst_root <= 1e-6, "roots {worst_root} m");
    assert!(
        deepest >= -5e-4,
        "deepest vertex {deepest} m inside the head"
    );
}

#[test]
fn still_air_and_a_still_head_move_nothing() {
    let (s, head) = strands(200);
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &SimParams::default()).unwrap();
    let rest = sim.x.clone();
    sim.advance(&e, 1000).unwrap();
    let moved = max_displacement(&rest, &sim.x);
    println!("1000 steps, no wind: largest motion {moved:.2e} m");
    assert!(moved <= 1e-4, "{moved} m");
}

#[test]
fn energy_never_rises_once_the_wind_stops() {
    let (s, head) = strands(200);
    let p = SimParams {
        wind: 2.0,
        wind_until: Some(10),
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    sim.advance(&e, 10 * p.substeps).unwrap();
    let mut last = sim.energy();
    let mut rises = 0;
    for k in 0..200 {
        sim.advance(&e, 5).unwrap();
        let en = sim.energy();
        if en > last * (1.0 + 1e-6) + 1e-12 {
            rises += 1;
            println!("step {}: energy rose {last:.6e} -> {en:.6e}", k * 5);
        }
        last = en;
    }
    assert_eq!(rises, 0);
}

#[test]
fn a_head_turn_carries_the_roots() {
    let (s, head) = strands(200);
    let p = SimParams {
        track: HeadTrack {
            yaw: coif::sim::track::parse_keys("0:0,15:20,30:0").unwrap(),
            ..Default::default()
        },
        ..Default::default()
    };
    let e = Engine::cpu();
    let mut sim = Sim::new(&s, &head, &p).unwrap();
    let mut worst_root = 0.0f64;
    let mut deepest = f32::INFINITY;
    for _ in 0..30 {
        sim.advance(&e, p.substeps).unwrap();
        let f = sim.figures();
        worst_root = worst_root.max(f.root_error_max);
        deepest = deepest.min(f.min_head_distance);
    }
    println!(
        "20° head turn: roots {worst_root:.1e} m, deepest {:.2} mm",
        deepest * 1e3
    );
    assert!(worst_root <= 1e-6, "{worst_root}");
    assert!(deepest >= -5e-4, "{deepest}");
}

fn lavapipe() -> Engine {
    Engine::new(coif::gpu::engine::BackendChoice::Gpu).expect("a Vulkan adapter (lavapipe)")
}

/// sim_step on lavapipe against its CPU mirror: after one step and after 100 steps of wind
/// with a head turn.
#[test]
fn sim_step_parity() {
    let (s, head) = strands(256);
    let p = SimParams {
        wind: 1.5,
        track: HeadTrack {
            yaw: coif::sim::track::parse_keys("0:0,10:10").unwrap(),
            ..Default::default()
        },
        ..Default::default()
    };
    let (cpu, gpu) = (Engine::cpu(), lavapipe());
    let mut a = Sim::new(&s, &head, &p).unwrap();
    let mut b = Sim::new(&s, &head, &p).unwrap();
    a.advance(&cpu, 1).unwrap();
    b.advance(&gpu, 1).unwrap();
    let one = max_displacement(&a.x, &b.x);
    println!("sim_step parity after 1 step: largest difference {one:.2e} m");
    assert!(one <= 1e-5, "{one} m");
    a.advance(&cpu, 99).unwrap();
    b.advance(&gpu, 99).unwrap();
    let mut d: Vec<f64> =
        a.x.chunks(3)
            .zip(b.x.chunks(3))
            .map(|(p, q)| max_displacement(p, q))
            .collect();
    d.sort_by(f64::total_cmp);
    let q999 = d[((d.len() - 1) as f64 * 0.999) as usize];
    let moved = max_displacement(&s_first(&a), &a.x);
    println!(
        "after 100 steps: 99.9th percentile difference {q999:.2e} m, largest {:.2e} m (hair moved up to {moved:.3} m)",
        d[d.len() - 1]
    );
    assert!(q999 <= 1e-3, "{q999} m");
}

fn s_first(sim: &Sim) -> Vec<f32> {
    sim.rest.points.iter().flatten().copied().collect()
}

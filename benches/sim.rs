//! Simulation steps per second (issue 14): 30k strands x 32 vertices of `coif synth --gt3d`
//! long hair in 1 m/s wind, on the cpu backend and on lavapipe (two steps: a slow software
//! GPU), next to the same mass-spring scheme in numba (`benches/peers/sim_numba.py`, parallel
//! over strands; it has a sphere for a head and constant wind, so it does less per step) in
//! the same run. Prints ms per step, the ratio, and the memory the state takes.
//!
//! Run: `cargo bench --bench sim` (needs `pip install numba` for the peer; COIF_BENCH_STRANDS
//! sets the strand count).

use coif::sim::{Sim, SimParams};
use coif::synth::synth3d::{synth3d_with, Synth3dOptions};
use coif::synth::{Style, SynthParams};
use coif::{BackendChoice, Engine};
use std::io::Write;
use std::process::Command;
use std::time::Instant;

fn ms_per_step(engine: &Engine, sim: &mut Sim, steps: u32, reps: usize) -> f64 {
    sim.advance(engine, 1).unwrap();
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            sim.advance(engine, steps).unwrap();
            1e3 * s.elapsed().as_secs_f64() / steps as f64
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn write_f32(path: &std::path::Path, v: &[f32]) {
    std::fs::File::create(path)
        .unwrap()
        .write_all(bytemuck::cast_slice(v))
        .unwrap();
}

fn main() {
    let n: usize = std::env::var("COIF_BENCH_STRANDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30_000);
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
    let p = SimParams {
        wind: 1.0,
        ..Default::default()
    };
    let mut sim = Sim::new(&c.gt, &c.head, &p).unwrap();
    println!(
        "sim bench: {} strands x {} vertices, dt {:.2e} s",
        sim.n_strands(),
        p.n_verts,
        p.dt()
    );
    let state = (sim.x.len() + sim.v.len() + sim.rest_lengths().len()) * 4;
    println!(
        "  memory: state {:.1} MiB (x, v, rest lengths: 36 B per vertex) + roots; the pass \
         keeps one strand's band matrix (9 KiB) per invocation in private memory",
        state as f64 / (1 << 20) as f64
    );
    let dir = tempfile::tempdir().unwrap();
    write_f32(&dir.path().join("x.f32"), &sim.x);
    write_f32(&dir.path().join("rest.f32"), sim.rest_lengths());
    write_f32(&dir.path().join("roots.f32"), sim.roots());
    let cpu = Engine::new(BackendChoice::Cpu).unwrap();
    let cpu_ms = ms_per_step(&cpu, &mut sim, 10, 3);
    println!(
        "  {}: {cpu_ms:.1} ms per step ({:.2} steps/s)",
        cpu.describe(),
        1e3 / cpu_ms
    );
    match Engine::new(BackendChoice::Gpu) {
        Ok(gpu) => {
            let mut g = Sim::new(&c.gt, &c.head, &p).unwrap();
            let ms = ms_per_step(&gpu, &mut g, 1, 1);
            println!(
                "  {}: {ms:.1} ms per step ({:.2} steps/s)",
                gpu.describe(),
                1e3 / ms
            );
        }
        Err(e) => println!("  gpu: not measured ({e})"),
    }
    let peer = Command::new("python3")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/benches/peers/sim_numba.py"
        ))
        .arg(dir.path())
        .arg(p.n_verts.to_string())
        .arg("10")
        .arg("3")
        .output();
    match peer {
        Ok(o) if o.status.success() => {
            let line = String::from_utf8_lossy(&o.stdout);
            let v: serde_json::Value = serde_json::from_str(line.trim()).unwrap();
            let peer_ms = v["ms_per_step"].as_f64().unwrap();
            println!(
                "  numba peer ({} threads): {peer_ms:.1} ms per step ({:.2} steps/s); coif cpu time / numba time = {:.2}",
                rayon::current_num_threads(),
                1e3 / peer_ms,
                cpu_ms / peer_ms
            );
        }
        Ok(o) => println!(
            "  numba peer failed (pip install numba): {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => println!("  numba peer not run: {e}"),
    }
}

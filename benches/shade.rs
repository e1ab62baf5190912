//! Shading time for 30k strands x 50 vertices (issue 5's bench size), one key light and one
//! back light, on the CPU mirrors and on the GPU (lavapipe here). Prints times; no asserts.

use coif::gpu::engine::{BackendChoice, Engine};
use coif::render::shade::{shade_model_space, Light, ShadeParams};
use std::time::Instant;

fn main() {
    let (strands, per) = (30_000u32, 50u32);
    let mut points = Vec::with_capacity((strands * per) as usize);
    for s in 0..strands {
        let a = s as f32 * 0.618_034 * std::f32::consts::TAU;
        for j in 0..per {
            let t = j as f32 * 0.004;
            points.push([0.1 * a.cos() + 0.01 * (t * 40.0).sin(), -t, 0.1 * a.sin()]);
        }
    }
    let counts = vec![per; strands as usize];
    let base = vec![[0.12f32, 0.07, 0.04, 1.0]; points.len()];
    let p = ShadeParams {
        amount: 0.6,
        hue: 30.0,
        lights: vec![Light::default(), "0.1,0.3,-1,1.5".parse().unwrap()],
        ..Default::default()
    };
    for choice in [BackendChoice::Cpu, BackendChoice::Gpu] {
        let e = Engine::new(choice).expect("backend");
        let run = || shade_model_space(&e, &points, &counts, &base, [0.0, 0.0, 1.0], &p).unwrap();
        run(); // pipeline compilation, first-touch allocations
        let reps = 3;
        let t0 = Instant::now();
        for _ in 0..reps {
            std::hint::black_box(run());
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / reps as f64;
        println!(
            "{}: {} vertices in {ms:.1} ms ({:.1} Mvertex/s)",
            e.describe(),
            points.len(),
            points.len() as f64 / ms / 1e3
        );
    }
}

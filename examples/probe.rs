use coif::orient::*;
use std::time::Instant;
fn main() {
    let n: u32 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(256);
    let mut s = 12345u64;
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = (i % n) as f32;
            let y = (i / n) as f32;
            0.5 + 0.3 * ((x * 0.9 + y * 1.3).sin()) + 0.1 * ((s >> 40) as f32 / 16777216.0)
        })
        .collect();
    let img = GrayImage {
        width: n,
        height: n,
        data,
    };
    let p = OrientParams::default();
    let cpu = coif::Engine::cpu();
    let t = Instant::now();
    let a = orient(&cpu, &img, None, &p).unwrap();
    println!("cpu {:?}", t.elapsed());
    let gpu = coif::Engine::new(coif::BackendChoice::Gpu).unwrap();
    let t = Instant::now();
    let b = orient(&gpu, &img, None, &p).unwrap();
    println!("gpu {:?}", t.elapsed());
    let t = Instant::now();
    let b = orient(&gpu, &img, None, &p).unwrap();
    println!("gpu again {:?}", t.elapsed());
    let mut bad = 0;
    let mut maxc = 0f32;
    let cmax = a.confidence.iter().cloned().fold(0f32, f32::max);
    for i in 0..a.theta.len() {
        let d = (a.theta[i] - b.theta[i]).abs() % std::f32::consts::PI;
        let d = d.min(std::f32::consts::PI - d);
        if d.to_degrees() > 0.5 {
            bad += 1;
        }
        maxc = maxc.max((a.confidence[i] - b.confidence[i]).abs() / cmax);
    }
    println!(
        "theta bad {} of {}, max conf rel diff {:e}, theta[0] {} {}",
        bad,
        a.theta.len(),
        maxc,
        a.theta[0],
        b.theta[0]
    );
}

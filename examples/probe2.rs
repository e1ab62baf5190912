use coif::orient::*;
use std::time::Instant;
fn main() {
    let n: u32 = 256;
    let data: Vec<f32> = (0..n * n).map(|i| ((i % 7) as f32) * 0.1).collect();
    let img = GrayImage {
        width: n,
        height: n,
        data,
    };
    let gpu = coif::Engine::new(coif::BackendChoice::Gpu).unwrap();
    for (name, p) in [
        (
            "gabor only",
            OrientParams {
                dog_sigma_coarse: 0.0,
                refine_iters: 0,
                smooth_sigma: 0.0,
                ..Default::default()
            },
        ),
        (
            "dog+gabor",
            OrientParams {
                refine_iters: 0,
                smooth_sigma: 0.0,
                ..Default::default()
            },
        ),
        ("full", OrientParams::default()),
    ] {
        orient(&gpu, &img, None, &p).unwrap();
        let t = Instant::now();
        orient(&gpu, &img, None, &p).unwrap();
        println!("{name} {:?}", t.elapsed());
    }
}

//! PatchMatch inpainting of the embedded 512² astronaut photo with her hair as the hole (the
//! layer C13 §4 fills behind the hair): the CPU backend (median of COIF_BENCH_REPS runs) and
//! lavapipe (one timed run after a warm-up that compiles the pipelines), next to OpenCV's
//! `cv2.inpaint` (Telea and Navier-Stokes, `benches/peers/inpaint_cv.py`) on the same 8-bit
//! photo and hole in the same run. cv2.inpaint is a diffusion-type method (it propagates
//! smooth colour, copies no texture), so the ratio compares cost, not results.
//!
//! The hole: coif's stroke segmentation of the hair (`coif::analyze::segment` with the shipped
//! `ASTRONAUT_STROKES`), dilated by 4 px (a disc) to take the hair's soft edge too.
//!
//! Run: `CARGO_TARGET_DIR=/work/target-h cargo bench --bench inpaint`
//! (needs `pip install opencv-python-headless` for the peer; COIF_BENCH_OUT=dir keeps the
//! pictures: photo with the hole in magenta, our fill, Telea's.)

use coif::base::colour::{linear_to_srgb, srgb_to_linear};
use coif::render::inpaint::{inpaint, InpaintParams};
use coif::{BackendChoice, Engine};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn json_f64(s: &str, key: &str) -> Option<f64> {
    let at = s.find(&format!("\"{key}\":"))? + key.len() + 3;
    let rest = s[at..].trim_start();
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].trim().parse().ok()
}

/// The astronaut's hair mask from the shipped strokes, dilated by `r` px.
fn hair_hole(img: &image::RgbImage, r: i32) -> Vec<u8> {
    let (w, h) = img.dimensions();
    let strokes = coif::io::annot::Strokes::parse(
        coif::io::assets::ASTRONAUT_STROKES,
        Path::new("astronaut_strokes.json"),
        Some((w, h)),
    )
    .expect("shipped strokes parse");
    let mask =
        coif::analyze::segment::segment(img, &strokes, &Default::default()).expect("segmentation");
    let (w, h) = (w as i32, h as i32);
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let hit = (-r..=r).any(|dy| {
                (-r..=r).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    dx * dx + dy * dy <= r * r
                        && xx >= 0
                        && yy >= 0
                        && xx < w
                        && yy < h
                        && mask.get_pixel(xx as u32, yy as u32)[0] > 127
                })
            });
            hit as u8
        })
        .collect()
}

fn to_rgb8(w: u32, h: u32, v: &[[f32; 3]]) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb(v[(y * w + x) as usize].map(linear_to_srgb))
    })
}

fn main() {
    let reps: usize = std::env::var("COIF_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let photo = image::load_from_memory(coif::io::assets::ASTRONAUT_PNG)
        .expect("embedded photo decodes")
        .to_rgb8();
    let (w, h) = photo.dimensions();
    let hole = hair_hole(&photo, 4);
    let n_hole = hole.iter().filter(|&&m| m != 0).count();
    let rgb: Vec<[f32; 3]> = photo
        .pixels()
        .map(|p| [p[0], p[1], p[2]].map(srgb_to_linear))
        .collect();
    let p = InpaintParams::default();
    println!(
        "PatchMatch inpainting, astronaut {w}x{h}, hole = hair mask dilated 4 px ({n_hole} px, \
         {:.1}%), patch {}, {} PM iterations x {} EM steps per level:",
        100.0 * n_hole as f64 / (w * h) as f64,
        p.patch,
        p.iterations,
        p.em_iterations
    );

    let cpu = Engine::cpu();
    let _ = inpaint(&cpu, w, h, &rgb, &hole, &p).unwrap();
    let mut times = Vec::new();
    let mut out_cpu = Vec::new();
    for _ in 0..reps {
        let t = Instant::now();
        let (o, rep) = inpaint(&cpu, w, h, &rgb, &hole, &p).unwrap();
        times.push(t.elapsed().as_secs_f64());
        if out_cpu.is_empty() {
            println!(
                "  levels {:?}, {} dispatches, mean patch error {:.2e}",
                rep.levels
                    .iter()
                    .map(|l| (l.width, l.height))
                    .collect::<Vec<_>>(),
                rep.dispatches,
                rep.mean_patch_error
            );
        }
        out_cpu = o;
    }
    let ours = median(times);
    println!("  {}: {:.3} s median of {reps}", cpu.describe(), ours);

    match Engine::new(BackendChoice::Gpu) {
        Ok(g) => {
            // Compile the four pipelines on a small image first, then one timed run.
            let small: Vec<[f32; 3]> = rgb[..64 * 64].to_vec();
            let mut sh = vec![0u8; 64 * 64];
            sh[30 * 64 + 30] = 1;
            let _ = inpaint(&g, 64, 64, &small, &sh, &p).unwrap();
            let t = Instant::now();
            let (o, _) = inpaint(&g, w, h, &rgb, &hole, &p).unwrap();
            let tg = t.elapsed().as_secs_f64();
            let mean_diff = (0..o.len())
                .filter(|&i| hole[i] != 0)
                .map(|i| {
                    (0..3)
                        .map(|c| (o[i][c] - out_cpu[i][c]).abs() as f64)
                        .sum::<f64>()
                        / 3.0
                })
                .sum::<f64>()
                / n_hole as f64;
            println!(
                "  {}: {tg:.3} s (one run); lavapipe / cpu backend {:.1}x; mean |gpu - cpu| over \
                 the hole {mean_diff:.1e}",
                g.describe(),
                tg / ours
            );
        }
        Err(e) => println!("  no GPU backend: {e}"),
    }

    let dir = tempfile::tempdir().unwrap();
    photo.save(dir.path().join("photo.png")).unwrap();
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([255 * hole[(y * w + x) as usize]]))
        .save(dir.path().join("hole.png"))
        .unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/inpaint_cv.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(dir.path())
        .arg(reps.to_string())
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let s = String::from_utf8_lossy(&o.stdout).to_string();
            println!(
                "  OpenCV cv2.inpaint (diffusion-type, radius 3): {}",
                s.trim()
            );
            let telea = json_f64(&s, "telea_s").expect("peer prints telea_s");
            let ns = json_f64(&s, "ns_s").expect("peer prints ns_s");
            println!(
                "  time ratio ours (cpu backend) / Telea: {:.1} ({:.3} s vs {:.3} s); / NS: {:.1}",
                ours / telea,
                ours,
                telea,
                ours / ns
            );
        }
        Ok(o) => println!(
            "  OpenCV peer failed (pip install opencv-python-headless): {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => println!("  cannot run python3: {e}"),
    }
    if let Ok(keep) = std::env::var("COIF_BENCH_OUT") {
        let keep = Path::new(&keep);
        std::fs::create_dir_all(keep).unwrap();
        let marked = image::RgbImage::from_fn(w, h, |x, y| {
            if hole[(y * w + x) as usize] != 0 {
                image::Rgb([255, 0, 255])
            } else {
                *photo.get_pixel(x, y)
            }
        });
        marked.save(keep.join("bench_hole.png")).unwrap();
        to_rgb8(w, h, &out_cpu)
            .save(keep.join("bench_patchmatch.png"))
            .unwrap();
        let _ = std::fs::copy(dir.path().join("telea.png"), keep.join("bench_telea.png"));
        println!("  pictures in {}", keep.display());
    }
}

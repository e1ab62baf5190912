//! Loading a clip: a folder of numbered PNG/JPEG frames, or a video file decoded to such a
//! folder with the `ffmpeg` program. Listing, numbering and size checks are light sequential
//! work and stay on the CPU.
//!
//! Frames are ordered by the number in their file name (`0000.png`, `frame_1.png`,
//! `frame_10.png`, ...), not by text order, and the numbers must run without a gap so that a
//! lost frame cannot silently shift the motion by one frame.

use crate::error::{Error, Result};
use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Longest digit run read as a frame number: 18 digits always fit in a `u64`.
const MAX_DIGITS: usize = 18;

/// File written beside decoded frames so that a later run can reuse them (see [`decode_video`]).
pub const DECODED_JSON: &str = "decoded.json";

/// What to tell a user who has no ffmpeg.
const INSTALL_HINT: &str =
    "install ffmpeg (Debian: apt-get install ffmpeg) or pass --frames DIR of PNGs";

/// A clip: frame files in order, all of one size.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    pub width: u32,
    pub height: u32,
    /// Frame `k` of the clip is `frames[k]`.
    pub frames: Vec<PathBuf>,
    /// Frames per second when the source tells it (a video read with ffprobe); `None` for a
    /// folder of images.
    pub fps: Option<f32>,
}

impl Clip {
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Frame `k` as 8-bit RGB. The size is checked again: a file may have been replaced since
    /// the folder was opened.
    pub fn load_rgb(&self, k: usize) -> Result<image::RgbImage> {
        let path = self.frames.get(k).ok_or_else(|| {
            Error::Invalid(format!(
                "frame index {k} is out of range: the clip has {} frames (0..={})",
                self.frames.len(),
                self.frames.len().saturating_sub(1)
            ))
        })?;
        let img = crate::io::images::load_rgb(path)?;
        if img.dimensions() != (self.width, self.height) {
            return Err(Error::bad_file(
                path,
                format!(
                    "frame is {}x{} px but the clip is {}x{} px",
                    img.width(),
                    img.height(),
                    self.width,
                    self.height
                ),
            ));
        }
        Ok(img)
    }
}

/// A frame file name split around its frame number: `frame_0012.png` → ("frame_", 12, "").
struct Numbered {
    path: PathBuf,
    number: u64,
    /// The name with the number taken out, which every frame of a clip shares.
    pattern: (String, String),
}

fn is_frame_image(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(OsStr::to_str)
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg"))
}

/// The last run of ASCII digits in the file stem, with the text before and after it.
fn split_number(path: &Path) -> Result<Option<Numbered>> {
    let stem = path.file_stem().and_then(OsStr::to_str).unwrap_or("");
    let bytes = stem.as_bytes();
    let Some(end) = bytes.iter().rposition(u8::is_ascii_digit).map(|i| i + 1) else {
        return Ok(None);
    };
    let start = bytes[..end]
        .iter()
        .rposition(|b| !b.is_ascii_digit())
        .map_or(0, |i| i + 1);
    let digits = &stem[start..end];
    // Leading zeros do not count towards the limit: 0000000000000000000001 is frame 1.
    let significant = digits.trim_start_matches('0');
    if significant.len() > MAX_DIGITS {
        return Err(Error::bad_file(
            path,
            format!("the frame number {digits} has more than {MAX_DIGITS} digits"),
        ));
    }
    let number = if significant.is_empty() {
        0
    } else {
        significant.parse().expect("checked digits")
    };
    Ok(Some(Numbered {
        path: path.to_path_buf(),
        number,
        pattern: (stem[..start].to_string(), stem[end..].to_string()),
    }))
}

/// Opens a folder of numbered PNG/JPEG frames. Other files (and hidden ones, such as
/// temporary files) are ignored. Only image headers are read here; [`Clip::load_rgb`] decodes.
pub fn open_frames_dir(dir: &Path) -> Result<Clip> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut images = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let path = entry.path();
        let hidden = entry.file_name().to_string_lossy().starts_with('.');
        if hidden || !is_frame_image(&path) {
            continue;
        }
        // Follows symlinks, so a folder of links to frames works.
        if std::fs::metadata(&path)
            .map(|m| m.is_file())
            .unwrap_or(false)
        {
            images.push(path);
        }
    }
    if images.is_empty() {
        return Err(Error::bad_file(
            dir,
            "no frames: the folder holds no PNG or JPEG files",
        ));
    }
    images.sort();

    let mut numbered = Vec::with_capacity(images.len());
    let mut unnumbered = Vec::new();
    for path in &images {
        match split_number(path)? {
            Some(n) => numbered.push(n),
            None => unnumbered.push(path),
        }
    }
    if numbered.is_empty() {
        return Err(Error::bad_file(
            dir,
            format!(
                "no numbered frames: none of the {} images has a number in its name \
                 (frames are ordered by it, e.g. 0000.png, 0001.png, ...)",
                images.len()
            ),
        ));
    }
    if let Some(p) = unnumbered.first() {
        return Err(Error::bad_file(
            p,
            format!(
                "image without a frame number in its name, beside numbered frames such as {}; \
                 rename it or move it out of the folder",
                file_name(&numbered[0].path)
            ),
        ));
    }
    numbered.sort_by_key(|n| n.number);
    let first = &numbered[0];
    if let Some(other) = numbered.iter().find(|n| n.pattern != first.pattern) {
        return Err(Error::bad_file(
            &other.path,
            format!(
                "its name does not follow the pattern of {} ({}<number>{}); \
                 one clip per folder",
                file_name(&first.path),
                first.pattern.0,
                first.pattern.1
            ),
        ));
    }
    for w in numbered.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if a.number == b.number {
            return Err(Error::bad_file(
                &b.path,
                format!(
                    "frame number {} appears twice: also {}",
                    b.number,
                    file_name(&a.path)
                ),
            ));
        }
        if b.number != a.number + 1 {
            let missing = if b.number == a.number + 2 {
                format!("frame {} is missing", a.number + 1)
            } else {
                format!("frames {} to {} are missing", a.number + 1, b.number - 1)
            };
            return Err(Error::bad_file(
                dir,
                format!(
                    "{missing}: the numbering jumps from {} to {}",
                    file_name(&a.path),
                    file_name(&b.path)
                ),
            ));
        }
    }

    let (width, height) = image_size(&first.path)?;
    for n in &numbered[1..] {
        let (w, h) = image_size(&n.path)?;
        if (w, h) != (width, height) {
            return Err(Error::bad_file(
                &n.path,
                format!(
                    "frame is {w}x{h} px but {} is {width}x{height} px; all frames must have one size",
                    file_name(&first.path)
                ),
            ));
        }
    }
    Ok(Clip {
        width,
        height,
        frames: numbered.into_iter().map(|n| n.path).collect(),
        fps: None,
    })
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
}

/// Width and height from the image header alone.
fn image_size(path: &Path) -> Result<(u32, u32)> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    if reader.format().is_none() {
        return Err(Error::bad_file(
            path,
            "unreadable frame: not a PNG or JPEG image",
        ));
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| Error::bad_file(path, format!("unreadable frame: {e}")))?;
    if w == 0 || h == 0 {
        return Err(Error::bad_file(path, "unreadable frame: it has no pixels"));
    }
    Ok((w, h))
}

/// The external programs [`decode_video_with`] runs. A name without a `/` is looked up in
/// `search_path` (the `PATH` variable's format), or in `PATH` when that is `None`; tests
/// inject an empty folder to check the "no ffmpeg" error.
#[derive(Clone, Debug)]
pub struct Tools {
    pub ffmpeg: OsString,
    pub ffprobe: OsString,
    pub search_path: Option<OsString>,
}

impl Default for Tools {
    fn default() -> Self {
        Tools {
            ffmpeg: "ffmpeg".into(),
            ffprobe: "ffprobe".into(),
            search_path: None,
        }
    }
}

impl Tools {
    /// The program's path, or `None` when it is not there.
    pub fn find(&self, program: &OsStr) -> Option<PathBuf> {
        let p = Path::new(program);
        if p.components().count() > 1 {
            return is_executable(p).then(|| p.to_path_buf());
        }
        let path = match &self.search_path {
            Some(s) => s.clone(),
            None => std::env::var_os("PATH")?,
        };
        std::env::split_paths(&path)
            .map(|d| d.join(p))
            .find(|c| is_executable(c))
    }
}

fn is_executable(p: &Path) -> bool {
    let Ok(m) = std::fs::metadata(p) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        m.is_file() && m.permissions().mode() & 0o111 != 0
    }
    #[cfg(not(unix))]
    {
        m.is_file()
    }
}

/// Decodes `video` into `out_dir` as `0001.png`, `0002.png`, ... with the `ffmpeg` program on
/// `PATH`; see [`decode_video_with`].
pub fn decode_video(video: &Path, out_dir: &Path) -> Result<Clip> {
    decode_video_with(video, out_dir, &Tools::default())
}

/// Where a decoded folder came from: a later run reuses the frames only when this matches.
fn source_stamp(video: &Path) -> Result<serde_json::Value> {
    let meta = std::fs::metadata(video).map_err(|e| Error::io(video, e))?;
    if meta.is_dir() {
        return Err(Error::bad_file(video, "not a video file (it is a folder)"));
    }
    if !meta.is_file() {
        // ffprobe and ffmpeg each read the video, and the stamp needs its size and time.
        return Err(Error::bad_file(
            video,
            "not a regular file (a pipe or device): a video is read twice (probed, then \
             decoded) and its size and time are kept to reuse the frames, so save the stream \
             to a file first",
        ));
    }
    let modified = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map(|d| d.as_nanos().to_string());
    let abs = std::fs::canonicalize(video).map_err(|e| Error::io(video, e))?;
    Ok(serde_json::json!({
        "video": abs.to_string_lossy(),
        "bytes": meta.len(),
        "modified_ns": modified,
    }))
}

/// Decodes `video` into `out_dir` as numbered PNG frames with `tools.ffmpeg`, reading the
/// frame rate with `tools.ffprobe` when that is there (otherwise `fps` is `None`).
///
/// The frames are decoded into a temporary folder beside `out_dir` and renamed into place
/// when complete, so a stopped run leaves no half-written folder. A folder decoded earlier
/// from the same file (same path, size and modification time, recorded in
/// [`DECODED_JSON`]) is reused as it is; any other non-empty `out_dir` is an error rather
/// than something to overwrite.
pub fn decode_video_with(video: &Path, out_dir: &Path, tools: &Tools) -> Result<Clip> {
    let stamp = source_stamp(video)?;
    if let Some(clip) = reuse_decoded(out_dir, &stamp)? {
        return Ok(clip);
    }
    let ffmpeg = tools.find(&tools.ffmpeg).ok_or_else(|| {
        Error::Invalid(format!(
            "cannot decode {}: the ffmpeg program ({}) was not found; {INSTALL_HINT}",
            video.display(),
            Path::new(&tools.ffmpeg).display()
        ))
    })?;

    let parent = match out_dir.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    crate::io::ensure_dir(parent)?;
    // Same parent as out_dir, so the final rename stays on one file system.
    let tmp = tempfile::Builder::new()
        .prefix(".coif-decode-")
        .tempdir_in(parent)
        .map_err(|e| Error::io(parent, e))?;
    let out = Command::new(&ffmpeg)
        .arg("-nostdin")
        .args(["-v", "error", "-i"])
        .arg(video)
        // One output picture per decoded frame: no duplicated or dropped frames to meet a
        // constant output rate. (-vsync rather than -fps_mode: ffmpeg 4 knows only -vsync.)
        .args(["-vsync", "passthrough"])
        .arg(tmp.path().join("%04d.png"))
        .output()
        .map_err(|e| Error::io(&ffmpeg, e))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        // ffmpeg's own words for a file without a video stream (audio only, say).
        let what = if stderr.contains("does not contain any stream") {
            "no video stream in this file"
        } else {
            "ffmpeg could not decode it"
        };
        return Err(Error::bad_file(
            video,
            format!("{what} ({}): {}", out.status, summarise(&stderr)),
        ));
    }
    let decoded = std::fs::read_dir(tmp.path())
        .map_err(|e| Error::io(tmp.path(), e))?
        .filter_map(|e| e.ok())
        .filter(|e| is_frame_image(&e.path()))
        .count();
    if decoded == 0 {
        let why = summarise(&String::from_utf8_lossy(&out.stderr));
        return Err(Error::bad_file(
            video,
            format!(
                "ffmpeg decoded zero frames: no video frames in this file{}",
                if why.is_empty() {
                    String::new()
                } else {
                    format!(" ({why})")
                }
            ),
        ));
    }
    let fps = tools
        .find(&tools.ffprobe)
        .and_then(|p| probe_fps(&p, video));
    let mut record = stamp;
    record["fps"] = serde_json::json!(fps);
    record["frames"] = serde_json::json!(decoded);
    crate::io::write_json(&tmp.path().join(DECODED_JSON), &record)?;

    // An empty out_dir (made by the caller) is replaced; reuse_decoded refused any other.
    if out_dir.is_dir() {
        std::fs::remove_dir(out_dir).map_err(|e| Error::io(out_dir, e))?;
    }
    let kept = tmp.keep();
    if let Err(e) = std::fs::rename(&kept, out_dir) {
        let _ = std::fs::remove_dir_all(&kept);
        return Err(Error::io(out_dir, e));
    }
    let mut clip = open_frames_dir(out_dir)?;
    clip.fps = fps;
    Ok(clip)
}

/// The clip in `out_dir` when it was decoded from the file `stamp` describes; `None` when
/// `out_dir` is absent or empty; an error when it holds anything else.
fn reuse_decoded(out_dir: &Path, stamp: &serde_json::Value) -> Result<Option<Clip>> {
    let mut entries = match std::fs::read_dir(out_dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(out_dir, e)),
    };
    if entries.next().is_none() {
        return Ok(None);
    }
    let record_path = out_dir.join(DECODED_JSON);
    let record: Option<serde_json::Value> = std::fs::read(&record_path)
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok());
    let same = record.as_ref().is_some_and(|r| {
        ["video", "bytes", "modified_ns"]
            .iter()
            .all(|k| r.get(k) == stamp.get(k))
    });
    if !same {
        return Err(Error::bad_file(
            out_dir,
            format!(
                "the output folder is not empty and was not decoded from {}; \
                 remove it or choose another",
                stamp["video"].as_str().unwrap_or("this video")
            ),
        ));
    }
    let mut clip = open_frames_dir(out_dir)?;
    let r = record.expect("checked above");
    if r.get("frames").and_then(|v| v.as_u64()) != Some(clip.len() as u64) {
        return Err(Error::bad_file(
            out_dir,
            format!(
                "{DECODED_JSON} records {} frames but the folder holds {}; remove the folder \
                 to decode again",
                r["frames"],
                clip.len()
            ),
        ));
    }
    clip.fps = r.get("fps").and_then(|v| v.as_f64()).map(|f| f as f32);
    Ok(Some(clip))
}

/// The last few lines of a program's error output, on one line and not too long.
fn summarise(stderr: &str) -> String {
    let lines: Vec<&str> = stderr
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let tail = lines[lines.len().saturating_sub(3)..].join(" | ");
    const MAX: usize = 400;
    if tail.len() > MAX {
        let mut cut = tail.len() - MAX;
        while !tail.is_char_boundary(cut) {
            cut += 1;
        }
        format!("...{}", &tail[cut..])
    } else {
        tail
    }
}

/// Frames per second of the first video stream, from ffprobe; `None` when it cannot tell.
fn probe_fps(ffprobe: &Path, video: &Path) -> Option<f32> {
    let out = Command::new(ffprobe)
        .args(["-v", "error", "-select_streams", "v:0"])
        .args(["-show_entries", "stream=avg_frame_rate,r_frame_rate"])
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(video)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let rate = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
            .and_then(parse_rate)
    };
    // The average rate is the true one for variable-rate files; r_frame_rate is a fallback.
    rate("avg_frame_rate").or_else(|| rate("r_frame_rate"))
}

/// "30000/1001" or "25" → frames per second; `None` for 0/0 and the like.
fn parse_rate(s: &str) -> Option<f32> {
    let s = s.trim();
    let v = match s.split_once('/') {
        Some((n, d)) => n.parse::<f64>().ok()? / d.parse::<f64>().ok()?,
        None => s.parse::<f64>().ok()?,
    };
    (v.is_finite() && v > 0.0).then_some(v as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates() {
        assert!((parse_rate("30000/1001").unwrap() - 29.97).abs() < 1e-2);
        assert_eq!(parse_rate("25"), Some(25.0));
        assert_eq!(parse_rate("0/0"), None);
        assert_eq!(parse_rate("N/A"), None);
    }

    #[test]
    fn summary_keeps_last_lines() {
        let s = summarise("a\n\n b \nc\nd\n");
        assert_eq!(s, "b | c | d");
    }
}

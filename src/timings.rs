//! Where a run's time goes, for `--timings FILE`: per-stage wall time, GPU time per pass
//! (when the adapter has timestamp queries) and the process's peak resident memory.
//!
//! Stages are recorded on the calling thread while [`collect`] runs: a pipeline marks a stage
//! with a [`stage`] span or hands over laps it already measured ([`record_all`]), without
//! passing a recorder through every signature. Only top-level stages count, so a span inside
//! another adds nothing and the stages never sum to more than the run. Stage names are
//! stable identifiers (lower case, `_`): users diff them across versions.

use crate::error::Result;
use crate::gpu::engine::Engine;
use serde::Serialize;
use serde_json::json;
use std::cell::RefCell;
use std::path::Path;
use std::time::Instant;

/// Version of the timings file (`schemas/timings.v1.schema.json`).
pub const FORMAT: &str = "coif-timings/1";

/// One stage's wall time, summed over its occurrences (a stage run once per frame counts
/// every frame).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stage {
    pub name: String,
    pub seconds: f64,
    pub count: u32,
}

#[derive(Default)]
struct Recorder {
    stages: Vec<Stage>,
    depth: u32,
}

thread_local! {
    static REC: RefCell<Option<Recorder>> = const { RefCell::new(None) };
}

/// Adds `seconds` to the stage `name` (merged with an earlier stage of that name).
fn push(stages: &mut Vec<Stage>, name: &str, seconds: f64, count: u32) {
    match stages.iter_mut().find(|s| s.name == name) {
        Some(s) => {
            s.seconds += seconds;
            s.count += count;
        }
        None => stages.push(Stage {
            name: name.to_string(),
            seconds,
            count,
        }),
    }
}

/// Runs `f` and returns what it returned with the top-level stages it recorded, in the order
/// they first ran. A `collect` inside another keeps its stages to itself.
pub fn collect<T>(f: impl FnOnce() -> T) -> (T, Vec<Stage>) {
    let outer = REC.with(|r| r.borrow_mut().replace(Recorder::default()));
    let out = f();
    let rec = REC.with(|r| std::mem::replace(&mut *r.borrow_mut(), outer));
    (out, rec.map(|r| r.stages).unwrap_or_default())
}

/// A stage that ends when the span is dropped.
#[must_use = "the stage ends when the span is dropped"]
pub struct Span {
    name: &'static str,
    start: Instant,
    active: bool,
}

/// Starts the stage `name`; nothing is recorded outside [`collect`] or inside another span.
pub fn stage(name: &'static str) -> Span {
    let active = REC.with(|r| match r.borrow_mut().as_mut() {
        Some(rec) => {
            rec.depth += 1;
            true
        }
        None => false,
    });
    Span {
        name,
        start: Instant::now(),
        active,
    }
}

impl Span {
    /// Runs `f` as the stage.
    pub fn run<T>(self, f: impl FnOnce() -> T) -> T {
        let out = f();
        drop(self);
        out
    }
}

impl Drop for Span {
    fn drop(&mut self) {
        if !self.active {
            return;
        }
        let seconds = self.start.elapsed().as_secs_f64();
        REC.with(|r| {
            if let Some(rec) = r.borrow_mut().as_mut() {
                rec.depth -= 1;
                if rec.depth == 0 {
                    push(&mut rec.stages, self.name, seconds, 1);
                }
            }
        });
    }
}

/// Records laps a pipeline measured itself (e.g. `Model::timings`), at the top level only.
pub fn record_all<S: AsRef<str>>(laps: &[(S, f64)]) {
    REC.with(|r| {
        if let Some(rec) = r.borrow_mut().as_mut().filter(|rec| rec.depth == 0) {
            for (name, s) in laps {
                push(&mut rec.stages, name.as_ref(), *s, 1);
            }
        }
    });
}

/// Records another run's stages as `<prefix>/<name>` (a job of a list, a step of a batch
/// job), at the top level only.
pub fn record_prefixed(prefix: &str, stages: &[Stage]) {
    REC.with(|r| {
        if let Some(rec) = r.borrow_mut().as_mut().filter(|rec| rec.depth == 0) {
            for s in stages {
                push(
                    &mut rec.stages,
                    &format!("{prefix}/{}", s.name),
                    s.seconds,
                    s.count,
                );
            }
        }
    });
}

/// Checks a `--timings` path before any work: a `.json` file whose folder exists (a wrong
/// type is a usage error, 64; a missing folder 74).
pub fn check_path(path: &Path) -> Result<()> {
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if !json || path.is_dir() {
        return Err(crate::error::Error::Invalid(format!(
            "--timings {}: expected a .json file to write",
            path.display()
        )));
    }
    crate::io::outpath::require_folder(path)
}

/// GPU time of one pass (a compute stage or a render pass), over every dispatch of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PassTime {
    pub name: String,
    pub dispatches: u32,
    pub seconds: f64,
}

/// What the file says about GPU time: measured per pass, or why there is none.
#[derive(Clone, Debug, PartialEq)]
pub enum GpuTime {
    Measured(Vec<PassTime>),
    /// No GPU timing, and why (the cpu backend; an adapter without timestamp queries).
    None(String),
}

impl GpuTime {
    /// The engine's pass times since the last call, or why there are none.
    pub fn take(engine: &Engine) -> GpuTime {
        match engine.gpu() {
            None => GpuTime::None("the cpu backend runs no GPU passes".into()),
            Some(g) if !g.has_timestamps() => GpuTime::None(format!(
                "the adapter {} has no timestamp queries (wgpu TIMESTAMP_QUERY)",
                g.info.name
            )),
            Some(g) => match g.take_pass_times() {
                Some(p) => GpuTime::Measured(p),
                None => GpuTime::None("passes were not timed".into()),
            },
        }
    }

    pub fn to_json(&self) -> serde_json::Value {
        match self {
            GpuTime::Measured(p) => json!({
                "status": "measured",
                "seconds": p.iter().map(|p| p.seconds).sum::<f64>(),
                "passes": p,
            }),
            GpuTime::None(why) => json!({ "status": "unavailable", "reason": why }),
        }
    }
}

/// Where the peak resident memory comes from, and over what span.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PeakScope {
    /// Since the process started.
    Process,
    /// Since the job started: [`reset_peak_rss`] reset the kernel's high-water mark.
    Job,
}

/// The process's peak resident set size in bytes: Linux's `VmHWM` (which
/// [`reset_peak_rss`] can reset), else `getrusage`'s `ru_maxrss`.
pub fn peak_rss_bytes() -> Option<u64> {
    if let Ok(s) = std::fs::read_to_string("/proc/self/status") {
        let kb = s
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok());
        if let Some(kb) = kb {
            return Some(kb * 1024);
        }
    }
    rusage_max_rss()
}

#[cfg(unix)]
fn rusage_max_rss() -> Option<u64> {
    // SAFETY: getrusage fills the zeroed struct it is given and reads nothing else.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return None;
    }
    // Kilobytes on Linux and the BSDs, bytes on macOS.
    let unit = if cfg!(target_os = "macos") { 1 } else { 1024 };
    u64::try_from(u.ru_maxrss).ok().map(|v| v * unit)
}

#[cfg(not(unix))]
fn rusage_max_rss() -> Option<u64> {
    None
}

/// Resets the kernel's peak-RSS mark to the current RSS (Linux: `5` into
/// `/proc/self/clear_refs`), so the next [`peak_rss_bytes`] is the peak of what ran since.
/// False where the kernel does not allow it: the peak is then the process's.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", b"5").is_ok()
}

/// One run's timings: stages, GPU time and peak memory.
#[derive(Clone, Debug)]
pub struct RunTimings {
    pub wall_seconds: f64,
    pub stages: Vec<Stage>,
    pub gpu: GpuTime,
    pub peak_rss_bytes: Option<u64>,
    pub peak_rss_scope: PeakScope,
}

impl RunTimings {
    /// The part of the file every run has (a batch job's entry in the summary too).
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "wall_seconds": self.wall_seconds,
            "stages": self.stages,
            "gpu_time": self.gpu.to_json(),
            "peak_rss_bytes": self.peak_rss_bytes,
            "peak_rss_scope": self.peak_rss_scope,
        })
    }
}

/// The backend part of the file: `cpu` or `gpu` with the adapter and whether it has
/// timestamp queries.
pub fn backend_json(engine: &Engine) -> serde_json::Value {
    match engine.gpu() {
        None => json!({ "kind": "cpu", "threads": rayon::current_num_threads() }),
        Some(g) => json!({
            "kind": "gpu",
            "adapter": crate::gpu::describe(&g.info),
            "timestamp_queries": g.has_timestamps(),
        }),
    }
}

/// Writes the timings file of `command` (atomically).
pub fn write(path: &Path, command: &str, engine: &Engine, t: &RunTimings) -> Result<()> {
    let mut v = json!({
        "format": FORMAT,
        "coif_version": env!("CARGO_PKG_VERSION"),
        "command": command,
        "backend": backend_json(engine),
    });
    if let (Some(o), serde_json::Value::Object(rest)) = (v.as_object_mut(), t.to_json()) {
        o.extend(rest);
    }
    crate::io::write_json(path, &v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_spans_and_laps_inside_spans_are_not_counted_twice() {
        let ((), stages) = collect(|| {
            {
                let _a = stage("a");
                let _b = stage("b");
                record_all(&[("c", 1.0)]);
            }
            record_all(&[("d", 2.0), ("d", 3.0)]);
            let _a = stage("a");
        });
        let names: Vec<_> = stages.iter().map(|s| (s.name.as_str(), s.count)).collect();
        assert_eq!(names, [("a", 2), ("d", 2)]);
        assert_eq!(stages[1].seconds, 5.0);
    }

    #[test]
    fn nothing_is_recorded_outside_collect_and_an_inner_collect_keeps_its_own() {
        record_all(&[("x", 1.0)]);
        let _s = stage("y");
        let (inner, outer) = collect(|| {
            let _o = stage("outer");
            let ((), inner) = collect(|| record_all(&[("inner", 1.0)]));
            inner
        });
        assert_eq!(inner.len(), 1);
        assert_eq!(inner[0].name, "inner");
        assert_eq!(outer.len(), 1);
        assert_eq!(outer[0].name, "outer");
    }

    #[test]
    fn peak_rss_covers_a_touched_allocation() {
        // Other tests run alongside: only a lower bound holds.
        let v = vec![1u8; 64 << 20];
        std::hint::black_box(&v);
        let peak = peak_rss_bytes().expect("Linux reports VmHWM");
        assert!(peak >= 64 << 20, "{peak}");
        assert!(rusage_max_rss().unwrap() >= 64 << 20);
    }
}

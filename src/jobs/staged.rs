//! How a job meets the file system: a job that writes a folder runs into a temporary folder
//! that is put in place only when the whole run succeeded ([`crate::io::txn`]); a job that
//! writes one file has its path checked before work and writes it atomically. Every job
//! starts at a signal check, so `coif demo` and batches stop between jobs.

use super::{run_here, Job, Report};
use crate::gpu::engine::Engine;
use crate::hair::scene::Scene;
use crate::io::{outpath, txn};
use std::path::{Path, PathBuf};

impl Job {
    /// The folder a job writes as one unit, if it writes one. `coif video` writes its folder
    /// in place on purpose: it resumes from the frames a stopped run wrote (`progress.json`).
    /// A render writes a folder only for a moving scene, which it learns from the model
    /// ([`super::render_frames`] makes its own transaction).
    fn folder_out(&self) -> Option<&Path> {
        match self {
            Job::Synth(j) => Some(&j.out),
            Job::SynthVideo(j) => Some(&j.out),
            Job::Unpack(j) => Some(&j.out),
            Job::Orient(j) => Some(&j.out),
            Job::Analyze(j) => Some(&j.out),
            Job::Model(j) => Some(&j.out),
            Job::Simulate(j) => Some(&j.out),
            Job::Edit(j) => Some(&j.out),
            Job::Import(j) => Some(&j.out),
            Job::Transfer(j) => Some(&j.out),
            Job::Sketch(j) => Some(&j.out),
            _ => None,
        }
    }

    /// The job writing into `dir` instead of its folder.
    fn into_folder(mut self, dir: &Path) -> Job {
        let out = match &mut self {
            Job::Synth(j) => &mut j.out,
            Job::SynthVideo(j) => &mut j.out,
            Job::Unpack(j) => &mut j.out,
            Job::Orient(j) => &mut j.out,
            Job::Analyze(j) => &mut j.out,
            Job::Model(j) => &mut j.out,
            Job::Simulate(j) => &mut j.out,
            Job::Edit(j) => &mut j.out,
            Job::Import(j) => &mut j.out,
            Job::Transfer(j) => &mut j.out,
            Job::Sketch(j) => &mut j.out,
            _ => unreachable!("only jobs with a folder_out"),
        };
        *out = dir.to_path_buf();
        self
    }

    /// Checks of a single output file the job's own run does not make before its work.
    fn check_file_out(&self) -> crate::Result<()> {
        match self {
            Job::Export(j) => {
                let inputs = Scene::inputs(&j.model);
                let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
                outpath::check_file(&j.to, &inputs)
            }
            Job::Convert(j) => outpath::check_file(&j.output, &[&j.input]),
            Job::SketchConvert(j) => outpath::check_file(&j.out, &[&j.input]),
            Job::SketchEdit(j) => outpath::check_file(&j.out, &[&j.input]),
            _ => Ok(()),
        }
    }

    /// The file a job writes alone (its folder is where its stale temporaries would be).
    fn file_out(&self) -> Option<&Path> {
        match self {
            Job::Render(j) => Some(&j.out),
            Job::Export(j) => Some(&j.to),
            Job::Convert(j) => Some(&j.output),
            Job::SketchConvert(j) => Some(&j.out),
            Job::SynthHair(j) => Some(&j.out),
            Job::Cartoon(j) => Some(&j.out),
            Job::SketchEdit(j) => Some(&j.out),
            _ => None,
        }
    }
}

impl Report {
    /// The report with the temporary folder's path written as the folder it became.
    pub fn relabel(mut self, from: &Path, to: &Path) -> Report {
        let (from, to) = (from.display().to_string(), to.display().to_string());
        let fix = |s: &mut String| {
            if s.contains(&from) {
                *s = s.replace(&from, &to);
            }
        };
        fix(&mut self.summary);
        self.details.iter_mut().for_each(fix);
        self.warnings.iter_mut().for_each(fix);
        self
    }
}

pub(super) fn run(engine: &Engine, job: &Job) -> anyhow::Result<Report> {
    crate::interrupt::check()?;
    if let Job::Video(j) = job {
        // In place (see folder_out), but still one run at a time.
        txn::require_folder_or_absent(&j.out)?;
        let _lock = txn::lock_folder(&j.out)?;
        return run_here(engine, job);
    }
    let Some(out) = job.folder_out() else {
        job.check_file_out()?;
        if let Some(f) = job.file_out() {
            let dir = match f.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            txn::clean_stale(dir, None)?;
        }
        return run_here(engine, job);
    };
    let t = txn::Txn::begin(out)?;
    let tmp = t.dir().to_path_buf();
    let r = run_here(engine, &job.clone().into_folder(&tmp))?;
    // The last boundary: a signal before here discards the run, after it the run is done.
    crate::interrupt::check()?;
    t.commit()?;
    Ok(r.relabel(&tmp, out))
}

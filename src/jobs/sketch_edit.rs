//! `coif sketch-edit`: a sketch file in, edits applied ([`crate::sketch::edit`]), a sketch
//! file out, one line per change printed.

use super::Report;
use crate::error::Error;
use crate::sketch::edit::{apply_logged, curves_from_file, Edit};
use crate::sketch::{format, Kind};
use std::path::PathBuf;

/// One requested edit: a ready [`Edit`], or curves to read from a file (they take the
/// input sketch's median contrast when drawn, so they are resolved once it is loaded).
#[derive(Clone, Debug)]
pub enum EditStep {
    Edit(Edit),
    /// `--add file[:TYPE]`.
    AddFile(PathBuf, Option<Kind>),
}

/// Edits of a sketch (`coif sketch-edit`).
#[derive(Clone, Debug)]
pub struct SketchEditJob {
    pub input: PathBuf,
    pub out: PathBuf,
    /// Applied in this order, each on the sketch the previous ones left.
    pub steps: Vec<EditStep>,
}

pub(super) fn run_sketch_edit(j: &SketchEditJob) -> anyhow::Result<Report> {
    let s = format::load(&j.input)?;
    if !j.steps.iter().any(|st| matches!(st, EditStep::AddFile(..))) {
        // Nothing will be added: a sketch without curves stays one.
        format::require_curves(&s, &j.input)?;
    }
    let mut edits = Vec::new();
    let mut details = Vec::new();
    for st in &j.steps {
        match st {
            EditStep::Edit(e) => edits.push(e.clone()),
            EditStep::AddFile(p, kind) => {
                for (c, worst) in curves_from_file(p, *kind, &s)? {
                    if worst > 0.0 {
                        details.push(format!(
                            "{}: a {}-primitive curve within {worst:.1} px of the drawn line",
                            p.display(),
                            c.prims.len()
                        ));
                    }
                    edits.push(Edit::Add(c));
                }
            }
        }
    }
    if edits.is_empty() {
        return Err(Error::Invalid(
            "coif sketch-edit needs at least one edit (--delete, --flip, --move, --add, \
             --contrast, --base, --delete-base, --add-base); to convert a sketch use coif \
             sketch-convert"
                .into(),
        )
        .into());
    }
    let (q, log) = apply_logged(&s, &edits).map_err(|e| match e {
        Error::Invalid(m) => Error::Invalid(format!("{}: {m}", j.input.display())),
        e => e,
    })?;
    if q.curves.is_empty() {
        // Synthesis, the cartoon and the field are drawn from the curves.
        format::require_curves(&s, &j.input)?;
        return Err(Error::Invalid(format!(
            "{}: the edits delete every curve; a sketch needs at least one",
            j.input.display()
        ))
        .into());
    }
    format::save(&q, &j.out)?;
    let mut lines = log;
    lines.extend(details);
    Ok(Report {
        summary: format!(
            "sketch-edit: {} -> {}: {} edits ({} curves, {} primitives, {} bases; {} B as .czs)",
            j.input.display(),
            j.out.display(),
            edits.len(),
            q.curves.len(),
            q.curves.iter().map(|c| c.prims.len()).sum::<usize>(),
            q.shading.bases.len(),
            format::to_czs(&q).len()
        ),
        details: lines,
        ..Default::default()
    })
}

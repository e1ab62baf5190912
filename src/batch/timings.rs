//! Each batch job's timings (its steps' stages as `<step>/<stage>`, GPU time per pass, peak
//! memory) and their aggregate over the completed jobs, for the summary and `--timings`.

use crate::timings::{GpuTime, PassTime, RunTimings, Stage};
use serde::Serialize;
use std::collections::BTreeMap;

/// One stage (or GPU pass) over the jobs that ran it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Aggregate {
    pub name: String,
    /// Jobs that ran it.
    pub jobs: u32,
    pub total_seconds: f64,
    pub mean_seconds: f64,
    pub max_seconds: f64,
}

/// The summary's `timings`: every stage and GPU pass over the completed jobs, and the largest
/// peak memory of a job.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BatchTimings {
    /// Completed jobs aggregated.
    pub jobs: u32,
    pub stages: Vec<Aggregate>,
    pub gpu_passes: Vec<Aggregate>,
    pub peak_rss_bytes_max: Option<u64>,
}

/// Totals in the order names first appear, so the summary lists stages as they ran.
fn aggregate<'a>(per_job: impl Iterator<Item = Vec<(&'a str, f64)>>) -> Vec<Aggregate> {
    let mut order: Vec<String> = Vec::new();
    let mut by: BTreeMap<String, (u32, f64, f64)> = BTreeMap::new();
    for job in per_job {
        // A name twice in one job (it cannot be: stages are merged by name) would count the
        // job twice; merge first anyway.
        let mut merged: Vec<(&str, f64)> = Vec::new();
        for (n, s) in job {
            match merged.iter_mut().find(|m| m.0 == n) {
                Some(m) => m.1 += s,
                None => merged.push((n, s)),
            }
        }
        for (n, s) in merged {
            let e = by.entry(n.to_string()).or_insert_with(|| {
                order.push(n.to_string());
                (0, 0.0, 0.0)
            });
            e.0 += 1;
            e.1 += s;
            e.2 = e.2.max(s);
        }
    }
    order
        .into_iter()
        .map(|name| {
            let (jobs, total, max) = by[&name];
            Aggregate {
                name,
                jobs,
                total_seconds: total,
                mean_seconds: total / f64::from(jobs),
                max_seconds: max,
            }
        })
        .collect()
}

impl BatchTimings {
    /// The aggregate of the completed jobs' timings.
    pub fn of(jobs: &[&RunTimings]) -> BatchTimings {
        let stages = aggregate(jobs.iter().map(|t| {
            t.stages
                .iter()
                .map(|s| (s.name.as_str(), s.seconds))
                .collect()
        }));
        let gpu_passes = aggregate(jobs.iter().map(|t| match &t.gpu {
            GpuTime::Measured(p) => p.iter().map(|p| (p.name.as_str(), p.seconds)).collect(),
            GpuTime::None(_) => Vec::new(),
        }));
        BatchTimings {
            jobs: jobs.len() as u32,
            stages,
            gpu_passes,
            peak_rss_bytes_max: jobs.iter().filter_map(|t| t.peak_rss_bytes).max(),
        }
    }

    /// The batch's own `--timings` stages: each stage's total over the jobs.
    pub fn stage_totals(&self) -> Vec<Stage> {
        self.stages
            .iter()
            .map(|a| Stage {
                name: a.name.clone(),
                seconds: a.total_seconds,
                count: a.jobs,
            })
            .collect()
    }
}

/// The GPU pass totals of several jobs, for the batch's own `--timings` file; None when no
/// job measured any.
pub fn pass_totals(jobs: &[&RunTimings]) -> Option<Vec<PassTime>> {
    let mut by: BTreeMap<String, (u32, f64)> = BTreeMap::new();
    let mut any = false;
    for t in jobs {
        if let GpuTime::Measured(p) = &t.gpu {
            any = true;
            for p in p {
                let e = by.entry(p.name.clone()).or_default();
                e.0 += p.dispatches;
                e.1 += p.seconds;
            }
        }
    }
    any.then(|| {
        by.into_iter()
            .map(|(name, (dispatches, seconds))| PassTime {
                name,
                dispatches,
                seconds,
            })
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timings::PeakScope;

    fn run(stages: &[(&str, f64)], peak: u64) -> RunTimings {
        RunTimings {
            wall_seconds: stages.iter().map(|s| s.1).sum(),
            stages: stages
                .iter()
                .map(|(n, s)| Stage {
                    name: n.to_string(),
                    seconds: *s,
                    count: 1,
                })
                .collect(),
            gpu: GpuTime::None("cpu".into()),
            peak_rss_bytes: Some(peak),
            peak_rss_scope: PeakScope::Process,
        }
    }

    #[test]
    fn totals_means_and_maxima_over_the_jobs_that_ran_each_stage() {
        let a = run(&[("orient/read", 1.0), ("orient/orientation", 4.0)], 10);
        let b = run(&[("orient/read", 3.0), ("model/growth", 2.0)], 30);
        let t = BatchTimings::of(&[&a, &b]);
        let names: Vec<_> = t.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["orient/read", "orient/orientation", "model/growth"]);
        let read = &t.stages[0];
        assert_eq!(
            (
                read.jobs,
                read.total_seconds,
                read.mean_seconds,
                read.max_seconds
            ),
            (2, 4.0, 2.0, 3.0)
        );
        assert_eq!(t.stages[2].jobs, 1);
        assert_eq!(t.peak_rss_bytes_max, Some(30));
        assert!(t.gpu_passes.is_empty());
        assert_eq!(pass_totals(&[&a, &b]), None);
    }
}

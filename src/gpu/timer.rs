//! GPU time per pass from timestamp queries (wgpu `TIMESTAMP_QUERY`): each timed pass writes
//! a timestamp at its beginning and end; after the submission the pairs are resolved, read
//! back and added to the context's totals by pass label.

use super::GpuContext;
use crate::error::{Error, Result};
use crate::timings::PassTime;
use std::collections::BTreeMap;

/// Pass totals by label: dispatches and seconds.
#[derive(Default)]
pub struct PassTotals(BTreeMap<String, (u32, f64)>);

impl PassTotals {
    pub fn into_list(self) -> Vec<PassTime> {
        self.0
            .into_iter()
            .map(|(name, (dispatches, seconds))| PassTime {
                name,
                dispatches,
                seconds,
            })
            .collect()
    }
}

/// Timestamp slots for the passes of one submission.
pub struct PassQueries {
    sets: Vec<wgpu::QuerySet>,
    labels: Vec<&'static str>,
    staging: Vec<wgpu::Buffer>,
}

/// Two timestamps per pass; a query set holds at most `QUERY_SET_MAX_QUERIES`.
const PASSES_PER_SET: u32 = wgpu::QUERY_SET_MAX_QUERIES / 2;

impl PassQueries {
    /// Slots for `passes` passes, or None when the context is not timing passes.
    pub fn new(g: &GpuContext, passes: usize) -> Option<PassQueries> {
        if passes == 0 || !g.timing_passes() {
            return None;
        }
        let n_sets = (passes as u32).div_ceil(PASSES_PER_SET);
        let sets = (0..n_sets)
            .map(|k| {
                let count = 2 * (passes as u32 - k * PASSES_PER_SET).min(PASSES_PER_SET);
                g.device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("coif.timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count,
                })
            })
            .collect();
        Some(PassQueries {
            sets,
            labels: Vec::with_capacity(passes),
            staging: Vec::new(),
        })
    }

    /// The next pass's slots, labelled `label`.
    fn next(&mut self, label: &'static str) -> (&wgpu::QuerySet, u32) {
        let k = self.labels.len() as u32;
        self.labels.push(label);
        let set = &self.sets[(k / PASSES_PER_SET) as usize];
        (set, 2 * (k % PASSES_PER_SET))
    }

    pub fn compute(&mut self, label: &'static str) -> wgpu::ComputePassTimestampWrites<'_> {
        let (query_set, i) = self.next(label);
        wgpu::ComputePassTimestampWrites {
            query_set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        }
    }

    pub fn render(&mut self, label: &'static str) -> wgpu::RenderPassTimestampWrites<'_> {
        let (query_set, i) = self.next(label);
        wgpu::RenderPassTimestampWrites {
            query_set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        }
    }

    /// Resolves the written slots into buffers the host can read after the submission.
    pub fn resolve(&mut self, g: &GpuContext, encoder: &mut wgpu::CommandEncoder) {
        let used = 2 * self.labels.len() as u32;
        for (k, set) in self.sets.iter().enumerate() {
            let count = (used - (k as u32 * 2 * PASSES_PER_SET)).min(2 * PASSES_PER_SET);
            let bytes = u64::from(count) * u64::from(wgpu::QUERY_SIZE);
            let buffer = |label, usage| {
                g.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage,
                    mapped_at_creation: false,
                })
            };
            let resolved = buffer(
                "coif.timestamps.resolve",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            );
            let staging = buffer(
                "coif.timestamps.read",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            );
            encoder.resolve_query_set(set, 0..count, &resolved, 0);
            // The resolve buffer lives on in the command buffer until it has run.
            encoder.copy_buffer_to_buffer(&resolved, 0, &staging, 0, bytes);
            self.staging.push(staging);
        }
    }

    /// Asks for the read-back; call after the submission and before the device poll.
    pub fn map(&self) {
        for st in &self.staging {
            st.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
    }

    /// Adds each pass's time to the context's totals; call after the device poll.
    pub fn finish(self, g: &GpuContext) -> Result<()> {
        let period_ns = f64::from(g.queue.get_timestamp_period());
        let mut ticks: Vec<u64> = Vec::with_capacity(2 * self.labels.len());
        for st in &self.staging {
            let view = st
                .slice(..)
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("cannot map the timestamps: {e}")))?;
            ticks.extend_from_slice(bytemuck::cast_slice(&view[..]));
        }
        g.add_pass_times(self.labels.iter().zip(ticks.chunks_exact(2)).map(|(l, t)| {
            // A pass whose end is before its beginning (a timer wrap) counts as zero.
            (*l, t[1].saturating_sub(t[0]) as f64 * period_ns * 1e-9)
        }));
        Ok(())
    }
}

impl PassTotals {
    pub fn add(&mut self, label: &str, seconds: f64) {
        let e = self.0.entry(label.to_string()).or_default();
        e.0 += 1;
        e.1 += seconds;
    }
}

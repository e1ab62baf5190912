//! The one strand container: polylines root → tip with optional per-vertex attributes. Grid
//! space (modelling), image space (previews) and model space (files, render, simulation) are
//! views of the same type; the files it is read from and written to are in
//! [`crate::io::strands`].

use crate::error::{Error, Result};

/// A strand model: strands are polylines root→tip; per-vertex optional attributes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StrandSet {
    /// All vertices, strand after strand.
    pub points: Vec<[f32; 3]>,
    /// Vertices per strand (each >= 1; a 1-vertex strand is an empty root).
    pub counts: Vec<u32>,
    /// Per vertex, in the file's length unit (USD `widths`, i.e. a diameter).
    pub thickness: Option<Vec<f32>>,
    /// Per vertex, 0 opaque .. 1 fully transparent (cyHair's convention).
    pub transparency: Option<Vec<f32>>,
    /// Per vertex, linear 0..1.
    pub colors: Option<Vec<[f32; 3]>>,
}

impl StrandSet {
    /// A set with points and counts only.
    pub fn new(points: Vec<[f32; 3]>, counts: Vec<u32>) -> Self {
        StrandSet {
            points,
            counts,
            ..Default::default()
        }
    }

    /// Number of strands.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The vertices of strand `i`. O(i): use [`StrandSet::strands`] to visit them all.
    ///
    /// # Panics
    /// If `i` is out of range or the counts exceed the points (see [`StrandSet::validate`]).
    pub fn strand(&self, i: usize) -> &[[f32; 3]] {
        let start: usize = self.counts[..i].iter().map(|&c| c as usize).sum();
        &self.points[start..start + self.counts[i] as usize]
    }

    /// Iterates the strands in order. Stops early if the counts exceed the points.
    pub fn strands(&self) -> impl Iterator<Item = &[[f32; 3]]> + '_ {
        let mut start = 0usize;
        self.counts.iter().map_while(move |&c| {
            let s = self.points.get(start..start + c as usize)?;
            start += c as usize;
            Some(s)
        })
    }

    /// Where each strand starts in `points`, plus the end: strand `i` is
    /// `points[o[i]..o[i + 1]]`. Built once by stages that visit strands out of order.
    pub fn offsets(&self) -> Vec<usize> {
        let mut o = Vec::with_capacity(self.counts.len() + 1);
        o.push(0);
        for &c in &self.counts {
            o.push(o[o.len() - 1] + c as usize);
        }
        o
    }

    /// Appends a strand without attributes (sets that carry attributes are built whole).
    pub fn push(&mut self, verts: &[[f32; 3]]) {
        self.points.extend_from_slice(verts);
        self.counts.push(verts.len() as u32);
    }

    /// Checks only that the counts add up to the points: the invariant the modelling stages
    /// keep while a set is being grown (it may be empty, and a strand may have no vertex).
    pub fn check_packing(&self) -> Result<()> {
        let total: u64 = self.counts.iter().map(|&c| u64::from(c)).sum();
        if total != self.points.len() as u64 {
            return Err(Error::Invalid(format!(
                "strand vertex counts sum to {total} but there are {} points",
                self.points.len()
            )));
        }
        Ok(())
    }

    /// Checks that the set is usable: at least one strand, every count >= 1, counts summing
    /// to the number of points, per-vertex attributes of that length, all values finite.
    pub fn validate(&self) -> Result<()> {
        self.check().map_err(Error::Invalid)
    }

    /// [`StrandSet::validate`] with a bare message, so readers and writers can name their file.
    pub(crate) fn check(&self) -> std::result::Result<(), String> {
        if self.counts.is_empty() {
            return Err("zero strands".into());
        }
        let mut total = 0u64;
        for (i, &c) in self.counts.iter().enumerate() {
            if c == 0 {
                return Err(format!("strand {i} has no vertices"));
            }
            total += u64::from(c);
        }
        if total != self.points.len() as u64 {
            return Err(format!(
                "strand vertex counts sum to {total} but there are {} points",
                self.points.len()
            ));
        }
        let n = self.points.len();
        if let Some(i) = self.points.iter().position(|p| !finite3(p)) {
            return Err(format!("point {i} is not finite: {:?}", self.points[i]));
        }
        fn attr<T>(
            name: &str,
            v: &Option<Vec<T>>,
            n: usize,
            ok: impl Fn(&T) -> bool,
        ) -> std::result::Result<(), String> {
            let Some(v) = v else { return Ok(()) };
            if v.len() != n {
                return Err(format!("{name} has {} values for {n} points", v.len()));
            }
            match v.iter().position(|x| !ok(x)) {
                Some(i) => Err(format!("{name} of point {i} is not finite")),
                None => Ok(()),
            }
        }
        attr("thickness", &self.thickness, n, |x| x.is_finite())?;
        attr("transparency", &self.transparency, n, |x| x.is_finite())?;
        attr("colors", &self.colors, n, finite3)
    }

    /// Axis-aligned bounds of the points as (min, max); zeros for a set without points.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        if self.points.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

fn finite3(p: &[f32; 3]) -> bool {
    p.iter().all(|x| x.is_finite())
}

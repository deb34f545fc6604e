//! [`SkipRuns`]: the samples of a ray cut into runs that are empty or lie in
//! one occupied macrocell, as a renderer's integrator consumes them.
//!
//! This is the one place where a ray walks the skip grid: an integrator asks
//! for the runs of its sample range and decides per run what to do (skip an
//! empty run, composite a uniform cell in closed form, march sample by
//! sample, skip a cell whose range cannot change the result).

use super::SkipGrid;
use super::skip::CellClass;
use crate::integrator::RaySegment;

/// What a run of samples lies in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    /// Empty space: no sample of the run contributes.
    Empty,
    /// One occupied macrocell (its index in the macrocell grid).
    Cell(usize),
    /// Skipping is off: nothing is known about the samples.
    Unknown,
}

/// Samples `start..end` of a ray, all of one [`RunKind`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleRun {
    /// First sample index.
    pub start: u32,
    /// One past the last sample index. For an empty run it is the first
    /// sample after the empty box, which may lie past the range asked for;
    /// other runs end within the range.
    pub end: u32,
    /// What the samples lie in.
    pub kind: RunKind,
}

/// The runs of samples `k0..k1` of a ray (see [`SkipRuns::new`]).
#[derive(Debug, Clone)]
pub struct SkipRuns<'a> {
    skip: Option<&'a SkipGrid>,
    seg: &'a RaySegment,
    k: u32,
    k1: u32,
}

impl<'a> SkipRuns<'a> {
    /// The runs of samples `k0..k1` of `seg` (clamped to the ray's kept
    /// samples `first..count`) by `skip`,
    /// or, with `None`, one run of [`RunKind::Unknown`].
    #[inline(always)]
    pub fn new(skip: Option<&'a SkipGrid>, seg: &'a RaySegment, k0: u32, k1: u32) -> Self {
        SkipRuns {
            skip,
            seg,
            k: k0.max(seg.first),
            k1: k1.min(seg.count),
        }
    }
}

impl Iterator for SkipRuns<'_> {
    type Item = SampleRun;

    #[inline(always)]
    fn next(&mut self) -> Option<SampleRun> {
        let (k, seg) = (self.k, self.seg);
        if k >= self.k1 {
            return None;
        }
        let Some(skip) = self.skip else {
            self.k = self.k1;
            return Some(SampleRun {
                start: k,
                end: self.k1,
                kind: RunKind::Unknown,
            });
        };
        // The run ends at the first sample at or after the box's exit
        // (possibly one early, never late: see `first_index_at_or_after`),
        // and always advances.
        let (bounds, kind) = match skip.classify(seg.pos(k)) {
            CellClass::Occupied { bounds, index, .. } => (bounds, RunKind::Cell(index)),
            CellClass::Empty(bounds) => (bounds, RunKind::Empty),
        };
        let mut end = seg
            .first_index_at_or_after(bounds.exit(seg.origin, seg.inv_dir))
            .max(k + 1);
        if kind != RunKind::Empty {
            end = end.min(self.k1);
        }
        self.k = end;
        Some(SampleRun {
            start: k,
            end,
            kind,
        })
    }
}

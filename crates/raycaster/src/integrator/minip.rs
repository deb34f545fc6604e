//! Minimum intensity projection: [`MipState`](super::MipState) with the
//! minimum.
//!
//! Skipping: a macrocell's samples are interpolated from its voxels, so none
//! of them lies below the cell's smallest value; a cell whose smallest value
//! is not below the running minimum cannot lower it and is jumped over.
//! Nothing else may be skipped (every cell is occupied for a minimum, as for
//! a maximum), except clipped space, which the skip grid marks empty.

use glam::Vec4;

use super::batch::fold_values;
use super::{FrameContext, Integrator, Span};
use crate::accel::RunKind;
use crate::volume::Volume;

/// Running minimum of a ray.
#[derive(Debug, Clone, Copy)]
pub struct MinipState {
    /// Smallest interpolated value so far (+∞ before the first sample).
    pub min: f32,
}

impl Default for MinipState {
    fn default() -> Self {
        MinipState { min: f32::INFINITY }
    }
}

impl Integrator for MinipState {
    /// Folds the span's samples into the minimum, skipping with ESS the
    /// macrocells whose smallest value cannot lower it.
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let mut taken = 0u64;
        for run in span.runs() {
            if let RunKind::Cell(i) = run.kind
                && ctx.macrocells.ranges[i].0 >= self.min
            {
                continue;
            }
            if run.kind == RunKind::Empty {
                continue;
            }
            self.min = fold_values(ctx.volume, seg, run.start, run.end, self.min, f32::min);
            taken += (run.end - run.start) as u64;
        }
        taken
    }

    /// `C = a·c, A = a` of the TF at the minimum (no step correction).
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        if self.min == f32::INFINITY {
            return Vec4::ZERO;
        }
        let e = ctx.tf.evaluate(self.min);
        (e.truncate() * e.w).extend(e.w)
    }
}

//! Maximum intensity projection.

use glam::Vec4;

use super::batch::fold_values;
use super::{FrameContext, Integrator, Span};
use crate::accel::RunKind;
use crate::volume::Volume;

/// Running maximum of a ray.
#[derive(Debug, Clone, Copy)]
pub struct MipState {
    /// Largest interpolated value so far (−∞ before the first sample).
    pub max: f32,
}

impl Default for MipState {
    fn default() -> Self {
        MipState {
            max: f32::NEG_INFINITY,
        }
    }
}

impl Integrator for MipState {
    /// Folds the span's samples into the maximum. With ESS, macrocells
    /// whose largest value cannot raise the maximum are jumped over (every
    /// cell is occupied for MIP: the running maximum decides).
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let mut taken = 0u64;
        for run in span.runs() {
            if let RunKind::Cell(i) = run.kind
                && ctx.macrocells.ranges[i].1 <= self.max
            {
                continue;
            }
            if run.kind == RunKind::Empty {
                continue;
            }
            self.max = fold_values(ctx.volume, seg, run.start, run.end, self.max, f32::max);
            taken += (run.end - run.start) as u64;
        }
        taken
    }

    /// `C = a·c, A = a` of the TF at the maximum (no step correction).
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        if self.max == f32::NEG_INFINITY {
            return Vec4::ZERO;
        }
        let e = ctx.tf.evaluate(self.max);
        (e.truncate() * e.w).extend(e.w)
    }
}

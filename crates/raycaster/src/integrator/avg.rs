//! The mean value along a ray ("x-ray").

use glam::{Vec3, Vec4};

use super::batch::fold_values;
use super::{Fragment, FrameContext, Integrator, Span};
use crate::volume::Volume;

/// Running sum and count.
#[derive(Debug, Clone, Copy, Default)]
pub struct AvgState {
    /// Sum of interpolated values (f64: long rays through big volumes).
    pub sum: f64,
    /// Number of samples.
    pub count: u64,
}

impl Integrator for AvgState {
    type Scratch = ();

    /// Adds the span's samples. Every kept sample counts, so nothing is
    /// skipped (clipped samples are outside `first..count`).
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (k0, k1) = (span.start.max(span.seg.first), span.end.min(span.seg.count));
        let sum = fold_values(span.ctx.volume, span.seg, k0, k1, 0.0f32, |s, v| s + v);
        let n = k1.saturating_sub(k0) as u64;
        self.sum += sum as f64;
        self.count += n;
        n
    }

    /// Grey `mean / max` with `A = 1` when the ray had any sample.
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        Self::colour(self.sum, self.count, ctx.avg_norm)
    }

    /// The sum and the count.
    fn fragment<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Fragment {
        Fragment {
            value: self.sum as f32,
            count: self.count as u32,
            ..Fragment::default()
        }
    }
}

impl AvgState {
    /// Grey `mean / norm` with `A = 1` for `count > 0` samples summing to
    /// `sum`, else transparent.
    pub fn colour(sum: f64, count: u64, norm: f32) -> Vec4 {
        if count == 0 {
            return Vec4::ZERO;
        }
        let g = (sum / count as f64) as f32 / norm;
        Vec3::splat(g).extend(1.0)
    }
}

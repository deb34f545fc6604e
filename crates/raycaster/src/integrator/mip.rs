//! Maximum intensity projection.

use glam::Vec4;

use super::{FrameContext, RaySegment};
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

impl MipState {
    /// Folds samples `k0..k1` into the maximum. With ESS, macrocells whose
    /// largest value cannot raise the maximum are jumped over.
    #[inline]
    pub fn integrate<V: Volume>(
        &mut self,
        ctx: &FrameContext<'_, V>,
        seg: &RaySegment,
        k0: u32,
        k1: u32,
    ) -> u64 {
        let k1 = k1.min(seg.count);
        let mut taken = 0u64;
        let mut k = k0;
        let cells = ctx.macrocells;
        let m = cells.cell as f32;
        while k < k1 {
            let run_end = if ctx.ess {
                let p = seg.pos(k);
                let c = cells.cell_of(p);
                let lo = c.as_vec3() * m;
                let t_exit = crate::geometry::Aabb::new(lo, lo + glam::Vec3::splat(m))
                    .exit(seg.origin, seg.inv_dir);
                let next = seg.first_index_at_or_after(t_exit).max(k + 1);
                if cells.ranges[cells.index(c)].1 <= self.max {
                    k = next;
                    continue;
                }
                next.min(k1)
            } else {
                k1
            };
            while k < run_end {
                let v = ctx.volume.sample(seg.pos(k));
                taken += 1;
                k += 1;
                self.max = self.max.max(v);
            }
        }
        taken
    }

    /// `C = a·c, A = a` of the TF at the maximum (no step correction).
    pub fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        if self.max == f32::NEG_INFINITY {
            return Vec4::ZERO;
        }
        let e = ctx.tf.evaluate(self.max);
        (e.truncate() * e.w).extend(e.w)
    }
}

//! Direct volume rendering: front-to-back compositing with ERT and ESS.

use glam::Vec3;

use super::{FrameContext, RaySegment};
use crate::volume::Volume;

/// Accumulated colour (premultiplied) and opacity of a ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct DvrState {
    /// `C`, premultiplied.
    pub color: Vec3,
    /// `A`.
    pub alpha: f32,
    /// Set once `A` reached the ERT threshold.
    pub terminated: bool,
}

impl DvrState {
    /// Composites samples `k0..k1` (clamped to the ray); returns how many were taken.
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
        let threshold = ctx.ert.unwrap_or(f32::INFINITY);
        while k < k1 && !self.terminated {
            // Decide how far we may march sample by sample.
            let run_end = if ctx.ess {
                let p = seg.pos(k);
                match ctx.skip.occupied_cell_box(p) {
                    Some(cell) => {
                        let t_exit = cell.exit(seg.origin, seg.inv_dir);
                        seg.first_index_at_or_after(t_exit).max(k + 1).min(k1)
                    }
                    None => {
                        // Empty: jump past the empty box around this cell.
                        if let Some(b) = ctx.skip.empty_box(p) {
                            let t_exit = b.exit(seg.origin, seg.inv_dir);
                            k = seg.first_index_at_or_after(t_exit).max(k + 1);
                        } else {
                            k += 1;
                        }
                        continue;
                    }
                }
            } else {
                k1
            };
            while k < run_end {
                let p = seg.pos(k);
                let v = ctx.volume.sample(p);
                taken += 1;
                k += 1;
                let e = ctx.lut.lookup(v);
                if e.w <= 0.0 {
                    continue;
                }
                let mut rgb = e.truncate();
                if let Some(ph) = &ctx.shading
                    && let Some((diffuse, spec)) = ph.terms(ctx.volume.gradient(p), seg.world_dir)
                {
                    rgb = rgb * diffuse + Vec3::splat(e.w * spec);
                }
                let w = 1.0 - self.alpha;
                self.color += w * rgb;
                self.alpha += w * e.w;
                if self.alpha >= threshold {
                    self.terminated = true;
                    break;
                }
            }
        }
        taken
    }
}

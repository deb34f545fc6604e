//! Isosurface: the first crossing of the iso value, refined by bisection.

use glam::{Vec3, Vec4};

use super::{FrameContext, RaySegment};
use crate::volume::Volume;

/// The search state of an iso ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct IsoState {
    /// The last sample taken: index and value.
    pub prev: Option<(u32, f32)>,
    /// Voxel-space hit point and world ray direction, once found.
    pub hit: Option<(Vec3, Vec3)>,
}

impl IsoState {
    /// Searches samples `k0..k1` for a sign change of `value − iso`.
    ///
    /// ESS: cells whose range excludes the iso value are skipped, but the
    /// first sample into and the last sample out of an empty run are taken,
    /// so every pair of consecutive samples that could bracket a crossing is
    /// still compared.
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
        while k < k1 && self.hit.is_none() {
            if ctx.ess {
                let p = seg.pos(k);
                if let Some(b) = ctx.skip.empty_box(p) {
                    let next = seg
                        .first_index_at_or_after(b.exit(seg.origin, seg.inv_dir))
                        .max(k + 1);
                    // Close the pair (k − 1, k), then open the pair
                    // (next − 1, next); the samples between lie in the empty
                    // box, on one side of the iso value.
                    let mut visited = false;
                    if self.prev.is_some() {
                        taken += self.visit(ctx, seg, k);
                        visited = true;
                    }
                    let last = next - 1;
                    if last < k1 && (last > k || !visited) {
                        taken += self.visit(ctx, seg, last);
                    }
                    k = next;
                    continue;
                }
            }
            taken += self.visit(ctx, seg, k);
            k += 1;
        }
        taken
    }

    #[inline]
    fn visit<V: Volume>(&mut self, ctx: &FrameContext<'_, V>, seg: &RaySegment, k: u32) -> u64 {
        if self.hit.is_some() {
            return 0;
        }
        let v = ctx.volume.sample(seg.pos(k));
        let iso = ctx.iso_value;
        if let Some((kp, vp)) = self.prev
            && (vp >= iso) != (v >= iso)
        {
            // Bisection on [t(kp), t(k)] to 1/100 of a step.
            let (mut ta, mut tb) = (seg.t(kp), seg.t(k));
            let side_a = vp >= iso;
            let tol = seg.step * 0.01;
            while tb - ta > tol {
                let tm = 0.5 * (ta + tb);
                let vm = ctx.volume.sample(seg.origin + seg.dir * tm);
                if (vm >= iso) == side_a {
                    ta = tm;
                } else {
                    tb = tm;
                }
            }
            let t = 0.5 * (ta + tb);
            self.hit = Some((seg.origin + seg.dir * t, seg.world_dir));
        }
        self.prev = Some((k, v));
        1
    }

    /// The TF colour at the iso value, Phong-shaded when shading is on; opaque.
    pub fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        let Some((p, dir)) = self.hit else {
            return Vec4::ZERO;
        };
        let c = ctx.tf.evaluate(ctx.iso_value).truncate();
        let rgb = match &ctx.shading {
            Some(ph) => {
                let mut ph = *ph;
                ph.gradient_threshold = 0.0;
                match ph.terms(ctx.volume.gradient(p), dir) {
                    Some((d, s)) => c * d + Vec3::splat(s),
                    None => c * ph.ka,
                }
            }
            None => c,
        };
        rgb.extend(1.0)
    }
}

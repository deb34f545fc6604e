//! Isosurface: the first crossing of the iso value, refined by bisection.

use glam::{Vec3, Vec4};

use super::{FrameContext, Integrator, Occupancy, RaySegment, Span};
use crate::accel::RunKind;
use crate::volume::Volume;

/// The search state of an iso ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct IsoState {
    /// The last sample taken: index and value.
    pub prev: Option<(u32, f32)>,
    /// Voxel-space hit point and world ray direction, once found.
    pub hit: Option<(Vec3, Vec3)>,
}

impl Integrator for IsoState {
    const SPLITS_RAYS: bool = false;

    const OCCUPANCY: Occupancy = Occupancy::IsoValue;

    /// Searches the span's samples for a sign change of `value − iso`.
    ///
    /// ESS: runs in cells whose range excludes the iso value are skipped,
    /// but the first sample into and the last sample out of an empty run are
    /// taken, so every pair of consecutive samples that could bracket a
    /// crossing is still compared.
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let k1 = span.end.min(seg.count);
        let mut taken = 0u64;
        for run in span.runs() {
            if self.hit.is_some() {
                break;
            }
            if run.kind != RunKind::Empty {
                for k in run.start..run.end {
                    taken += self.visit(ctx, seg, k);
                    if self.hit.is_some() {
                        break;
                    }
                }
                continue;
            }
            // Close the pair (start − 1, start), then open the pair
            // (end − 1, end); the samples between lie in the empty box, on
            // one side of the iso value.
            let mut visited = false;
            if self.prev.is_some() {
                taken += self.visit(ctx, seg, run.start);
                visited = true;
            }
            let last = run.end - 1;
            if last < k1 && (last > run.start || !visited) {
                taken += self.visit(ctx, seg, last);
            }
        }
        taken
    }

    fn is_done(&self) -> bool {
        self.hit.is_some()
    }

    /// The TF colour at the iso value, Phong-shaded when shading is on; opaque.
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
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

impl IsoState {
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
}

//! Rays and axis-aligned boxes.

use glam::{Vec3, Vec3A};

/// `a.min(b)` for a `b` that is not NaN (a NaN `a` gives `b`, as
/// `f32::min` does): one `minss`, where `f32::min`'s handling of a NaN `b`
/// takes three instructions, which shows in the per-cell loops.
#[inline(always)]
pub(crate) fn min_to(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `a.max(b)` for a `b` that is not NaN (see [`min_to`]).
#[inline(always)]
pub(crate) fn max_to(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// One axis of the slab method: `(t0, t1)` narrowed to the parameters at
/// which a ray with inverse direction component `inv` lies between the
/// planes at offsets `lo` and `hi` from its origin along that axis. Plain
/// comparisons (one `minss`/`maxss` each, and vectorised in lane-wise
/// loops) rather than `f32::min`/`max`, whose NaN handling triples the
/// instructions; callers keep NaN out (no `0·∞`).
#[inline(always)]
pub(crate) fn clip_slab(lo: f32, hi: f32, inv: f32, (t0, t1): (f32, f32)) -> (f32, f32) {
    let (a, b) = (lo * inv, hi * inv);
    let (near, far) = if a < b { (a, b) } else { (b, a) };
    (max_to(near, t0), min_to(far, t1))
}

/// A ray `origin + t·dir`; renderers keep `dir` normalised so that `t` is a
/// world-space distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Direction (unit length for camera rays).
    pub dir: Vec3,
}

impl Ray {
    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// An axis-aligned box `[min, max]` (inclusive; may be flat along an axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box with corners `min` and `max`.
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb { min, max }
    }

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The 8 corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }

    /// True when `p` is inside or on the box.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The parameter interval `[t_in, t_out]` where the ray is inside the box,
    /// with `t_in` clamped to 0 (a ray starting inside enters at 0); `None`
    /// when the ray misses or the box lies behind it.
    ///
    /// Slab method. An axis along which the ray does not move constrains
    /// nothing when the origin lies within the slab (boundary included) and
    /// makes the ray miss otherwise, so rays in a face plane still hit.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, f32)> {
        // One axis at a time, spelled out: as a loop indexing the vectors by
        // axis it compiled to several times the instructions.
        #[inline(always)]
        fn slab(o: f32, d: f32, lo: f32, hi: f32, t: &mut (f32, f32)) -> bool {
            if d == 0.0 {
                return !(o < lo || o > hi);
            }
            // No operand is NaN for a finite ray (`d` is not 0).
            *t = clip_slab(lo - o, hi - o, 1.0 / d, *t);
            true
        }
        let (o, d) = (ray.origin, ray.dir);
        let mut t = (0.0f32, f32::INFINITY);
        let inside = slab(o.x, d.x, self.min.x, self.max.x, &mut t)
            && slab(o.y, d.y, self.min.y, self.max.y, &mut t)
            && slab(o.z, d.z, self.min.z, self.max.z, &mut t);
        (inside && t.0 <= t.1).then_some(t)
    }

    /// [`Aabb::intersect`] for rays from `origin` along `dir[axis][lane]`,
    /// lane by lane: the entry and exit parameters (`entry <= exit` when
    /// the lane's ray meets the box), the same bits as `intersect` gives,
    /// for all lanes at once. No direction component may be 0 (`intersect`
    /// treats those apart).
    #[inline(always)]
    pub fn intersect_lanes<const N: usize>(
        &self,
        origin: Vec3,
        dir: &[[f32; N]; 3],
    ) -> ([f32; N], [f32; N]) {
        let mut t0 = [0.0f32; N];
        let mut t1 = [f32::INFINITY; N];
        for a in 0..3 {
            let (o, lo, hi) = (origin[a], self.min[a], self.max[a]);
            for l in 0..N {
                (t0[l], t1[l]) = clip_slab(lo - o, hi - o, 1.0 / dir[a][l], (t0[l], t1[l]));
            }
        }
        (t0, t1)
    }

    /// The exit parameter of a ray known to start inside the box.
    #[inline]
    pub fn exit(&self, origin: impl Into<Vec3A>, inv_dir: impl Into<Vec3A>) -> f32 {
        let inv: Vec3A = inv_dir.into();
        // Per axis the far plane: the upper one for a positive direction,
        // the lower one for a negative one. An axis the ray is parallel to
        // (1/d = ±∞) never ends it, even with the origin on a plane
        // (0·∞ = NaN); three lanes at once.
        let far = Vec3A::select(inv.cmpge(Vec3A::ZERO), self.max.into(), self.min.into());
        let t = (far - origin.into()) * inv;
        Vec3A::select(inv.abs().cmplt(Vec3A::INFINITY), t, Vec3A::INFINITY).min_element()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_through_unit_box() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let r = Ray {
            origin: Vec3::new(0.5, 0.5, -1.0),
            dir: Vec3::Z,
        };
        assert_eq!(b.intersect(&r), Some((1.0, 2.0)));
        let miss = Ray {
            origin: Vec3::new(2.0, 0.5, -1.0),
            dir: Vec3::Z,
        };
        assert_eq!(b.intersect(&miss), None);
        let inside = Ray {
            origin: Vec3::splat(0.5),
            dir: -Vec3::X,
        };
        assert_eq!(b.intersect(&inside), Some((0.0, 0.5)));
        let behind = Ray {
            origin: Vec3::new(0.5, 0.5, 3.0),
            dir: Vec3::Z,
        };
        assert_eq!(b.intersect(&behind), None);
    }

    #[test]
    fn ray_in_a_face_plane_still_hits() {
        // dir.x = 0 and origin.x on the slab plane: 0 * inf = NaN must not poison.
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let r = Ray {
            origin: Vec3::new(0.0, 0.5, -1.0),
            dir: Vec3::Z,
        };
        assert_eq!(b.intersect(&r), Some((1.0, 2.0)));
    }

    #[test]
    fn flat_box_is_hit_at_one_point() {
        let b = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        let r = Ray {
            origin: Vec3::new(0.5, 0.5, -2.0),
            dir: Vec3::Z,
        };
        assert_eq!(b.intersect(&r), Some((2.0, 2.0)));
    }
}

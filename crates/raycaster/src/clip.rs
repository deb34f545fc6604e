//! Clipping: a crop box and up to [`MAX_CLIP_PLANES`] half-spaces that
//! remove samples (SPEC §8 "Clipping").
//!
//! [`Clip`] is the user's description in world coordinates; a frame turns it
//! into a [`ClipRegion`] in voxel space (where rays are marched), once. The
//! kept region, box ∩ half-spaces, is convex, so the samples of a ray that
//! it keeps are one contiguous range of indices: [`ClipRegion::sample_range`]
//! finds it from the ray/region parameters and settles each end with the
//! same `f32` test on the computed sample positions (`RaySegment::pos`), so
//! every renderer keeps exactly the same samples. Skipping structures ask
//! [`ClipRegion::may_hold`] whether a box can hold a kept sample at all.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::volume::Grid;

/// At most this many clip planes.
pub const MAX_CLIP_PLANES: usize = 6;

/// A half-space removal: samples at `p` with `normal·p > offset` are removed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClipPlane {
    /// Normal (world units, any non-zero length).
    pub normal: Vec3,
    /// Offset `d` of `n·p > d`.
    pub offset: f32,
}

/// What to clip away, in world coordinates.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Clip {
    /// Samples outside `[min, max]` are removed (`None`: no crop box).
    pub clip_box: Option<(Vec3, Vec3)>,
    /// Half-spaces whose samples are removed.
    pub planes: Vec<ClipPlane>,
}

impl Clip {
    /// True when nothing is clipped.
    pub fn is_empty(&self) -> bool {
        self.clip_box.is_none() && self.planes.is_empty()
    }

    /// Checks the description: a box with `min <= max` and finite corners,
    /// at most [`MAX_CLIP_PLANES`] planes with finite, non-zero normals and
    /// finite offsets. The error names the option (`clip-box`, `clip-plane`).
    pub fn validate(&self) -> Result<()> {
        if let Some((lo, hi)) = self.clip_box {
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(Error::option(
                    "clip-box",
                    format!("corners {lo} and {hi} must be finite"),
                ));
            }
            if lo.cmpgt(hi).any() {
                return Err(Error::option(
                    "clip-box",
                    format!("x0,y0,z0 = {lo} must not exceed x1,y1,z1 = {hi} on any axis"),
                ));
            }
        }
        if self.planes.len() > MAX_CLIP_PLANES {
            return Err(Error::option(
                "clip-plane",
                format!(
                    "{} planes given, at most {MAX_CLIP_PLANES}",
                    self.planes.len()
                ),
            ));
        }
        for p in &self.planes {
            if !(p.normal.is_finite() && p.offset.is_finite()) {
                return Err(Error::option(
                    "clip-plane",
                    format!("normal {} and offset {} must be finite", p.normal, p.offset),
                ));
            }
            if p.normal == Vec3::ZERO {
                return Err(Error::option("clip-plane", "the normal must not be zero"));
            }
        }
        Ok(())
    }

    /// The region in the voxel space of `grid`; `None` when nothing is
    /// clipped. Call [`Clip::validate`] first.
    pub fn region(&self, grid: &Grid) -> Option<ClipRegion> {
        if self.is_empty() {
            return None;
        }
        let (lo, hi) = match self.clip_box {
            Some((lo, hi)) => (grid.world_to_voxel(lo), grid.world_to_voxel(hi)),
            None => (Vec3::NEG_INFINITY, Vec3::INFINITY),
        };
        // n·(origin + spacing∘v) > d  ⇔  (n∘spacing)·v > d − n·origin.
        let planes = self
            .planes
            .iter()
            .map(|p| {
                (
                    p.normal * grid.spacing,
                    p.offset - p.normal.dot(grid.origin),
                )
            })
            .collect();
        // Slack for the conservative box tests: well above the rounding of
        // a sample position (voxel units; positions lie in the grid's box).
        let margin = 1e-4 * grid.dims.max_element() as f32 + 1e-3;
        Some(ClipRegion {
            lo,
            hi,
            planes,
            margin,
        })
    }
}

/// The kept region in voxel space: `lo <= p <= hi` and `n·p <= d` for every
/// plane.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipRegion {
    lo: Vec3,
    hi: Vec3,
    planes: Vec<(Vec3, f32)>,
    margin: f32,
}

impl ClipRegion {
    /// Whether voxel-space point `p` is kept: the test that decides every
    /// sample at the ends of a ray's kept range.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        self.lo.cmple(p).all()
            && p.cmple(self.hi).all()
            && self.planes.iter().all(|&(n, d)| n.dot(p) <= d)
    }

    /// Whether the voxel-space box `[lo, hi]` may hold a kept point: false
    /// only when the box, grown by a margin well above rounding, lies wholly
    /// outside the crop box or wholly beyond one plane.
    pub fn may_hold(&self, lo: Vec3, hi: Vec3) -> bool {
        let m = Vec3::splat(self.margin);
        let (lo, hi) = (lo - m, hi + m);
        if hi.cmplt(self.lo).any() || lo.cmpgt(self.hi).any() {
            return false;
        }
        self.planes.iter().all(|&(n, d)| {
            // The box corner that minimises n·p.
            let p = Vec3::select(n.cmpge(Vec3::ZERO), lo, hi);
            n.dot(p) <= d + self.margin * n.abs().element_sum()
        })
    }

    /// The parameter interval `[a, b]` of the line `origin + t·dir` inside
    /// the region (`a > b` when it misses), from the slab and plane
    /// equations: an estimate that [`ClipRegion::sample_range`] settles on
    /// the positions.
    pub(crate) fn interval(&self, origin: Vec3, dir: Vec3) -> (f32, f32) {
        let (mut a, mut b) = (f32::NEG_INFINITY, f32::INFINITY);
        for i in 0..3 {
            let (o, d) = (origin[i], dir[i]);
            if d == 0.0 {
                if !(self.lo[i] <= o && o <= self.hi[i]) {
                    return (f32::INFINITY, f32::NEG_INFINITY);
                }
                continue;
            }
            let t0 = (self.lo[i] - o) / d;
            let t1 = (self.hi[i] - o) / d;
            a = a.max(t0.min(t1));
            b = b.min(t0.max(t1));
        }
        for &(n, dd) in &self.planes {
            let nd = n.dot(dir);
            let no = n.dot(origin);
            if nd == 0.0 {
                if no > dd {
                    return (f32::INFINITY, f32::NEG_INFINITY);
                }
                continue;
            }
            let t = (dd - no) / nd;
            if nd > 0.0 {
                b = b.min(t);
            } else {
                a = a.max(t);
            }
        }
        (a, b)
    }

    /// The kept samples of a ray among `0..count`, sample `k` at voxel
    /// position `pos(k)` and world parameter `t0 + k·step`: the range
    /// `first..end` of the `k` whose position [`ClipRegion::contains`],
    /// `(0, 0)` when none. The ends are estimated from the region's
    /// equations, then moved sample by sample until the computed positions
    /// confirm them (first and last inside, their outer neighbours not).
    pub fn sample_range(
        &self,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        inv_step: f32,
        count: u32,
        pos: impl Fn(u32) -> Vec3,
    ) -> (u32, u32) {
        let (a, b) = self.interval(origin, dir);
        // NaN (a degenerate ray) counts as a miss.
        if a > b || a.is_nan() || b.is_nan() || count == 0 {
            return (0, 0);
        }
        // `as` saturates: −∞ and NaN give 0, +∞ gives u32::MAX.
        let index = |t: f32| ((t - t0) * inv_step).ceil().max(0.0) as u32;
        let mut first = index(a).min(count);
        let mut end = (((b - t0) * inv_step).floor().max(-1.0) + 1.0) as u32;
        end = end.min(count).max(first);
        let inside = |k: u32| self.contains(pos(k));
        while first > 0 && inside(first - 1) {
            first -= 1;
        }
        end = end.max(first);
        while first < end && !inside(first) {
            first += 1;
        }
        if first == end {
            // The estimate holds no sample: look at the one on each side.
            if first < count && inside(first) {
                end = first + 1;
            } else {
                return (0, 0);
            }
        }
        while end < count && inside(end) {
            end += 1;
        }
        while end > first && !inside(end - 1) {
            end -= 1;
        }
        (first, end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    fn region(clip: Clip) -> ClipRegion {
        clip.validate().unwrap();
        clip.region(&Grid::new(UVec3::splat(40), Vec3::new(1.0, 0.5, 2.0)))
            .unwrap()
    }

    /// The range equals brute force over the positions, for random rays,
    /// boxes and planes.
    #[test]
    fn sample_ranges_match_brute_force() {
        let mut rng = fastrand::Rng::with_seed(5);
        let v = |rng: &mut fastrand::Rng, s: f32| {
            Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * s
        };
        for trial in 0..3000 {
            let lo = v(&mut rng, 40.0) + Vec3::splat(10.0);
            let hi = lo + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 30.0;
            let planes = (0..rng.usize(0..4))
                .map(|_| ClipPlane {
                    normal: v(&mut rng, 2.0),
                    offset: rng.f32() * 20.0,
                })
                .filter(|p| p.normal != Vec3::ZERO)
                .collect();
            let clip = Clip {
                clip_box: (trial % 3 != 0).then_some((lo, hi)),
                planes,
            };
            if clip.is_empty() {
                continue;
            }
            let r = region(clip);
            let origin = v(&mut rng, 100.0);
            let mut dir = v(&mut rng, 2.0);
            if trial % 7 == 0 {
                dir.y = 0.0;
            }
            let t0 = rng.f32() * 3.0;
            let step = 0.1 + rng.f32();
            let count = rng.u32(0..200);
            let pos = |k: u32| origin + dir * (t0 + k as f32 * step);
            let got = r.sample_range(origin, dir, t0, 1.0 / step, count, pos);
            let kept: Vec<u32> = (0..count).filter(|&k| r.contains(pos(k))).collect();
            let want = match (kept.first(), kept.last()) {
                (Some(&a), Some(&b)) => (a, b + 1),
                _ => (0, 0),
            };
            assert_eq!(got, want, "trial {trial}");
        }
    }

    #[test]
    fn boxes_outside_are_found_and_boxes_inside_kept() {
        let r = region(Clip {
            clip_box: Some((Vec3::splat(5.0), Vec3::splat(20.0))),
            planes: vec![ClipPlane {
                normal: Vec3::X,
                offset: 12.0,
            }],
        });
        // World x 5..12, y 5..20, z 5..20 → voxel x 5..12, y 10..40, z 2.5..10.
        assert!(r.may_hold(Vec3::new(6.0, 11.0, 3.0), Vec3::new(7.0, 12.0, 4.0)));
        assert!(!r.may_hold(Vec3::new(13.0, 11.0, 3.0), Vec3::new(15.0, 12.0, 4.0)));
        assert!(!r.may_hold(Vec3::new(6.0, 0.0, 3.0), Vec3::new(7.0, 9.0, 4.0)));
        assert!(r.may_hold(Vec3::new(11.0, 0.0, 0.0), Vec3::new(30.0, 30.0, 30.0)));
    }

    #[test]
    fn bad_descriptions_name_the_option() {
        let bad_box = Clip {
            clip_box: Some((Vec3::new(2.0, 0.0, 0.0), Vec3::ONE)),
            planes: vec![],
        };
        assert!(
            bad_box
                .validate()
                .unwrap_err()
                .to_string()
                .contains("clip-box")
        );
        let zero = Clip {
            clip_box: None,
            planes: vec![ClipPlane {
                normal: Vec3::ZERO,
                offset: 1.0,
            }],
        };
        assert!(
            zero.validate()
                .unwrap_err()
                .to_string()
                .contains("clip-plane")
        );
        let many = Clip {
            clip_box: None,
            planes: vec![
                ClipPlane {
                    normal: Vec3::X,
                    offset: 1.0
                };
                7
            ],
        };
        assert!(
            many.validate()
                .unwrap_err()
                .to_string()
                .contains("clip-plane")
        );
    }
}

//! [`RaySegment`]: one ray in voxel space with its sample index range.
//!
//! Every mode walks the same sample positions `t_k = t0 + k·s`, computed
//! from `k` (never by accumulating `t += s`), so any renderer that splits a
//! ray into pieces — per brick, per tile — takes exactly the same samples.
//! `t0` is the box entry `t_in`, or with jitter `t_in + j·s` ([`jitter`]).
//! Clipping keeps the samples `first..count` ([`crate::clip`]); every
//! integrator and schedule takes only those.

use glam::Vec3;

use crate::clip::ClipRegion;
use crate::geometry::Ray;
use crate::volume::Grid;

/// The jitter offset `j ∈ [0, 1)` of pixel `(i, j)` for `seed` (SPEC §8
/// "Jitter"): a 32-bit integer hash (Wang/Jenkins-style mixing rounds) of
/// the three numbers, its top 24 bits as a fraction, so `j` is exact in
/// `f32` and identical for every renderer.
#[inline]
pub fn jitter(i: u32, j: u32, seed: u32) -> f32 {
    let mut h =
        seed.wrapping_mul(0x9E37_79B9) ^ i.wrapping_mul(0x85EB_CA6B) ^ j.wrapping_mul(0xC2B2_AE35);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// One ray prepared for marching through a volume: in voxel space, with its
/// sample index range.
#[derive(Debug, Clone, Copy, Default)]
pub struct RaySegment {
    /// Ray origin in voxel space.
    pub origin: Vec3,
    /// Ray direction in voxel space per world unit of `t`.
    pub dir: Vec3,
    /// `1 / dir`, for box exits.
    pub inv_dir: Vec3,
    /// World direction (unit), for shading.
    pub world_dir: Vec3,
    /// Start of the part of the ray searched by exact iso: the entry into
    /// the volume's box, raised to the clip region's entry when clipped.
    pub t_in: f32,
    /// End of that part: the exit from the volume's box (`t_k <= t_out`
    /// for every sample), lowered to the clip region's exit when clipped.
    pub t_out: f32,
    /// Parameter of sample 0: the box entry plus the jitter offset `j·s`.
    pub t0: f32,
    /// Sampling step (world units).
    pub step: f32,
    /// `1 / step`.
    pub inv_step: f32,
    /// First sample kept by clipping (0 without clipping).
    pub first: u32,
    /// One past the last sample kept: the ray's samples are `first..count`.
    pub count: u32,
}

impl RaySegment {
    /// Clips a world-space ray (unit direction) against the grid's box;
    /// `None` when it misses.
    #[inline]
    pub fn new(grid: &Grid, ray: &Ray, step: f32) -> Option<Self> {
        Self::with(grid, ray, step, 0.0, None)
    }

    /// [`RaySegment::new`] with the jitter offset `jitter` (in steps,
    /// `0 <= jitter < 1`) and the samples outside `clip` removed. A ray may
    /// then keep no sample (`first == count`).
    #[inline(always)]
    pub fn with(
        grid: &Grid,
        ray: &Ray,
        step: f32,
        jitter: f32,
        clip: Option<&ClipRegion>,
    ) -> Option<Self> {
        let (t_in, t_out) = grid.bounds().intersect(ray)?;
        // j = 0 gives t0 = t_in exactly: the unjittered samples.
        let t0 = t_in + jitter * step;
        let inv_step = 1.0 / step;
        let count = sample_count(t0, t_out, step, last_estimate(t0, t_out, inv_step));
        let dir = ray.dir / grid.spacing;
        let mut seg = RaySegment {
            origin: grid.world_to_voxel(ray.origin),
            dir,
            inv_dir: dir.recip(),
            world_dir: ray.dir,
            t_in,
            t_out,
            t0,
            step,
            inv_step,
            first: 0,
            count,
        };
        if let Some(clip) = clip {
            let (first, end) =
                clip.sample_range(seg.origin, seg.dir, t0, seg.inv_step, count, |k| seg.pos(k));
            seg.first = first;
            seg.count = end;
            let (a, b) = clip.interval(seg.origin, seg.dir);
            seg.t_in = seg.t_in.max(a);
            seg.t_out = seg.t_out.min(b);
        }
        Some(seg)
    }

    /// The ray clipped to the grid's box but keeping no sample (`None` when
    /// it misses the box): a ray known to see nothing, counted as entering
    /// the volume without the cost of preparing it. Only its box interval
    /// and world direction are set; with no sample to take, nothing reads
    /// the rest.
    #[inline]
    pub fn entering(grid: &Grid, ray: &Ray, step: f32) -> Option<Self> {
        let (t_in, t_out) = grid.bounds().intersect(ray)?;
        Some(RaySegment {
            origin: Vec3::ZERO,
            dir: Vec3::ZERO,
            inv_dir: Vec3::ZERO,
            world_dir: ray.dir,
            t_in,
            t_out,
            t0: t_in,
            step,
            inv_step: 0.0,
            first: 0,
            count: 0,
        })
    }

    /// Whether clipping (or jitter) left the ray without a sample.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.first >= self.count
    }

    /// World parameter of sample `k`.
    #[inline(always)]
    pub fn t(&self, k: u32) -> f32 {
        self.t0 + k as f32 * self.step
    }

    /// Voxel-space position of sample `k`.
    #[inline(always)]
    pub fn pos(&self, k: u32) -> Vec3 {
        self.origin + self.dir * self.t(k)
    }

    /// A sample index at or just before the first sample at or after
    /// parameter `t` (saturating). Callers use it as the end of a run of
    /// samples inside a box whose exit is `t`, or as where to resume after
    /// skipping such a box: it may err by one sample early (harmless: that
    /// sample is taken) but never late (which would skip a sample outside an
    /// empty box).
    #[inline(always)]
    pub fn first_index_at_or_after(&self, t: f32) -> u32 {
        Self::index_at_or_after(self.t0, self.inv_step, t)
    }

    /// [`RaySegment::first_index_at_or_after`] of a segment whose first
    /// sample is at `t0`, `inv_step` = `1 / step` (for lane-wise set-ups).
    #[inline(always)]
    pub fn index_at_or_after(t0: f32, inv_step: f32, t: f32) -> u32 {
        let x = (t - t0) * inv_step - 1e-3;
        // ceil without a libm call; `as` saturates negatives and NaN to 0.
        let k = x as u32;
        k + ((k as f32) < x) as u32
    }
}

/// An estimate of the index of the last sample `t0 + k·s <= t_out` (a
/// multiplication by `1/s`: a division here would sit on every ray's
/// critical path), made exact by [`sample_count`].
#[inline(always)]
pub(super) fn last_estimate(t0: f32, t_out: f32, inv_step: f32) -> f32 {
    ((t_out - t0) * inv_step).floor().max(0.0)
}

/// The number of `k` with `t0 + k·s <= t_out` (`s` = `step`), computed as
/// the renderers will, from `last`, [`last_estimate`]'s.
#[inline(always)]
pub(super) fn sample_count(t0: f32, t_out: f32, step: f32, last: f32) -> u32 {
    if t0 > t_out {
        return 0;
    }
    let mut last = last as u32;
    // The estimate is almost always right: test it once before looping (a
    // bare loop is vectorised into a search whose set-up costs every ray
    // more than the loop ever runs).
    if last > 0 && t0 + last as f32 * step > t_out {
        last -= 1;
        while last > 0 && t0 + last as f32 * step > t_out {
            last -= 1;
        }
    }
    while t0 + (last + 1) as f32 * step <= t_out {
        last += 1;
    }
    last + 1
}

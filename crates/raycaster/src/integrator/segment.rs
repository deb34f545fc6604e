//! [`RaySegment`]: one ray in voxel space with its sample index range.
//!
//! Every mode walks the same sample positions `t_k = t_in + k·s`, computed
//! from `k` (never by accumulating `t += s`), so any renderer that splits a
//! ray into pieces — per brick, per tile — takes exactly the same samples.

use glam::Vec3;

use crate::geometry::Ray;
use crate::volume::Grid;

/// One ray prepared for marching through a volume: in voxel space, with its
/// sample index range.
#[derive(Debug, Clone, Copy)]
pub struct RaySegment {
    /// Ray origin in voxel space.
    pub origin: Vec3,
    /// Ray direction in voxel space per world unit of `t`.
    pub dir: Vec3,
    /// `1 / dir`, for box exits.
    pub inv_dir: Vec3,
    /// World direction (unit), for shading.
    pub world_dir: Vec3,
    /// Entry parameter into the volume's box.
    pub t_in: f32,
    /// Exit parameter from the volume's box (`t_k <= t_out` for every
    /// sample).
    pub t_out: f32,
    /// Sampling step (world units).
    pub step: f32,
    /// `1 / step`.
    pub inv_step: f32,
    /// Number of samples on the whole ray: indices `0..count`.
    pub count: u32,
}

impl RaySegment {
    /// Clips a world-space ray (unit direction) against the grid's box;
    /// `None` when it misses.
    #[inline]
    pub fn new(grid: &Grid, ray: &Ray, step: f32) -> Option<Self> {
        let (t_in, t_out) = grid.bounds().intersect(ray)?;
        // Largest k with t_in + k·s <= t_out, computed as the renderers will.
        let mut last = ((t_out - t_in) / step).floor().max(0.0) as u32;
        while last > 0 && t_in + last as f32 * step > t_out {
            last -= 1;
        }
        while t_in + (last + 1) as f32 * step <= t_out {
            last += 1;
        }
        let dir = ray.dir / grid.spacing;
        Some(RaySegment {
            origin: grid.world_to_voxel(ray.origin),
            dir,
            inv_dir: dir.recip(),
            world_dir: ray.dir,
            t_in,
            t_out,
            step,
            inv_step: 1.0 / step,
            count: last + 1,
        })
    }

    /// World parameter of sample `k`.
    #[inline(always)]
    pub fn t(&self, k: u32) -> f32 {
        self.t_in + k as f32 * self.step
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
        let x = (t - self.t_in) * self.inv_step - 1e-3;
        // ceil without a libm call; `as` saturates negatives and NaN to 0.
        let k = x as u32;
        k + ((k as f32) < x) as u32
    }
}

//! The geometry of a sample grid: dimensions, spacing, origin; sample
//! (x, y, z) sits at `origin + (x·sx, y·sy, z·sz)`.

use glam::{UVec3, Vec3};

use crate::geometry::Aabb;

/// Where a volume's samples sit in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Samples per axis, each at least 1.
    pub dims: UVec3,
    /// Distance between neighbouring samples along each axis (world units).
    pub spacing: Vec3,
    /// World position of sample (0, 0, 0).
    pub origin: Vec3,
}

impl Grid {
    /// A grid at the origin.
    pub fn new(dims: UVec3, spacing: Vec3) -> Self {
        Grid {
            dims,
            spacing,
            origin: Vec3::ZERO,
        }
    }

    /// Number of samples.
    pub fn voxel_count(&self) -> u64 {
        self.dims.x as u64 * self.dims.y as u64 * self.dims.z as u64
    }

    /// The bounding box `[origin, origin + (dims − 1)·spacing]`.
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.origin, self.origin + self.extent())
    }

    /// `(dims − 1)·spacing`.
    pub fn extent(&self) -> Vec3 {
        (self.dims.as_vec3() - Vec3::ONE) * self.spacing
    }

    /// World position to voxel-space position.
    #[inline]
    pub fn world_to_voxel(&self, p: Vec3) -> Vec3 {
        (p - self.origin) / self.spacing
    }

    /// Voxel-space position to world position.
    #[inline]
    pub fn voxel_to_world(&self, v: Vec3) -> Vec3 {
        self.origin + v * self.spacing
    }

    /// Largest voxel coordinate per axis, `dims − 1`, as floats.
    #[inline]
    pub fn max_coord(&self) -> Vec3 {
        self.dims.as_vec3() - Vec3::ONE
    }

    /// Lower corner of the last interpolation cell per axis: `dims − 2`, or 0
    /// along an axis of size 1.
    #[inline]
    pub fn last_cell(&self) -> UVec3 {
        self.dims.saturating_sub(UVec3::splat(2))
    }
}

//! `sdf`: the signed distance field of a small CSG scene, for isosurface
//! rendering (`vol_app render --mode iso --iso 128`).
//!
//! The scene is the classic CSG example, a cube intersected with a ball and
//! drilled through by three cylinders, with a thin torus around it, centred
//! in the volume and sized to `--object-size` (default: the smallest extent),
//! in units of the finest voxel spacing. A voxel at signed distance `d`
//! (negative inside) holds `128 − 128·d / band`, clamped to 0..=255, where
//! `band` is `--band` voxels (default 8): 128 on the surface, larger inside,
//! saturating `band` voxels away from it. The seed is not used.

use glam::{Vec2, Vec3};

use super::{Field, Region, Setup, to_u8};

/// Default `--band`.
pub const DEFAULT_BAND: f32 = 8.0;

/// The `sdf` generator.
#[derive(Debug, Clone, Copy)]
pub struct Sdf {
    centre: Vec3,
    size: f32,
    scale: Vec3,
    /// Value units per unit of distance.
    gain: f32,
}

impl Sdf {
    /// The scene described by `setup`.
    pub fn new(setup: &Setup) -> Result<Self, String> {
        let band = setup.band.unwrap_or(DEFAULT_BAND);
        if !(band.is_finite() && band > 0.0) {
            return Err(format!("--band {band} must be finite and greater than 0"));
        }
        let extent = setup.extent();
        let size = setup
            .object_size
            .map_or(extent.min_element(), |s| s as f32)
            .max(1.0);
        Ok(Sdf {
            centre: extent / 2.0,
            size,
            scale: setup.scale(),
            gain: 128.0 / band,
        })
    }

    /// Signed distance from `p` (relative to the centre) to the scene.
    #[inline]
    pub fn distance(&self, q: Vec3) -> f32 {
        let s = self.size;
        // Cube of side 0.6·s ∩ ball of radius 0.4·s.
        let d = q.abs() - Vec3::splat(0.3 * s);
        let cube = d.max(Vec3::ZERO).length() + d.max_element().min(0.0);
        let ball = q.length() - 0.4 * s;
        let body = cube.max(ball);
        // Minus three cylinders of radius 0.13·s along the axes.
        let r = 0.13 * s;
        let cross = (Vec2::new(q.y, q.z).length() - r)
            .min(Vec2::new(q.x, q.z).length() - r)
            .min(Vec2::new(q.x, q.y).length() - r);
        let carved = body.max(-cross);
        // ∪ a torus in the xz plane, clear of the body.
        let torus = Vec2::new(Vec2::new(q.x, q.z).length() - 0.45 * s, q.y).length() - 0.035 * s;
        carved.min(torus)
    }
}

impl Field for Sdf {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        region.for_each_row(out, |x, y, row| {
            let qx = x as f32 * self.scale.x - self.centre.x;
            let qy = y as f32 * self.scale.y - self.centre.y;
            for (i, v) in row.iter_mut().enumerate() {
                let qz = (region.lo.z + i as u32) as f32 * self.scale.z - self.centre.z;
                *v = to_u8(128.0 - self.distance(Vec3::new(qx, qy, qz)) * self.gain);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use glam::UVec3;

    #[test]
    fn surface_at_128_inside_high_outside_low() {
        let dims = UVec3::splat(65);
        let sdf = Sdf::new(&Setup::new(dims, 0)).unwrap();
        let data = render(&sdf, dims);
        let at = |x: usize, y: usize, z: usize| data[(x * 65 + y) * 65 + z];
        assert_eq!(at(0, 0, 0), 0, "far outside");
        // The centre is drilled out; the cube's solid corner region is inside.
        assert!(at(32, 32, 32) < 128);
        assert!(at(32 + 12, 32 + 12, 32 + 12) > 128);
        // Along the diagonal the values cross 128 somewhere.
        let diag: Vec<u8> = (32..65).map(|i| at(i, i, i)).collect();
        assert!(diag.windows(2).any(|w| (w[0] >= 128) != (w[1] >= 128)));
        assert_region_independent(&sdf, UVec3::new(11, 9, 10));
    }

    #[test]
    fn bad_band_is_rejected() {
        let s = Setup {
            band: Some(f32::NAN),
            ..Setup::new(UVec3::splat(4), 0)
        };
        assert!(Sdf::new(&s).is_err());
    }
}

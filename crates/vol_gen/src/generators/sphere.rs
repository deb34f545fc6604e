//! `sphere`: one ball centred in the volume whose value falls smoothly from
//! `--sample` (default 255) at the centre to 0 at its radius, with a
//! smoothstep profile `1 − t²(3 − 2t)`, `t = r / R`. The diameter is
//! `--object-size` (default: the volume's smallest extent), measured in units
//! of the finest voxel spacing so the ball is round in world space.

use glam::Vec3;

use super::{Field, Region, Setup, to_u8};

/// Default `--sample`: the value at the centre.
pub const DEFAULT_SAMPLE: u8 = 255;

/// The `sphere` generator.
#[derive(Debug, Clone, Copy)]
pub struct Sphere {
    centre: Vec3,
    radius: f32,
    scale: Vec3,
    peak: f32,
}

impl Sphere {
    /// The ball described by `setup`.
    pub fn new(setup: &Setup) -> Self {
        let extent = setup.extent();
        let diameter = setup
            .object_size
            .map_or(extent.min_element(), |s| s as f32)
            .max(1.0);
        Sphere {
            centre: extent / 2.0,
            radius: diameter / 2.0,
            scale: setup.scale(),
            peak: setup.sample.unwrap_or(DEFAULT_SAMPLE) as f32,
        }
    }
}

impl Field for Sphere {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        let r2 = self.radius * self.radius;
        region.for_each_row(out, |x, y, row| {
            let dx = x as f32 * self.scale.x - self.centre.x;
            let dy = y as f32 * self.scale.y - self.centre.y;
            let dxy2 = dx * dx + dy * dy;
            if dxy2 >= r2 {
                return;
            }
            for (i, v) in row.iter_mut().enumerate() {
                let dz = (region.lo.z + i as u32) as f32 * self.scale.z - self.centre.z;
                let t = ((dxy2 + dz * dz).sqrt() / self.radius).min(1.0);
                *v = to_u8(self.peak * (1.0 - t * t * (3.0 - 2.0 * t)));
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
    fn peak_in_the_middle_zero_at_the_corners() {
        let dims = UVec3::splat(21);
        let s = Sphere::new(&Setup::new(dims, 0));
        let data = render(&s, dims);
        assert_eq!(data[(10 * 21 + 10) * 21 + 10], 255);
        assert_eq!(data[0], 0);
        assert_region_independent(&s, UVec3::new(9, 8, 7));
    }

    #[test]
    fn anisotropic_spacing_keeps_it_round_in_world_space() {
        let dims = UVec3::new(21, 11, 21);
        let s = Sphere::new(&Setup {
            spacing: Vec3::new(1.0, 2.0, 1.0),
            ..Setup::new(dims, 0)
        });
        let data = render(&s, dims);
        let at = |x: usize, y: usize, z: usize| data[(x * 11 + y) * 21 + z];
        // 4 world units from the centre along x and along y.
        assert_eq!(at(14, 5, 10), at(10, 7, 10));
    }
}

//! `metaballs`: a density field summed from `--n-of-shapes` balls (default
//! 12) with the Wyvill soft-object kernel
//! `C(r) = 1 − 4/9·a³ + 17/9·a² − 22/9·a`, `a = (r/R)²`, for `r < R` (0 beyond),
//! which is 1 at a ball's centre and 1/2 at half its radius. Radii `R` are
//! drawn from 0.5..1.5 × `--object-size` / 2 (default size: a quarter of the
//! smallest extent), in units of the finest voxel spacing. A voxel holds
//! `256 · density`, clamped to 0..=255, so the classic iso level
//! `density = 1/2` is the value 128.

use glam::{DVec3, Vec3};

use super::bins::Bins;
use super::{Field, IBox, Region, Setup, to_u8};

/// Default `--n-of-shapes`.
pub const DEFAULT_COUNT: u32 = 12;

#[derive(Debug, Clone, Copy)]
struct Ball {
    centre: Vec3,
    radius2: f32,
    inv_radius2: f32,
    bounds: IBox,
}

/// The `metaballs` generator.
#[derive(Debug)]
pub struct Metaballs {
    balls: Vec<Ball>,
    bins: Bins,
    scale: Vec3,
}

/// The Wyvill kernel of `a = (r/R)²`, for `a < 1`.
#[inline(always)]
fn kernel(a: f32) -> f32 {
    1.0 + a * (-22.0 / 9.0 + a * (17.0 / 9.0 - a * (4.0 / 9.0)))
}

impl Metaballs {
    /// Draws the balls from `setup.seed`.
    pub fn new(setup: &Setup) -> Result<Self, String> {
        let n = super::object_count(setup, DEFAULT_COUNT)?;
        let extent = setup.extent().as_dvec3();
        let size = super::object_size(setup, extent.min_element() / 4.0)?;
        let scale = setup.scale();
        let mut rng = fastrand::Rng::with_seed(setup.seed);
        let mut balls = Vec::with_capacity(n as usize);
        let mut boxes = Vec::with_capacity(n as usize);
        for _ in 0..n {
            let radius = size / 2.0 * (0.5 + rng.f64());
            let spot = DVec3::new(rng.f64(), rng.f64(), rng.f64());
            // Centres at least half a radius from the faces where there is room.
            let margin = DVec3::splat(radius / 2.0).min(extent / 2.0);
            let centre = margin + spot * (extent - 2.0 * margin);
            // Voxel-space bounds, one voxel wider than needed: the kernel
            // test decides, so rounding here never changes a value.
            let s = scale.as_dvec3();
            let bounds = IBox::covering(
                (centre - radius) / s - 1.0,
                (centre + radius) / s + 1.0,
                setup.dims,
            );
            boxes.push(bounds);
            if let Some(bounds) = bounds {
                let r2 = (radius * radius) as f32;
                balls.push(Ball {
                    centre: centre.as_vec3(),
                    radius2: r2,
                    inv_radius2: 1.0 / r2,
                    bounds,
                });
            }
        }
        boxes.retain(Option::is_some);
        let cell = (size * 1.5 / scale.min_element() as f64).ceil() as u32;
        let bins = Bins::new(setup.dims, &boxes, cell);
        Ok(Metaballs { balls, bins, scale })
    }
}

impl Field for Metaballs {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        let ids = self.bins.query(region);
        if ids.is_empty() {
            return;
        }
        let mut density = vec![0f32; region.row_len()];
        region.for_each_row(out, |x, y, row| {
            density.fill(0.0);
            let mut any = false;
            for &id in &ids {
                let ball = &self.balls[id as usize];
                let b = ball.bounds;
                if x < b.lo.x || x > b.hi.x || y < b.lo.y || y > b.hi.y {
                    continue;
                }
                let dx = x as f32 * self.scale.x - ball.centre.x;
                let dy = y as f32 * self.scale.y - ball.centre.y;
                let dxy2 = dx * dx + dy * dy;
                if dxy2 >= ball.radius2 {
                    continue;
                }
                let z0 = b.lo.z.max(region.lo.z);
                let z1 = b.hi.z.min(region.hi.z - 1);
                for z in z0..=z1 {
                    let dz = z as f32 * self.scale.z - ball.centre.z;
                    let a = (dxy2 + dz * dz) * ball.inv_radius2;
                    if a < 1.0 {
                        density[(z - region.lo.z) as usize] += kernel(a);
                        any = true;
                    }
                }
            }
            if any {
                for (v, d) in row.iter_mut().zip(&density) {
                    *v = to_u8(d * 256.0);
                }
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
    fn kernel_is_one_half_at_half_radius() {
        assert!((kernel(0.0) - 1.0).abs() < 1e-6);
        assert!((kernel(0.25) - 0.5).abs() < 1e-6);
        assert!(kernel(1.0).abs() < 1e-6);
    }

    #[test]
    fn blobs_reach_the_iso_level_and_do_not_depend_on_the_region() {
        let dims = UVec3::new(30, 25, 20);
        let m = Metaballs::new(&Setup {
            n_of_shapes: Some(6),
            ..Setup::new(dims, 3)
        })
        .unwrap();
        let data = render(&m, dims);
        assert!(data.iter().any(|&v| v > 128));
        assert!(data.contains(&0));
        assert_region_independent(&m, dims);
    }
}

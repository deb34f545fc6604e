//! `shapes`: the benchmark data (see the README). N random spheres and
//! axis-aligned cuboids of about `--object-size` voxels, each filled with one
//! value drawn uniformly from `--sample − 8 ..= --sample + 8`. Under the
//! `shapes` transfer function (steps at 85, 95, 100, 115) that gives nearly
//! transparent red shapes (< 95), translucent blue ones (95..100) and opaque
//! green ones (>= 100). Where shapes overlap, the later one wins.
//!
//! Shapes are painted row by row: for a row `(x, y)` a sphere covers one run
//! of z, found with one square root, and a cuboid covers a fixed run, so the
//! cost per voxel is a `memset` no matter how many shapes there are.

use glam::{DVec3, UVec3};

use super::bins::Bins;
use super::{Field, IBox, Region, Setup};

/// Default `--n-of-shapes`.
pub const DEFAULT_COUNT: u32 = 20;
/// Default `--object-size`.
pub const DEFAULT_SIZE: u32 = 32;
/// Default `--sample`.
pub const DEFAULT_SAMPLE: u8 = 100;
/// Shape values lie within this distance of `--sample`.
pub const SPREAD: i32 = 8;

#[derive(Debug, Clone, Copy)]
enum Kind {
    Sphere { centre: DVec3, radius2: f64 },
    Cuboid,
}

/// One shape: the voxels it covers lie in `bounds`.
#[derive(Debug, Clone, Copy)]
struct Shape {
    kind: Kind,
    bounds: IBox,
    value: u8,
}

/// The `shapes` generator.
#[derive(Debug)]
pub struct Shapes {
    shapes: Vec<Shape>,
    bins: Bins,
}

impl Shapes {
    /// Draws the shapes from `setup.seed`.
    pub fn new(setup: &Setup) -> Result<Self, String> {
        let n = super::object_count(setup, DEFAULT_COUNT)?;
        let size = super::object_size(setup, DEFAULT_SIZE as f64)?;
        let sample = setup.sample.unwrap_or(DEFAULT_SAMPLE) as i32;
        let dims = setup.dims;
        let max = (dims - UVec3::ONE).as_dvec3();
        let mut rng = fastrand::Rng::with_seed(setup.seed);
        let mut shapes = Vec::with_capacity(n as usize);
        let mut boxes = Vec::with_capacity(n as usize);
        for _ in 0..n {
            // Draw the same numbers in the same order for either kind, so
            // one shape's kind never shifts the others.
            let sphere = rng.bool();
            let extent = DVec3::new(rng.f64(), rng.f64(), rng.f64()) * size + 0.5 * size;
            let spot = DVec3::new(rng.f64(), rng.f64(), rng.f64());
            let value = (sample + rng.i32(-SPREAD..=SPREAD)).clamp(1, 255) as u8;
            let half = if sphere {
                DVec3::splat(extent.x / 2.0)
            } else {
                extent / 2.0
            };
            // Centres such that the shape fits when the volume is big enough.
            let room = (max - 2.0 * half).max(DVec3::ZERO);
            let centre = DVec3::select(room.cmpgt(DVec3::ZERO), half + spot * room, spot * max);
            let bounds = IBox::covering(centre - half, centre + half, dims);
            let kind = if sphere {
                Kind::Sphere {
                    centre,
                    radius2: half.x * half.x,
                }
            } else {
                Kind::Cuboid
            };
            boxes.push(bounds);
            if let Some(bounds) = bounds {
                shapes.push(Shape {
                    kind,
                    bounds,
                    value,
                });
            }
        }
        boxes.retain(Option::is_some);
        let bins = Bins::new(dims, &boxes, size.ceil() as u32);
        Ok(Shapes { shapes, bins })
    }

    /// Number of shapes that cover at least one voxel.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// True when no shape covers a voxel.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }
}

impl Field for Shapes {
    fn fill(&self, region: &Region, out: &mut [u8]) {
        for id in self.bins.query(region) {
            let shape = &self.shapes[id as usize];
            let Some(b) = region.clip(&shape.bounds) else {
                continue;
            };
            for x in b.lo.x..=b.hi.x {
                for y in b.lo.y..=b.hi.y {
                    let (z0, z1) = match shape.kind {
                        Kind::Cuboid => (b.lo.z, b.hi.z),
                        Kind::Sphere { centre, radius2 } => {
                            let dx = x as f64 - centre.x;
                            let dy = y as f64 - centre.y;
                            let rest = radius2 - dx * dx - dy * dy;
                            if rest < 0.0 {
                                continue;
                            }
                            // The run depends only on the row, not on the region.
                            let h = rest.sqrt();
                            let lo = (centre.z - h).ceil().max(b.lo.z as f64);
                            let hi = (centre.z + h).floor().min(b.hi.z as f64);
                            if lo > hi {
                                continue;
                            }
                            (lo as u32, hi as u32)
                        }
                    };
                    let start = region.row_start(x, y);
                    let (z0, z1) = ((z0 - region.lo.z) as usize, (z1 - region.lo.z) as usize);
                    out[start + z0..=start + z1].fill(shape.value);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn setup(dims: UVec3, n: u32, size: u32) -> Setup {
        Setup {
            n_of_shapes: Some(n),
            object_size: Some(size),
            sample: Some(100),
            ..Setup::new(dims, 7)
        }
    }

    #[test]
    fn values_are_near_the_sample_and_cover_all_three_tf_classes() {
        let dims = UVec3::new(96, 80, 64);
        let shapes = Shapes::new(&setup(dims, 40, 16)).unwrap();
        let data = render(&shapes, dims);
        let mut seen = [false; 256];
        for &v in &data {
            seen[v as usize] = true;
        }
        assert!(seen[0], "background");
        for (v, &s) in seen.iter().enumerate().skip(1) {
            if s {
                assert!((92..=108).contains(&v), "value {v}");
            }
        }
        assert!(
            seen[92..95].iter().any(|&s| s),
            "a nearly transparent shape"
        );
        assert!(seen[95..100].iter().any(|&s| s), "a translucent shape");
        assert!(seen[100..109].iter().any(|&s| s), "an opaque shape");
    }

    #[test]
    fn shapes_fit_inside_the_volume() {
        let dims = UVec3::new(120, 100, 90);
        let shapes = Shapes::new(&setup(dims, 30, 20)).unwrap();
        assert_eq!(shapes.len(), 30);
        for s in &shapes.shapes {
            // Extents up to 1.5 × 20 voxels fit in every axis, so no shape
            // touches the volume's faces.
            assert!(s.bounds.lo.cmpgt(UVec3::ZERO).all(), "{:?}", s.bounds);
            assert!(s.bounds.hi.cmplt(dims - UVec3::ONE).all(), "{:?}", s.bounds);
        }
    }

    #[test]
    fn a_voxel_gets_the_same_value_in_any_region() {
        let dims = UVec3::new(23, 17, 11);
        let shapes = Shapes::new(&setup(dims, 12, 9)).unwrap();
        assert_region_independent(&shapes, dims);
    }

    #[test]
    fn spheres_are_round() {
        let dims = UVec3::splat(41);
        let mut spheres = 0;
        for seed in 0..6 {
            let shapes = Shapes::new(&Setup {
                seed,
                ..setup(dims, 1, 30)
            })
            .unwrap();
            let Kind::Sphere { centre, radius2 } = shapes.shapes[0].kind else {
                continue;
            };
            spheres += 1;
            let data = render(&shapes, dims);
            for (i, &v) in data.iter().enumerate() {
                let p = DVec3::new(
                    (i / (41 * 41)) as f64,
                    (i / 41 % 41) as f64,
                    (i % 41) as f64,
                );
                let d2 = (p - centre).length_squared();
                if (d2 - radius2).abs() > 1e-6 {
                    assert_eq!(v != 0, d2 < radius2, "{p}");
                }
            }
        }
        assert!(spheres > 0);
    }
}

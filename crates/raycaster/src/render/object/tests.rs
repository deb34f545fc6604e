//! Brick ranges and footprints against brute force.

use glam::{UVec3, Vec3};

use super::bricks::{BrickSet, exact_range, sample_range};
use super::footprint::footprint;
use crate::camera::{Camera, Projection};
use crate::geometry::{Aabb, Ray};
use crate::integrator::RaySegment;
use crate::volume::Grid;

fn random_unit(rng: &mut fastrand::Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.f32() * 2.0 - 1.0,
            rng.f32() * 2.0 - 1.0,
            rng.f32() * 2.0 - 1.0,
        );
        if let Some(u) = v.try_normalize() {
            // Now and then an axis-aligned or axis-parallel-plane ray.
            return match rng.u32(0..8) {
                0 => Vec3::new(u.x, 0.0, 0.0).try_normalize().unwrap_or(Vec3::X),
                1 => Vec3::new(u.x, u.y, 0.0).try_normalize().unwrap_or(Vec3::Y),
                _ => u,
            };
        }
    }
}

/// Every sample index of random rays falls in exactly one brick's range,
/// the brick that holds its computed position, and along the ray the
/// bricks come in increasing front-to-back key.
#[test]
fn brick_ranges_partition_every_ray() {
    let mut rng = fastrand::Rng::with_seed(5);
    for trial in 0..300 {
        let dims = UVec3::new(rng.u32(2..70), rng.u32(2..70), rng.u32(1..70));
        let spacing = Vec3::new(0.5 + rng.f32(), 0.5 + rng.f32(), 0.5 + rng.f32());
        let grid = Grid::new(dims, spacing);
        let side = rng.u32(1..24);
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(side) };
        let set = BrickSet {
            side,
            count: UVec3::new(n(dims.x), n(dims.y), n(dims.z)),
            visible: Vec::new(),
        };
        let ext = grid.extent();
        let inside = trial % 3 == 0;
        let origin = if inside {
            Vec3::new(rng.f32(), rng.f32(), rng.f32()) * ext
        } else {
            ext * 0.5 + random_unit(&mut rng) * (ext.length() + 5.0)
        };
        // Aim at a random point of the box (or a face plane now and then).
        let mut target = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * ext;
        if trial % 5 == 1 {
            target.x = 0.0;
        }
        let dir = if inside {
            random_unit(&mut rng)
        } else {
            (target - origin).try_normalize().unwrap_or(Vec3::Z)
        };
        let ray = Ray { origin, dir };
        let step = [0.05, 0.2, 0.37, 1.0][rng.usize(0..4)];
        let Some(seg) = RaySegment::new(&grid, &ray, step) else {
            continue;
        };
        let mut owner = vec![u32::MAX; seg.count as usize];
        let mut bricks = Vec::new();
        for bx in 0..set.count.x {
            for by in 0..set.count.y {
                for bz in 0..set.count.z {
                    let b = UVec3::new(bx, by, bz);
                    let r = set.region(b);
                    let (k0, k1) = sample_range(&seg, &r);
                    assert_eq!(
                        (k0 < k1).then_some((k0, k1)),
                        {
                            let (e0, e1) = exact_range(&seg, &r);
                            (e0 < e1).then_some((e0, e1))
                        },
                        "fast and exact ranges differ"
                    );
                    if k0 >= k1 {
                        continue;
                    }
                    bricks.push((k0, b));
                    for k in k0..k1 {
                        assert_eq!(
                            owner[k as usize],
                            u32::MAX,
                            "sample {k} in two bricks (trial {trial})"
                        );
                        owner[k as usize] = bx * 10000 + by * 100 + bz;
                        let p = seg.pos(k);
                        let want = UVec3::new(
                            set.brick_of(p.x, set.count.x),
                            set.brick_of(p.y, set.count.y),
                            set.brick_of(p.z, set.count.z),
                        );
                        assert_eq!(want, b, "sample {k} at {p} assigned to the wrong brick");
                    }
                }
            }
        }
        assert!(
            owner.iter().all(|&o| o != u32::MAX),
            "trial {trial}: a sample in no brick"
        );
        // Front-to-back: keys strictly increase along the ray.
        bricks.sort_by_key(|&(k0, _)| k0);
        let eye = grid.world_to_voxel(origin);
        let key = |b: UVec3| -> i64 {
            (0..3)
                .map(|a| (b[a] as i64 - set.brick_of(eye[a], set.count[a]) as i64).abs())
                .sum()
        };
        for w in bricks.windows(2) {
            assert!(key(w[0].1) < key(w[1].1), "order broken at {:?}", w);
        }
    }
}

/// Every pixel whose ray hits a box lies in the box's footprint, for
/// cameras outside, beside and inside the box, in both projections.
#[test]
fn footprints_hold_every_hitting_pixel() {
    let mut rng = fastrand::Rng::with_seed(9);
    let mut full = 0;
    for n in 0..400 {
        let lo = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 10.0 - 5.0;
        let b = Aabb::new(
            lo,
            lo + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 4.0 + 0.1,
        );
        let pos = match n % 3 {
            0 => b.center() + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5) * 2.0,
            _ => Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 24.0 - 12.0,
        };
        let target = pos + random_unit(&mut rng);
        let mut cam = Camera::look_at(pos, target, 48, 36);
        cam.fov_y_deg = 20.0 + rng.f32() * 120.0;
        if n % 4 == 3 {
            cam.projection = Projection::Orthographic;
        }
        let Some(f) = cam.frame() else { continue };
        let fp = footprint(&f, &cam, &b);
        if fp.is_some_and(|r| r.area() == 48 * 36) {
            full += 1;
        }
        for j in 0..36 {
            for i in 0..48 {
                if b.intersect(&f.ray(i, j)).is_some() {
                    let r = fp.unwrap_or_else(|| {
                        panic!("pixel {i},{j} hits {b:?} but no footprint ({cam:?})")
                    });
                    assert!(r.contains(i, j), "pixel {i},{j} outside {r:?} ({cam:?})");
                }
            }
        }
    }
    // Most boxes are not around the eye: footprints are usually partial.
    assert!(full < 250, "{full} full-screen footprints");
}

//! Camera projection: a bright voxel lands on the pixel the camera's ray
//! formula projects it to, for random perspective and orthographic cameras,
//! and the image's orientation.

mod common;

use common::rays::random_unit;
use common::reference::{RefCamera, RefProjection};
use common::scenes::{opts, render, u8_volume};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

/// One bright voxel at a known world position shows up at the pixel given by
/// projecting it with the camera's ray formula (computed independently in the
/// reference), for perspective and orthographic cameras: the brightest pixel
/// is within one pixel of it and the intensity centroid within 0.35 px.
#[test]
fn a_bright_voxel_lands_on_the_projected_pixel() {
    let spacing = Vec3::new(1.0, 0.75, 1.5);
    let voxel = UVec3::new(25, 14, 20);
    let scene = Scene::new(u8_volume([41, 33, 37], spacing, |v| {
        if v == voxel { 255 } else { 0 }
    }));
    let world = scene.grid().voxel_to_world(voxel.as_vec3());
    let w = [world.x as f64, world.y as f64, world.z as f64];
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let centre = scene.grid().bounds().center();
    let mut rng = fastrand::Rng::with_seed(77);
    let mut n = 0;
    while n < 24 {
        let pos = centre + random_unit(&mut rng) * (45.0 + rng.f32() * 15.0);
        let target = centre + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5) * 10.0;
        let up = if rng.bool() {
            Vec3::Y
        } else {
            random_unit(&mut rng)
        };
        let ortho = n % 3 == 2;
        let mut cam = Camera::look_at(pos, target, 64 + 8 * (n % 3), 56);
        cam.up = up;
        cam.fov_y_deg = 12.0 + rng.f32() * 8.0;
        if ortho {
            cam.projection = Projection::Orthographic;
        }
        if cam.frame().is_none() {
            continue;
        }
        let reference = RefCamera {
            position: [pos.x as f64, pos.y as f64, pos.z as f64],
            target: [target.x as f64, target.y as f64, target.z as f64],
            up: [up.x as f64, up.y as f64, up.z as f64],
            fov_deg: cam.fov_y_deg as f64,
            width: cam.width,
            height: cam.height,
            projection: if ortho {
                RefProjection::Orthographic
            } else {
                RefProjection::Perspective
            },
        };
        let in_front = (world - pos).dot((target - pos).normalize()) > 1.0;
        let (px, py) = reference.project(w);
        if !in_front
            || px < 4.0
            || py < 4.0
            || px > cam.width as f64 - 4.0
            || py > cam.height as f64 - 4.0
        {
            continue; // off screen for this random camera
        }
        n += 1;
        let frame = render(&scene, &cam, &tf, &opts(RenderMode::Mip, 0.05));
        let (mut best, mut arg) = (0u8, (0, 0));
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for j in 0..cam.height {
            for i in 0..cam.width {
                let v = frame.pixel(i, j)[0];
                if v > best {
                    best = v;
                    arg = (i, j);
                }
                let wgt = v as f64;
                sw += wgt;
                sx += wgt * (i as f64 + 0.5);
                sy += wgt * (j as f64 + 0.5);
            }
        }
        assert!(best > 100, "{cam:?}: voxel not visible");
        let (cx, cy) = (sx / sw, sy / sw);
        let near = (arg.0 as f64 + 0.5 - px).abs() <= 1.0 && (arg.1 as f64 + 0.5 - py).abs() <= 1.0;
        assert!(
            near,
            "{cam:?}: brightest pixel {arg:?}, projection ({px:.2}, {py:.2})"
        );
        assert!(
            (cx - px).abs() < 0.35 && (cy - py).abs() < 0.35,
            "{cam:?}: centroid ({cx:.2}, {cy:.2}), projection ({px:.2}, {py:.2})"
        );
    }
}

/// Orientation: i grows to the right (+r), j grows downwards (−u).
#[test]
fn image_orientation() {
    // Bright voxel at +x, +y of the centre, camera on +z looking −z, up +y:
    // it must appear right of and above the centre.
    let scene = Scene::new(u8_volume([21, 21, 21], Vec3::ONE, |v| {
        if v == UVec3::new(15, 14, 10) { 255 } else { 0 }
    }));
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let cam = Camera::look_at(Vec3::new(10.0, 10.0, 60.0), Vec3::splat(10.0), 41, 41);
    let frame = render(&scene, &cam, &tf, &opts(RenderMode::Mip, 0.1));
    let mut arg = (0, 0, 0u8);
    for j in 0..41 {
        for i in 0..41 {
            let v = frame.pixel(i, j)[0];
            if v > arg.2 {
                arg = (i, j, v);
            }
        }
    }
    assert!(arg.0 > 20 && arg.1 < 20, "brightest pixel {arg:?}");
}

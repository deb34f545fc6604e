//! Iso-surfaces: hits on an analytic sphere, its silhouette,
//! shading towards the rim, and iso hits and images that ESS leaves
//! unchanged.

mod common;

use common::rays::{RayLab, random_ray};
use common::scenes::{opts, render, tf_points, u8_volume};
use glam::{UVec3, Vec3};
use raycaster::geometry::Ray;
use raycaster::integrator::{Phong, ShadingCache};
use raycaster::prelude::*;

/// A sphere as a distance field: value 100 + 10·(R − |p − c|) in world
/// units, so the iso value 100 crosses exactly at radius R (up to the
/// trilinear interpolation of |p − c|, a few hundredths of a voxel).
struct Sphere {
    c: Vec3,
    r: f32,
}

impl Sphere {
    fn value(&self, p: Vec3) -> f32 {
        100.0 + 10.0 * (self.r - (p - self.c).length())
    }

    /// Analytic first intersection of a ray (unit dir) starting outside.
    fn hit(&self, ray: &Ray) -> Option<Vec3> {
        let oc = ray.origin - self.c;
        let b = oc.dot(ray.dir);
        let disc = b * b - (oc.length_squared() - self.r * self.r);
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t >= 0.0).then(|| ray.at(t))
    }

    /// Distance from the centre to the ray's line.
    fn miss_distance(&self, ray: &Ray) -> f32 {
        let oc = self.c - ray.origin;
        (oc - ray.dir * oc.dot(ray.dir)).length()
    }
}

#[test]
fn iso_hits_lie_on_the_analytic_sphere() {
    let spacing = Vec3::new(1.0, 0.8, 1.25);
    let dims = UVec3::new(41, 47, 33);
    let grid = Grid::new(dims, spacing);
    let sphere = Sphere {
        c: grid.bounds().center() + Vec3::new(1.3, -0.7, 0.4),
        r: 13.0,
    };
    let f32_scene = Scene::new(AnyVolume::from_fn(grid, |v| {
        sphere.value(grid.voxel_to_world(v.as_vec3()))
    }));
    let u8_scene = Scene::new(AnyVolume::from_fn(grid, |v| {
        sphere
            .value(grid.voxel_to_world(v.as_vec3()))
            .round()
            .clamp(0.0, 255.0) as u8
    }));
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let mut rng = fastrand::Rng::with_seed(42);
    let (lo, hi) = (grid.bounds().min, grid.bounds().max);
    // Per data type: worst radial error | |hit − c| − R | and worst error
    // along the ray times the cosine of the incidence angle (a value error
    // δ moves the hit by δ/(|∇v|·cos θ) along the ray).
    let mut radial = [0.0f32; 2];
    let mut along = [0.0f32; 2];
    let mut hits = 0;
    for step in [0.5f32, 0.9] {
        let labs_f = RayLab::iso(&f32_scene, &tf, step, 100.0);
        let labs_u = RayLab::iso(&u8_scene, &tf, step, 100.0);
        for _ in 0..1500 {
            let ray = random_ray(&mut rng, lo, hi, false);
            let d = sphere.miss_distance(&ray);
            let want = sphere.hit(&ray);
            for (i, got) in [labs_f.iso_hit(&ray, false).0, labs_u.iso_hit(&ray, false).0]
                .into_iter()
                .enumerate()
            {
                if d < sphere.r - 0.5 {
                    let (got, want) = (got.expect("ray must hit"), want.unwrap());
                    let cos = (1.0 - (d / sphere.r).powi(2)).sqrt();
                    radial[i] = radial[i].max(((got - sphere.c).length() - sphere.r).abs());
                    along[i] = along[i].max((got - want).length() * cos);
                    hits += 1;
                } else if d > sphere.r + 0.5 {
                    assert!(
                        got.is_none(),
                        "ray at distance {d} from the centre hit at {got:?}"
                    );
                }
            }
        }
    }
    println!(
        "iso sphere: {hits} hits; worst radial error f32 {:.4}, u8 {:.4}; along the ray ×cos θ f32 {:.4}, u8 {:.4} (world units)",
        radial[0], radial[1], along[0], along[1]
    );
    // f32 data: trilinear interpolation of the distance field (a few
    // hundredths) plus bisection to s/100. u8 data adds the rounding of the
    // values to integers (±0.5 value = ±0.05 world units).
    assert!(
        radial[0] < 0.05 && along[0] < 0.05,
        "f32 iso hits off the sphere"
    );
    assert!(
        radial[1] < 0.1 && along[1] < 0.1,
        "u8 iso hits off the sphere"
    );
    assert!(hits > 1000);
}

/// The iso image's silhouette is the sphere's: a pixel is lit exactly when
/// its ray meets the sphere (pixels whose ray passes within a few hundredths
/// of the rim excepted).
#[test]
fn iso_silhouette_matches_the_sphere() {
    let grid = Grid::new(UVec3::new(40, 36, 44), Vec3::ONE);
    let sphere = Sphere {
        c: Vec3::new(19.2, 17.6, 21.0),
        r: 12.5,
    };
    let scene = Scene::new(AnyVolume::from_fn(grid, |v| sphere.value(v.as_vec3())));
    let tf = tf_points(
        Interpolation::Linear,
        &[(0.0, [1.0, 0.5, 0.0], 1.0), (200.0, [1.0, 0.5, 0.0], 1.0)],
    );
    for (pos, projection) in [
        (Vec3::new(50.0, 40.0, 80.0), Projection::Perspective),
        (Vec3::new(-30.0, 10.0, -40.0), Projection::Orthographic),
    ] {
        let mut cam = Camera::look_at(pos, sphere.c, 80, 64);
        cam.projection = projection;
        cam.fov_y_deg = 35.0;
        let frame_cam = cam.frame().unwrap();
        for ess in [false, true] {
            let o = RenderOptions {
                iso_value: 100.0,
                ess,
                background: Vec3::new(0.0, 0.0, 1.0),
                ..opts(RenderMode::Iso, 0.5)
            };
            let frame = render(&scene, &cam, &tf, &o);
            let mut lit = 0;
            for j in 0..cam.height {
                for i in 0..cam.width {
                    let ray = frame_cam.ray(i, j);
                    let d = sphere.miss_distance(&ray);
                    let px = frame.pixel(i, j);
                    if d < sphere.r - 0.05 {
                        assert_eq!(px, [255, 128, 0], "{projection:?} ({i}, {j}) ess {ess}");
                        lit += 1;
                    } else if d > sphere.r + 0.05 {
                        assert_eq!(px, [0, 0, 255], "{projection:?} ({i}, {j}) ess {ess}");
                    }
                }
            }
            assert!(lit > 500, "{lit}");
        }
    }
}

/// Shading (compared only qualitatively): on an iso sphere seen from the
/// front with a headlight, the pixel facing the camera is the brightest and
/// brightness falls towards the rim; shading changes the image.
#[test]
fn shading_darkens_towards_the_rim() {
    let grid = Grid::new(UVec3::new(41, 41, 41), Vec3::ONE);
    let sphere = Sphere {
        c: Vec3::splat(20.0),
        r: 14.0,
    };
    let scene = Scene::new(AnyVolume::from_fn(grid, |v| sphere.value(v.as_vec3())));
    let tf = tf_points(
        Interpolation::Linear,
        &[(0.0, [0.6; 3], 1.0), (300.0, [0.6; 3], 1.0)],
    );
    let mut cam = Camera::look_at(Vec3::new(20.0, 20.0, 120.0), sphere.c, 65, 65);
    cam.fov_y_deg = 20.0;
    let o = RenderOptions {
        iso_value: 100.0,
        ..opts(RenderMode::Iso, 0.5)
    };
    let flat = render(&scene, &cam, &tf, &o);
    let lit = render(&scene, &cam, &tf, &RenderOptions { shading: true, ..o });
    assert_ne!(flat.rgb, lit.rgb);
    // Along the centre row, from the centre to the rim.
    let row: Vec<u8> = (32..65)
        .map(|i| lit.pixel(i, 32)[0])
        .take_while(|&v| v > 0)
        .collect();
    assert!(row.len() > 10, "{row:?}");
    let centre = row[0];
    let rim = *row.last().unwrap();
    assert!(
        centre > 150 && rim + 60 < centre,
        "centre {centre}, rim {rim}: {row:?}"
    );
    for w in row.windows(2) {
        assert!(
            w[1] <= w[0] + 2,
            "brightness rises towards the rim: {row:?}"
        );
    }
    assert_eq!(flat.pixel(32, 32), [153; 3]);
}

/// The tile loop's normal cache (the corner differences of the last hit's
/// cell, reused while the next hits fall in the same cell) changes no
/// colour: rays swept across a bumpy surface like a tile's pixels, where
/// consecutive hits share cells and leave them, resolve to the same bits
/// with the cache carried along as without it.
#[test]
fn the_normal_cache_changes_no_colour() {
    let grid = Grid::new(UVec3::new(24, 21, 19), Vec3::new(1.0, 1.2, 0.9));
    let c = grid.bounds().center();
    // A sphere with ripples, so the gradient varies inside every cell.
    let scene = Scene::new(AnyVolume::from_fn(grid, |v| {
        let p = grid.voxel_to_world(v.as_vec3());
        100.0 + 10.0 * (8.0 - (p - c).length()) + 3.0 * (1.7 * p.x).sin() * (1.3 * p.y).cos()
    }));
    let tf = tf_points(
        Interpolation::Linear,
        &[(0.0, [0.6, 0.5, 0.4], 1.0), (300.0, [0.6, 0.5, 0.4], 1.0)],
    );
    let lab = RayLab::iso(&scene, &tf, 0.5, 100.0).shaded(Phong::default());
    // Two grazing lights with shadow rays: the cache also keeps the shadow
    // rays' directions.
    let lights = [
        Vec3::new(1.0, 0.2, 0.3).normalize(),
        Vec3::new(-0.3, 1.0, 0.25).normalize(),
    ];
    let shadowed = RayLab::iso(&scene, &tf, 0.5, 100.0)
        .shaded(Phong::default())
        .lit(&lights, true);
    let unshadowed = RayLab::iso(&scene, &tf, 0.5, 100.0)
        .shaded(Phong::default())
        .lit(&lights, false);
    let mut cache = ShadingCache::default();
    let (mut lit_cache, mut spare) = (cache, cache);
    let (mut hits, mut shared, mut in_shadow) = (0, 0, 0);
    let eye = c + Vec3::new(3.0, 5.0, 60.0);
    let mut last = None;
    let same_bits = |a: glam::Vec4, b: glam::Vec4| {
        assert_eq!(
            a.to_array().map(f32::to_bits),
            b.to_array().map(f32::to_bits)
        );
    };
    for j in 0..40 {
        for i in 0..40 {
            let target = c + Vec3::new(i as f32 - 20.0, j as f32 - 20.0, 0.0) * 0.45;
            let ray = Ray {
                origin: eye,
                dir: (target - eye).normalize(),
            };
            let Some((fresh, cached)) = lab.iso_colours(&ray, &mut cache) else {
                continue;
            };
            same_bits(fresh, cached);
            let (lit_fresh, lit_cached) = shadowed.iso_colours(&ray, &mut lit_cache).unwrap();
            same_bits(lit_fresh, lit_cached);
            let (open, _) = unshadowed.iso_colours(&ray, &mut spare).unwrap();
            if fresh.w > 0.0 {
                hits += 1;
                let rgb = fresh.truncate();
                shared += (last == Some(rgb)) as u32;
                last = Some(rgb);
                in_shadow += (open != lit_fresh) as u32;
            }
        }
    }
    // Enough hits, and colours varying from ray to ray (so the gradients
    // do: a cache that always returned its first cell would fail above);
    // some hits shadowed from a light, some not.
    assert!(hits > 400, "{hits} hits");
    assert!(shared < hits / 2, "{shared} of {hits} colours repeat");
    assert!(
        in_shadow > 0 && in_shadow < hits,
        "{in_shadow} of {hits} hits in shadow"
    );
}

// -------------------------------------------------------------- iso with ESS

/// As above for iso: hits with ESS on are the hits with ESS off.
#[test]
fn ess_changes_no_iso_hit_on_random_rays() {
    let (grid, f) = common::phantom_on_grid([37, 29, 41], Vec3::new(1.0, 1.5, 0.75));
    let lin = Scene::new(AnyVolume::from_fn(grid, f));
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let mut rng = fastrand::Rng::with_seed(10);
    let (lo, hi) = (grid.bounds().min, grid.bounds().max);
    let mut bad = Vec::new();
    for iso in [60.5f32, 100.0, 180.0] {
        for step in [0.37f32, 1.1] {
            let lab = RayLab::iso(&lin, &tf, step, iso);
            for i in 0..1500 {
                let ray = random_ray(&mut rng, lo, hi, i % 4 == 0);
                let (a, _) = lab.iso_hit(&ray, false);
                let (b, _) = lab.iso_hit(&ray, true);
                if a != b {
                    bad.push((iso, step, ray, a, b));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{} rays with different iso hits with ESS on, e.g. {:?}",
        bad.len(),
        &bad[..bad.len().min(3)]
    );
}

/// LIBRARY BUG (ESS must change nothing): in iso mode with ESS
/// on, when a ray's *first* sample lies in an empty macrocell whose empty box
/// the ray leaves within one step, `IsoState::integrate` neither takes that
/// sample nor records it as the previous one (it only visits the first sample
/// of an empty run when `prev` is set, and the last one when it differs from
/// the first). A crossing between samples 0 and 1 is then missed: the ray
/// shows the background, or hits the surface's far side.
///
/// Data: value 0 for x <= 8, 255 for x >= 9 (iso 128 crosses at x = 8.5);
/// macrocells of 8 voxels make cell x = 0 empty. The ray enters the face
/// z = 0 at x = 7.9 going (0.8, 0, 0.6): sample 0 (x = 7.9, value 0) is in
/// the empty cell and exits it after 0.125 < step = 1; sample 1 (x = 8.7,
/// value 178.5) is past the surface.
#[test]
fn iso_with_ess_finds_a_crossing_right_after_the_first_sample() {
    let scene = Scene::with_macrocell(
        u8_volume([17, 17, 17], Vec3::ONE, |v| if v.x <= 8 { 0 } else { 255 }),
        8,
    );
    assert_eq!(scene.macrocells().cell, 8);
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let lab = RayLab::iso(&scene, &tf, 1.0, 128.0);
    let dir = Vec3::new(0.8, 0.0, 0.6);
    let ray = Ray {
        origin: Vec3::new(7.9, 4.0, 0.0) - dir * 10.0,
        dir,
    };
    let (off, _) = lab.iso_hit(&ray, false);
    let off = off.expect("without ESS the ray hits the surface");
    assert!((off.x - 8.5).abs() < 0.02, "{off}");
    let (on, _) = lab.iso_hit(&ray, true);
    assert_eq!(
        on,
        Some(off),
        "with ESS on the iso hit is lost (ESS must change nothing)"
    );
}

/// The same bug seen in a rendered image: a strip of rays entering the z = 0
/// face just before the empty cell's edge shows background with ESS on.
#[test]
fn iso_image_is_the_same_with_and_without_ess() {
    let scene = Scene::new(u8_volume([17, 17, 17], Vec3::ONE, |v| {
        if v.x <= 8 { 0 } else { 255 }
    }));
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    // Looking from below z = 0, rays going +x, so they cross x = 8 soon after
    // entering the z = 0 face.
    let mut cam = Camera::look_at(
        Vec3::new(-6.0, 8.0, -12.0),
        Vec3::new(9.0, 8.0, 6.0),
        64,
        64,
    );
    cam.fov_y_deg = 50.0;
    let o = RenderOptions {
        iso_value: 128.0,
        background: Vec3::new(0.0, 0.0, 1.0),
        ..opts(RenderMode::Iso, 1.0)
    };
    let off = render(&scene, &cam, &tf, &o);
    let on = render(&scene, &cam, &tf, &RenderOptions { ess: true, ..o });
    let d = common::compare_images(&off.rgb, &on.rgb, 0);
    assert_eq!(d.over, 0, "iso image changes with ESS: {d}");
}

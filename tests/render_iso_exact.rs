//! Exact isosurfaces (SPEC §8): hits are the first crossing of the
//! trilinear interpolant (against an independent f64 root finder, and on
//! planes, which trilinear interpolation reproduces, against the analytic
//! answer) for several sample types and whatever the sampling step; thin
//! features between samples are found; renderers agree with lights and
//! shadows; a sphere's shadow on a plane falls where geometry says.

mod common;

use common::rays::{RayLab, random_ray};
use common::reference::{self as r, RefMode, RefOptions, RefTf, RefVolume};
use common::scenes::{opts, render, tf_points};
use glam::{DVec3, UVec3, Vec3};
use raycaster::geometry::Ray;
use raycaster::integrator::IsoNormals;
use raycaster::prelude::*;

fn white() -> TransferFunction {
    tf_points(
        Interpolation::Linear,
        &[(-1.0e6, [1.0; 3], 1.0), (1.0e6, [1.0; 3], 1.0)],
    )
}

/// The f64 reference volume of `field` on `grid` (origin 0, as the
/// library's `Grid::new`).
fn reference_volume(grid: &Grid, field: impl Fn(UVec3) -> f64) -> RefVolume {
    let d = grid.dims;
    RefVolume::from_fn(
        [d.x as usize, d.y as usize, d.z as usize],
        grid.spacing.as_dvec3().to_array(),
        1.0,
        |x, y, z| field(UVec3::new(x as u32, y as u32, z as u32)),
    )
}

/// The reference's first crossing of `iso` along `ray` (`tests/common/
/// reference.rs`: f64 steps of 1/32 spacing and bisection), voxel space.
fn reference_hit(vol: &RefVolume, grid: &Grid, ray: &Ray, iso: f64) -> Option<DVec3> {
    let opts = RefOptions {
        mode: RefMode::Iso(iso),
        step: 1.0,
        ert: None,
        background: [0.0; 3],
    };
    let o = ray.origin.as_dvec3().to_array();
    let d = ray.dir.as_dvec3().to_array();
    let hit = r::integrate(vol, &RefTf::shapes(), &opts, o, d).hit?;
    Some(DVec3::from_array(hit.1) / grid.spacing.as_dvec3())
}

/// Our hit for `ray`, voxel space.
fn our_hit(lab: &RayLab<'_>, grid: &Grid, ray: &Ray, ess: bool) -> Option<DVec3> {
    lab.iso_hit(ray, ess)
        .0
        .map(|w| grid.world_to_voxel(w).as_dvec3())
}

/// Compares our hits with the reference's on random rays; returns the
/// number of hits. `field` gives each voxel's value in f64 (what the
/// volume stores).
fn compare_with_reference(
    scene: &Scene,
    field: impl Fn(UVec3) -> f64,
    iso: f32,
    step: f32,
    rays: usize,
    seed: u64,
) -> usize {
    let grid = *scene.grid();
    let vol = reference_volume(&grid, &field);
    let tf = white();
    let lab = RayLab::iso(scene, &tf, step, iso);
    let mut rng = fastrand::Rng::with_seed(seed);
    let (lo, hi) = (grid.bounds().min, grid.bounds().max);
    let mut hits = 0;
    let mut worst = 0.0f64;
    for _ in 0..rays {
        let inside = rng.bool();
        let ray = random_ray(&mut rng, lo, hi, inside);
        let want = reference_hit(&vol, &grid, &ray, iso as f64);
        for ess in [true, false] {
            let got = our_hit(&lab, &grid, &ray, ess);
            match (want, got) {
                (Some(w), Some(g)) => {
                    worst = worst.max((w - g).length());
                    assert!(
                        (w - g).length() < 1e-3,
                        "hit {g} vs reference {w} (ess {ess}, ray {ray:?})"
                    );
                    hits += ess as usize;
                }
                (None, None) => {}
                (Some(w), None) => panic!("missed the crossing at {w} (ess {ess}, ray {ray:?})"),
                (None, Some(g)) => {
                    // Only a pair of crossings closer than the reference's
                    // 1/32-spacing steps may hide from it: then the field
                    // must really change side around our hit.
                    let dv = (ray.dir / grid.spacing).as_dvec3().normalize() * 2e-3;
                    let world = |p: DVec3| (p * grid.spacing.as_dvec3()).to_array();
                    let side = |p: DVec3| vol.value_at(world(p)) >= iso as f64;
                    assert_ne!(
                        side(g - dv),
                        side(g + dv),
                        "hit at {g} where the reference sees no crossing (ess {ess})"
                    );
                }
            }
        }
    }
    println!("{hits} hits, worst distance to the reference {worst:.2e} voxel");
    hits
}

#[test]
fn hits_on_sphere_and_torus_fields_match_an_f64_root_finder() {
    let spacing = Vec3::new(1.0, 0.8, 1.25);
    let grid = Grid::new(UVec3::new(37, 41, 29), spacing);
    let c = grid.bounds().center();
    let sphere = |v: UVec3| -> f32 {
        let p = grid.voxel_to_world(v.as_vec3());
        (p - c - Vec3::new(1.3, -0.7, 0.4)).length() - 11.0
    };
    let torus = |v: UVec3| -> f32 {
        let p = grid.voxel_to_world(v.as_vec3()) - c;
        let q = glam::Vec2::new(glam::Vec2::new(p.x, p.z).length() - 10.0, p.y);
        q.length() - 3.5
    };
    for (name, f) in [
        ("sphere", &sphere as &dyn Fn(UVec3) -> f32),
        ("torus", &torus),
    ] {
        let scene = Scene::new(AnyVolume::from_fn(grid, f));
        // The step does not matter to an exact search: a large one too.
        for step in [0.4f32, 3.0] {
            let hits = compare_with_reference(&scene, |v| f(v) as f64, 0.0, step, 600, 7);
            assert!(hits > 100, "{name}: only {hits} hits");
        }
    }
}

/// Trilinear interpolation reproduces a linear field, so the hits must lie
/// on the analytic plane; for integer sample types too.
#[test]
fn hits_on_a_linear_field_lie_on_the_plane_for_every_sample_type() {
    let dims = UVec3::new(30, 28, 26);
    let grid = Grid::new(dims, Vec3::new(1.0, 1.5, 0.75));
    let n = DVec3::new(4.0, 2.0, 1.0);
    let value = |v: UVec3| 4 * v.x + 2 * v.y + v.z; // 0..=199
    let iso = 100.5f32;
    let scenes = [
        (
            "u8",
            Scene::new(AnyVolume::from_fn(grid, |v| value(v) as u8)),
        ),
        (
            "i16",
            Scene::new(AnyVolume::from_fn(grid, |v| value(v) as i16 - 50)),
        ),
        (
            "u16",
            Scene::new(AnyVolume::from_fn(grid, |v| value(v) as u16 * 3)),
        ),
        (
            "f32",
            Scene::new(AnyVolume::from_fn(grid, |v| value(v) as f32 * 0.25)),
        ),
    ];
    let isos = [iso, iso - 50.0, iso * 3.0, iso * 0.25];
    let tf = white();
    let mut rng = fastrand::Rng::with_seed(3);
    for ((name, scene), iso) in scenes.iter().zip(isos) {
        let lab = RayLab::iso(scene, &tf, 2.5, iso);
        let mut hits = 0;
        for _ in 0..500 {
            let ray = random_ray(&mut rng, grid.bounds().min, grid.bounds().max, false);
            if let Some(p) = our_hit(&lab, &grid, &ray, true) {
                // Distance (voxels) to the plane n·p = 100.5.
                let d = (n.dot(p) - 100.5).abs() / n.length();
                assert!(d < 1e-3, "{name}: hit {p} is {d} voxel off the plane");
                hits += 1;
            }
        }
        assert!(hits > 100, "{name}: only {hits} hits");
    }
}

/// A sheet one voxel thick: value 1 on the plane x = 16, 0 elsewhere; the
/// iso value 0.5 crosses at x = 15.5 and 16.5. With a step of 4 voxels most
/// rays take no sample inside the sheet, yet every ray through it hits.
#[test]
fn a_thin_sheet_between_samples_is_found() {
    let grid = Grid::new(UVec3::splat(33), Vec3::ONE);
    let scene = Scene::new(AnyVolume::from_fn(grid, |v| (v.x == 16) as u8 as f32));
    let tf = white();
    let step = 4.0;
    let lab = RayLab::iso(&scene, &tf, step, 0.5);
    let mut rng = fastrand::Rng::with_seed(9);
    let (mut through, mut between) = (0, 0);
    for _ in 0..800 {
        let ray = random_ray(&mut rng, grid.bounds().min, grid.bounds().max, false);
        let Some((t0, t1)) = grid.bounds().intersect(&ray) else {
            continue;
        };
        let (x0, x1) = (ray.at(t0).x, ray.at(t1).x);
        if x0.min(x1) > 15.4 || x0.max(x1) < 16.6 {
            continue; // does not cross the whole sheet
        }
        through += 1;
        // Would a stepping search see the sheet? Only if a sample lands in
        // it (|x − 16| < 0.5).
        let samples = ((t1 - t0) / step) as u32 + 1;
        between +=
            (0..samples).all(|k| (ray.at(t0 + k as f32 * step).x - 16.0).abs() >= 0.5) as usize;
        let p = our_hit(&lab, &grid, &ray, true).expect("a ray through the sheet hits it");
        let want = if x0 < 16.0 { 15.5 } else { 16.5 };
        assert!((p.x - want).abs() < 1e-3, "hit {p}, want x = {want}");
    }
    assert!(
        through > 100 && between > 50,
        "{through} rays, {between} between samples"
    );
}

/// A sphere resting above a plane, as one distance field (their union).
struct SphereOnPlane {
    grid: Grid,
    centre: Vec3,
    radius: f32,
    floor: f32,
}

impl SphereOnPlane {
    fn new() -> Self {
        SphereOnPlane {
            grid: Grid::new(UVec3::new(49, 33, 49), Vec3::ONE),
            centre: Vec3::new(24.0, 20.0, 24.0),
            radius: 6.0,
            floor: 6.0,
        }
    }

    fn value(&self, p: Vec3) -> f32 {
        ((p - self.centre).length() - self.radius).min(p.y - self.floor)
    }

    fn scene(&self) -> Scene {
        Scene::new(AnyVolume::from_fn(self.grid, |v| {
            self.value(self.grid.voxel_to_world(v.as_vec3()))
        }))
    }
}

/// A perspective camera at `pos` looking at `at`, `w`×`h` pixels, with a
/// vertical field of view of `fov` degrees.
fn camera(pos: Vec3, at: Vec3, (w, h): (u32, u32), fov: f32) -> Camera {
    let mut cam = Camera::look_at(pos, at, w, h);
    cam.fov_y_deg = fov;
    cam
}

fn lit_options(lights: Vec<Vec3>, shadows: bool) -> RenderOptions {
    RenderOptions {
        iso_value: 0.0,
        shading: true,
        ess: true,
        lights,
        shadows,
        ..opts(RenderMode::Iso, 0.5)
    }
}

#[test]
fn renderers_agree_with_lights_and_shadows() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let tf = white();
    let cam = camera(Vec3::new(70.0, 55.0, 80.0), s.centre, (96, 80), 40.0);
    let o = lit_options(
        vec![Vec3::new(0.3, 1.0, 0.2), Vec3::new(-1.0, 0.5, 0.0)],
        true,
    );
    let serial = render(&scene, &cam, &tf, &o);
    for mut r in [
        Box::new(TiledRenderer::new(2, 16).expect("tiles")) as AnyRenderer,
        RendererKind::Object.renderer(2).expect("object"),
    ] {
        let f = r.render(&scene, &cam, &tf, &o).expect("render");
        let d = common::compare_images(&serial.rgb, &f.rgb, 0);
        assert_eq!(d.over, 0, "{} differs from serial: {d}", r.name());
    }
    // Without skipping the walk takes every cell, and primary and shadow
    // rays go one by one rather than in packets: the same hits.
    let no_ess = render(&scene, &cam, &tf, &RenderOptions { ess: false, ..o });
    let d = common::compare_images(&serial.rgb, &no_ess.rgb, 1);
    assert_eq!(d.over, 0, "ESS changes the image: {d}");
}

/// A headlight casts no shadow the eye can see (its shadow ray would
/// retrace the primary ray): with shadows on, every renderer gives the
/// image without them. (Shadow rays cast along the direction of a tile's
/// first hit darkened pixels near the sphere's silhouette, differently in
/// each renderer.)
#[test]
fn a_headlight_casts_no_shadow() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let tf = white();
    // Wide-angle, so that a tile's rays spread by several degrees.
    let cam = camera(
        Vec3::new(60.0, 20.0, 60.0),
        Vec3::new(24.0, 8.0, 24.0),
        (160, 120),
        70.0,
    );
    let without = render(&scene, &cam, &tf, &lit_options(Vec::new(), false));
    assert!(without.stats.covered > 2000, "{}", without.stats.covered);
    for mut r in [
        RendererKind::Serial.renderer(1).expect("serial"),
        Box::new(TiledRenderer::new(2, 7).expect("tiles")) as AnyRenderer,
        RendererKind::Object.renderer(2).expect("object"),
    ] {
        let f = r
            .render(&scene, &cam, &tf, &lit_options(Vec::new(), true))
            .expect("render");
        let d = common::compare_images(&without.rgb, &f.rgb, 0);
        assert_eq!(d.over, 0, "{}: {d}", r.name());
    }
}

/// Light straight from above: a point of the floor is in shadow exactly
/// when it lies under the sphere (within its radius of the centre's
/// vertical), away from a band of half a voxel around the rim.
#[test]
fn a_spheres_shadow_falls_under_it() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let tf = white();
    let cam = camera(
        Vec3::new(24.0, 60.0, 75.0),
        Vec3::new(24.0, 6.0, 24.0),
        (120, 100),
        45.0,
    );
    let frame_cam = cam.frame().expect("camera");
    let up = Vec3::Y;
    let with = render(&scene, &cam, &tf, &lit_options(vec![up], true));
    let without = render(&scene, &cam, &tf, &lit_options(vec![up], false));
    let (mut shadowed, mut lit) = (0, 0);
    for j in 0..cam.height {
        for i in 0..cam.width {
            let ray = frame_cam.ray(i, j);
            // Analytic first hit: the sphere, else the floor (inside the box).
            let oc = ray.origin - s.centre;
            let b = oc.dot(ray.dir);
            let disc = b * b - (oc.length_squared() - s.radius * s.radius);
            if disc > -1.0 {
                continue; // on or near the sphere
            }
            let t = (s.floor - ray.origin.y) / ray.dir.y;
            let q = ray.at(t);
            let inside_box = q.x > 1.0 && q.x < 47.0 && q.z > 1.0 && q.z < 47.0;
            if !(t > 0.0 && inside_box) {
                continue;
            }
            let r = glam::Vec2::new(q.x - s.centre.x, q.z - s.centre.z).length();
            let at = ((j * cam.width + i) * 3) as usize;
            let (a, b) = (with.rgb[at], without.rgb[at]);
            if r < s.radius - 0.5 {
                // Ambient only (0.3 of white), against fully lit.
                assert!(
                    a < 90 && b > 200,
                    "pixel {i},{j} at r = {r}: {a} with, {b} without"
                );
                shadowed += 1;
            } else if r > s.radius + 0.5 {
                assert_eq!(a, b, "pixel {i},{j} at r = {r} is shadowed");
                lit += 1;
            }
        }
    }
    assert!(
        shadowed > 50 && lit > 1000,
        "{shadowed} shadowed, {lit} lit pixels"
    );
}

/// A mirror floor (`--reflection 1`, unshaded) shows the sphere exactly
/// where the floor's mirrored ray meets it and the background elsewhere,
/// away from a band around the reflection's rim and the crease where the
/// sphere's field meets the floor's; lit and shadowed, every renderer
/// agrees.
#[test]
fn a_mirror_floor_shows_the_sphere_where_the_reflected_ray_meets_it() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let tf = white();
    let cam = camera(
        Vec3::new(24.0, 22.0, 75.0),
        Vec3::new(24.0, 8.0, 24.0),
        (120, 100),
        45.0,
    );
    let frame_cam = cam.frame().expect("camera");
    let background = Vec3::new(0.2, 0.4, 0.6);
    let o = RenderOptions {
        shading: false,
        reflection: 1.0,
        background,
        ..lit_options(vec![], false)
    };
    let mirror = render(&scene, &cam, &tf, &o);
    let bg = background.to_array().map(|c| (c * 255.0).round() as u8);
    let (mut sphere, mut sky) = (0, 0);
    for j in 0..cam.height {
        for i in 0..cam.width {
            let ray = frame_cam.ray(i, j);
            let oc = ray.origin - s.centre;
            let b = oc.dot(ray.dir);
            if b * b - (oc.length_squared() - s.radius * s.radius) > -1.0 {
                continue; // on or near the sphere itself
            }
            let t = (s.floor - ray.origin.y) / ray.dir.y;
            let q = ray.at(t);
            let inside_box = q.x > 1.0 && q.x < 47.0 && q.z > 1.0 && q.z < 47.0;
            if !(t > 0.0 && inside_box) || (q - s.centre).length() - s.radius < 3.0 {
                continue;
            }
            // The mirrored ray from the floor point.
            let r = Vec3::new(ray.dir.x, -ray.dir.y, ray.dir.z);
            let qc = q - s.centre;
            let b = qc.dot(r);
            let disc = b * b - (qc.length_squared() - s.radius * s.radius);
            let at = ((j * cam.width + i) * 3) as usize;
            let px = [mirror.rgb[at], mirror.rgb[at + 1], mirror.rgb[at + 2]];
            if disc > 1.0 && b < 0.0 {
                assert_eq!(px, [255; 3], "pixel {i},{j}: the sphere's reflection");
                sphere += 1;
            } else if disc < -1.0 {
                assert_eq!(px, bg, "pixel {i},{j}: the background's reflection");
                sky += 1;
            }
        }
    }
    assert!(
        sphere > 50 && sky > 1000,
        "{sphere} sphere, {sky} sky pixels"
    );
    // Lit and shadowed, every renderer gives the same image.
    let lit = RenderOptions {
        reflection: 0.4,
        background,
        ..lit_options(vec![Vec3::new(0.3, 1.0, 0.2)], true)
    };
    let serial = render(&scene, &cam, &tf, &lit);
    let mut object = RendererKind::Object.renderer(2).expect("object");
    let f = object.render(&scene, &cam, &tf, &lit).expect("render");
    let d = common::compare_images(&serial.rgb, &f.rgb, 0);
    assert_eq!(d.over, 0, "object differs from serial: {d}");
    // The reflection shows: the lit image differs from the one without.
    let plain = lit_options(vec![Vec3::new(0.3, 1.0, 0.2)], true);
    let d = common::compare_images(&serial.rgb, &render(&scene, &cam, &tf, &plain).rgb, 8);
    assert!(d.over > 1000, "the reflection changes too little: {d}");
    // Out of range is an error naming the option.
    let err = SerialRenderer::new()
        .render(
            &scene,
            &cam,
            &tf,
            &RenderOptions {
                reflection: 1.5,
                ..plain
            },
        )
        .expect_err("a reflection above 1 must be refused");
    assert!(err.to_string().contains("reflection"), "{err}");
}

#[test]
fn bad_lights_are_errors() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let cam = Camera::look_at(Vec3::new(70.0, 55.0, 80.0), s.centre, 16, 16);
    let o = lit_options(vec![Vec3::ZERO], true);
    let err = SerialRenderer::new()
        .render(&scene, &cam, &white(), &o)
        .expect_err("a zero light direction must be refused");
    assert!(err.to_string().contains("light"), "{err}");
}

/// On a linear field both normals are the plane's away from the volume's
/// faces (where SPEC §8's index-clamped differences are not): the two
/// settings give the same picture up to rounding inside a crop box that
/// keeps one voxel off the faces, and a curved field tells them apart.
#[test]
fn analytic_normals_agree_on_a_plane_and_differ_on_a_sphere() {
    let grid = Grid::new(UVec3::splat(24), Vec3::ONE);
    let cam = Camera::look_at(Vec3::new(40.0, 30.0, 50.0), Vec3::splat(11.5), 48, 48);
    let tf = white();
    let o = |normals| RenderOptions {
        iso_normals: normals,
        clip: raycaster::clip::Clip {
            clip_box: Some((Vec3::splat(1.0), Vec3::splat(22.0))),
            planes: Vec::new(),
        },
        ..lit_options(vec![Vec3::new(0.2, 1.0, 0.5)], false)
    };
    let plane = Scene::new(AnyVolume::from_fn(grid, |v| {
        v.x as f32 * 0.5 + v.y as f32 - 15.0
    }));
    let a = render(&plane, &cam, &tf, &o(IsoNormals::Gradient));
    let b = render(&plane, &cam, &tf, &o(IsoNormals::Analytic));
    assert_eq!(common::compare_images(&a.rgb, &b.rgb, 1).over, 0);
    let sphere = Scene::new(AnyVolume::from_fn(grid, |v| {
        (v.as_vec3() - Vec3::splat(11.5)).length() - 8.0
    }));
    let a = render(&sphere, &cam, &tf, &o(IsoNormals::Gradient));
    let b = render(&sphere, &cam, &tf, &o(IsoNormals::Analytic));
    assert!(common::compare_images(&a.rgb, &b.rgb, 1).over > 0);
}

/// The frame's proxy depths (where each pixel's walk starts, and which
/// pixels cannot hit) change nothing: with skipping the image and counts
/// equal those of the walk over every cell without it, from outside and
/// inside the volume, under both projections, with a clip box, and for
/// every renderer (which also checks the count of rays entering the box,
/// taken without tracing the culled rays of a tile whose corner rays all
/// enter it).
#[test]
fn starting_rays_at_the_proxy_depth_finds_the_same_hits() {
    let s = SphereOnPlane::new();
    let scene = s.scene();
    let tf = white();
    let inside = Vec3::new(40.0, 25.0, 44.0);
    let cameras = [
        (Vec3::new(70.0, 55.0, 80.0), Projection::Perspective, false),
        (
            Vec3::new(-30.0, 12.0, 20.0),
            Projection::Orthographic,
            false,
        ),
        (inside, Projection::Perspective, false),
        (Vec3::new(10.0, 70.0, -40.0), Projection::Perspective, true),
    ];
    for (pos, projection, clipped) in cameras {
        let mut cam = Camera::look_at(pos, s.centre, 90, 70);
        cam.projection = projection;
        let mut o = lit_options(vec![Vec3::new(0.3, 1.0, 0.2)], false);
        if clipped {
            o.clip.clip_box = Some((Vec3::new(0.0, 0.0, 0.0), Vec3::new(48.0, 32.0, 26.0)));
        }
        let walked = render(
            &scene,
            &cam,
            &tf,
            &RenderOptions {
                ess: false,
                ..o.clone()
            },
        );
        assert!(
            walked.stats.covered > 500,
            "{pos}: {}",
            walked.stats.covered
        );
        let mut renderers: Vec<AnyRenderer> = vec![
            RendererKind::Serial.renderer(1).expect("serial"),
            Box::new(TiledRenderer::new(2, 16).expect("tiles")),
            RendererKind::Object.renderer(2).expect("object"),
        ];
        for r in &mut renderers {
            let f = r.render(&scene, &cam, &tf, &o).expect("render");
            let d = common::compare_images(&walked.rgb, &f.rgb, 1);
            assert_eq!(d.over, 0, "{} from {pos} ({projection:?}): {d}", r.name());
            assert_eq!(f.stats.rays_in_volume, walked.stats.rays_in_volume, "{pos}");
            assert_eq!(f.stats.covered, walked.stats.covered, "{pos}");
            // The proxy starts the walks near the surface.
            assert!(f.stats.samples < walked.stats.samples, "{pos}");
        }
    }
}

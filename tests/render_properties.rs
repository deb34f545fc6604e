//! Properties of the renderer with analytic answers (SPEC §1–§5): opacity of
//! homogeneous media, MIP of known maxima, iso hits on a sphere, layout and
//! file independence, ERT/ESS tolerances, ESS sample counts, camera
//! projection, and the `.vol` reader's behaviour on good and bad files.

mod common;

use std::path::Path;

use common::TempFile;
use common::reference::{RefCamera, RefProjection};
use glam::{UVec3, Vec3};
use raycaster::accel::SkipGrid;
use raycaster::format::vol::{VolHeader, VolLayout};
use raycaster::geometry::Ray;
use raycaster::integrator::{DvrState, FrameContext, IsoState, MipState, RaySegment};
use raycaster::prelude::*;
use raycaster::scene::VolumeSource;
use raycaster::transfer::TfLut;

// ------------------------------------------------------------------ helpers

fn opts(mode: RenderMode, step: f32) -> RenderOptions {
    RenderOptions {
        mode,
        step: Some(step),
        ert: false,
        ess: false,
        shading: false,
        background: Vec3::ZERO,
        ..RenderOptions::default()
    }
}

fn render<V: VolumeSource>(
    scene: &Scene<V>,
    cam: &Camera,
    tf: &TransferFunction,
    o: &RenderOptions,
) -> Frame {
    SerialRenderer::new()
        .render(scene, cam, tf, o)
        .expect("render")
}

fn white_linear_tf(opacity: f32) -> TransferFunction {
    TransferFunction::new(
        Interpolation::Linear,
        vec![
            TfPoint {
                value: 0.0,
                color: [1.0; 3],
                opacity,
            },
            TfPoint {
                value: 255.0,
                color: [1.0; 3],
                opacity,
            },
        ],
    )
    .unwrap()
}

fn tf_points(interpolation: Interpolation, pts: &[(f32, [f32; 3], f32)]) -> TransferFunction {
    TransferFunction::new(
        interpolation,
        pts.iter()
            .map(|&(value, color, opacity)| TfPoint {
                value,
                color,
                opacity,
            })
            .collect(),
    )
    .unwrap()
}

fn u8_volume(dims: [u32; 3], spacing: Vec3, f: impl Fn(UVec3) -> u8) -> LinearVolume<u8> {
    LinearVolume::from_fn(Grid::new(UVec3::from_array(dims), spacing), f)
}

/// A camera looking straight down −z at (x, y) from height `z`, with an odd
/// image so the centre pixel's ray is exactly (0, 0, −1).
fn down_camera(x: f32, y: f32, z: f32, projection: Projection) -> Camera {
    let mut c = Camera::look_at(Vec3::new(x, y, z), Vec3::new(x, y, 0.0), 33, 33);
    c.projection = projection;
    c.fov_y_deg = 30.0;
    c
}

/// Every voxel of a u8 volume of any layout, in linear order.
fn voxels_u8(v: &AnyVolume) -> Vec<u8> {
    fn all<V: Volume<Sample = u8>>(v: &V) -> Vec<u8> {
        let d = v.grid().dims;
        let mut out = Vec::with_capacity(v.grid().voxel_count() as usize);
        for x in 0..d.x {
            for y in 0..d.y {
                for z in 0..d.z {
                    out.push(v.voxel(UVec3::new(x, y, z)));
                }
            }
        }
        out
    }
    match v {
        AnyVolume::LinearU8(v) => all(v),
        AnyVolume::BrickedU8(v) => all(v),
        other => panic!("expected a u8 volume, got {:?}", other.sample_type()),
    }
}

/// Integrates single rays with the library's integrators (the API renderers
/// are built from), for one volume, TF, step and mode.
struct RayLab<'a, V: Volume> {
    scene: &'a Scene<V>,
    tf: &'a TransferFunction,
    lut: TfLut,
    skip: SkipGrid,
    step: f32,
    iso: f32,
}

impl<'a, V: Volume> RayLab<'a, V> {
    fn dvr(scene: &'a Scene<V>, tf: &'a TransferFunction, step: f32) -> Self {
        let lut = TfLut::new(tf, step);
        let skip = SkipGrid::build(scene.macrocells(), |lo, hi| lut.any_visible(lo, hi));
        RayLab {
            scene,
            tf,
            lut,
            skip,
            step,
            iso: 0.0,
        }
    }

    fn iso(scene: &'a Scene<V>, tf: &'a TransferFunction, step: f32, iso: f32) -> Self {
        let lut = TfLut::new(tf, step);
        let skip = SkipGrid::build(scene.macrocells(), |lo, hi| lo <= iso && iso <= hi);
        RayLab {
            scene,
            tf,
            lut,
            skip,
            step,
            iso,
        }
    }

    fn ctx(&self, ess: bool) -> FrameContext<'_, V> {
        FrameContext {
            volume: self.scene.volume(),
            tf: self.tf,
            lut: &self.lut,
            macrocells: self.scene.macrocells(),
            skip: &self.skip,
            ess,
            ert: None,
            shading: None,
            iso_value: self.iso,
            avg_norm: 255.0,
        }
    }

    fn segment(&self, ray: &Ray) -> Option<RaySegment> {
        RaySegment::new(self.scene.volume().grid(), ray, self.step)
    }

    /// World-space iso hit, and the samples taken.
    fn iso_hit(&self, ray: &Ray, ess: bool) -> (Option<Vec3>, u64) {
        let Some(seg) = self.segment(ray) else {
            return (None, 0);
        };
        let mut st = IsoState::default();
        let n = st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        let grid = self.scene.volume().grid();
        (st.hit.map(|(p, _)| grid.voxel_to_world(p)), n)
    }

    fn dvr_state(&self, ray: &Ray, ess: bool) -> Option<(DvrState, u64)> {
        let seg = self.segment(ray)?;
        let mut st = DvrState::default();
        let n = st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        Some((st, n))
    }

    fn mip_max(&self, ray: &Ray, ess: bool) -> Option<f32> {
        let seg = self.segment(ray)?;
        let mut st = MipState::default();
        st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        Some(st.max)
    }
}

fn random_unit(rng: &mut fastrand::Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 2.0 - Vec3::ONE;
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

/// A random ray from outside (or, for `inside`, within) `bounds` aimed at a
/// random point of the box.
fn random_ray(rng: &mut fastrand::Rng, lo: Vec3, hi: Vec3, inside: bool) -> Ray {
    let pick = |rng: &mut fastrand::Rng| {
        Vec3::new(
            lo.x + rng.f32() * (hi.x - lo.x),
            lo.y + rng.f32() * (hi.y - lo.y),
            lo.z + rng.f32() * (hi.z - lo.z),
        )
    };
    let target = pick(rng);
    let origin = if inside {
        pick(rng)
    } else {
        (lo + hi) * 0.5 + random_unit(rng) * (hi - lo).length() * 1.5
    };
    Ray {
        origin,
        dir: (target - origin).normalize(),
    }
}

// ------------------------------------------------- §4/§5: opacity of media

/// Samples `t_in + k·s <= t_in + len` (k = 0, 1, …) on a chord of length `len`.
fn samples_on_chord(len: f64, s: f64) -> u32 {
    let mut n = 0;
    while n as f64 * s <= len + 1e-9 {
        n += 1;
    }
    n
}

/// A homogeneous volume (every voxel 100) with a white TF of constant opacity
/// `a`: the centre ray crosses L = 20 world units, takes n = floor(L/s) + 1
/// samples, each of opacity α = 1 − (1 − a)^s, so A = 1 − (1 − α)^n =
/// 1 − (1 − a)^(s·n), which exceeds the continuous 1 − (1 − a)^L by at most
/// (1 − a)^L·(1 − (1 − a)^s).
#[test]
fn homogeneous_medium_has_the_spec_opacity() {
    // Box [0, 32]² × [0, 20]; the camera at z = 100 gives t_in = 80, t_out = 100,
    // both exact in f32, so steps dividing 20 put the last sample on t_out.
    let scene = Scene::new(u8_volume([33, 33, 21], Vec3::ONE, |_| 100));
    let len = 20.0f64;
    let mut worst_cont = 0.0f64;
    for projection in [Projection::Perspective, Projection::Orthographic] {
        let cam = down_camera(16.0, 16.0, 100.0, projection);
        for a in [0.02f32, 0.05, 0.2, 0.5] {
            let tf = white_linear_tf(a);
            for s in [0.25f32, 0.3, 0.5, 0.7, 1.0, 1.3, 2.5, 3.0, 7.0] {
                let o = opts(RenderMode::Dvr, s);
                let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
                let (a64, s64) = (a as f64, s as f64);
                let n = samples_on_chord(len, s64);
                let alpha = 1.0 - (1.0 - a64).powf(s64);
                let expect = 1.0 - (1.0 - alpha).powi(n as i32);
                assert!(
                    ((1.0 - (1.0 - a64).powf(s64 * n as f64)) - expect).abs() < 1e-12,
                    "algebra"
                );
                for ch in px {
                    assert!(
                        (ch as f64 - 255.0 * expect).abs() <= 1.0,
                        "{projection:?} a {a} s {s}: n = {n}, expected A = {expect:.5} \
                         ({:.1}/255), pixel {px:?}",
                        255.0 * expect
                    );
                }
                // Approaches the continuous answer within the discretisation bound.
                let cont = 1.0 - (1.0 - a64).powf(len);
                let bound = (1.0 - a64).powf(len) * (1.0 - (1.0 - a64).powf(s64));
                let got = px[0] as f64 / 255.0;
                assert!(
                    got - cont >= -1.0 / 255.0 && got - cont <= bound + 1.0 / 255.0,
                    "a {a} s {s}: A = {got:.4}, continuous {cont:.4}, bound {bound:.4}"
                );
                if s <= 0.3 {
                    worst_cont = worst_cont.max((got - cont).abs());
                }
            }
        }
    }
    // At small steps the discrete answer is within ~1.5% of the continuous one.
    assert!(worst_cont < 0.015, "{worst_cont}");
}

/// ERT stops at the first sample where A >= threshold: with a homogeneous
/// medium that is A_k* = 1 − (1 − α)^k* for the first such k*.
#[test]
fn ert_stops_at_the_first_sample_over_the_threshold() {
    let scene = Scene::new(u8_volume([33, 33, 21], Vec3::ONE, |_| 100));
    let cam = down_camera(16.0, 16.0, 100.0, Projection::Perspective);
    let mut checked = 0;
    for a in [0.3f32, 0.5, 0.8] {
        let tf = white_linear_tf(a);
        for s in [0.3f32, 0.5, 1.0] {
            for thr in [0.5f32, 0.9, 0.99] {
                let alpha = 1.0 - (1.0 - a as f64).powf(s as f64);
                let n = samples_on_chord(20.0, s as f64);
                let acc = |k: u32| 1.0 - (1.0 - alpha).powi(k as i32);
                let k_stop = (1..=n).find(|&k| acc(k) >= thr as f64).unwrap_or(n);
                if (1..=n).any(|k| (acc(k) - thr as f64).abs() < 1e-4) {
                    continue; // some A_k too close to the threshold to call in f32
                }
                let o = RenderOptions {
                    ert: true,
                    ert_threshold: thr,
                    ..opts(RenderMode::Dvr, s)
                };
                let frame = render(&scene, &cam, &tf, &o);
                let px = frame.pixel(16, 16);
                let expect = 255.0 * acc(k_stop);
                assert!(
                    (px[0] as f64 - expect).abs() <= 1.0,
                    "a {a} s {s} thr {thr}: stop after {k_stop} samples, A = {expect:.1}/255, got {px:?}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 20);
}

/// A slab of value 200 for voxel z in [10, 20] (0 elsewhere) under a step TF
/// visible from 50: the interpolated value is >= 50 exactly for
/// z ∈ [9.25, 20.75], so the samples counted are those z_k = 30 − k·s in that
/// interval (boundaries included) and A = 1 − (1 − α)^count.
#[test]
fn slab_of_known_thickness() {
    let scene = Scene::new(u8_volume([17, 17, 31], Vec3::ONE, |v| {
        if (10..=20).contains(&v.z) { 200 } else { 0 }
    }));
    let a = 0.1f32;
    let tf = tf_points(
        Interpolation::Step,
        &[(50.0, [1.0; 3], a), (250.0, [0.0; 3], 0.0)],
    );
    for ess in [false, true] {
        for s in [0.25f32, 0.3, 0.5, 0.75, 1.0, 1.5] {
            let cam = down_camera(8.0, 8.0, 100.0, Projection::Perspective);
            let o = RenderOptions {
                ess,
                ..opts(RenderMode::Dvr, s)
            };
            let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
            let count = (0..)
                .map(|k| 30.0 - k as f64 * s as f64)
                .take_while(|&z| z >= 0.0)
                .filter(|&z| (9.25..=20.75).contains(&z))
                .count();
            let alpha = 1.0 - (1.0 - a as f64).powf(s as f64);
            let expect = 1.0 - (1.0 - alpha).powi(count as i32);
            assert!(
                (px[0] as f64 - 255.0 * expect).abs() <= 1.0,
                "s {s} ess {ess}: {count} samples in the slab, A = {expect:.4}, got {px:?}"
            );
            // 11.5 world units of medium.
            let cont = 1.0 - (1.0 - a as f64).powf(11.5);
            assert!(
                (px[0] as f64 / 255.0 - cont).abs() < 0.06,
                "s {s}: {px:?} vs {cont}"
            );
        }
    }
}

// ------------------------------------------------------------------ MIP

/// MIP shows TF(max) composited once, C = a·c and A = a, with no step
/// correction, whatever the step.
#[test]
fn mip_is_the_tf_of_the_maximum_composited_once() {
    // A single bright voxel: the centre ray of an orthographic camera passes
    // through it and a sample lands on it (z_k = 20 − k/2 hits 10).
    let scene = Scene::new(u8_volume([21, 21, 21], Vec3::ONE, |v| {
        if v == UVec3::splat(10) { 200 } else { 0 }
    }));
    let colour = [1.0, 0.5, 0.25];
    let tf = tf_points(
        Interpolation::Linear,
        &[(0.0, colour, 0.0), (255.0, colour, 1.0)],
    );
    let cam = down_camera(10.0, 10.0, 100.0, Projection::Orthographic);
    for ess in [false, true] {
        for s in [0.5f32, 0.25, 1.0] {
            let o = RenderOptions {
                ess,
                ..opts(RenderMode::Mip, s)
            };
            let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
            let a = 200.0 / 255.0;
            let want = colour.map(|c| (255.0 * a * c as f64).round() as u8);
            assert_eq!(px, want, "ess {ess} step {s}");
        }
    }

    // An affine field v = 2x + 3y + z is reproduced exactly by trilinear
    // interpolation; along a vertical ray its maximum is on the top face
    // z = 49, where the first sample lies: m = 2x + 3y + 49.
    let scene = Scene::new(u8_volume([40, 30, 50], Vec3::ONE, |v| {
        (2 * v.x + 3 * v.y + v.z) as u8
    }));
    let shapes = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let c255 = |c: [f64; 3], a: f64| c.map(|x| (a * x).round() as u8);
    for (x, y, want) in [
        // m = 96: the shapes TF gives (10, 60, 180)/255 with a = 0.3 — not
        // the step-corrected 1 − 0.7^s.
        (12.25f32, 7.5f32, c255([10.0, 60.0, 180.0], 0.3)),
        // m = 94: (255, 30, 60)/255, a = 0.02.
        (15.0, 5.0, c255([255.0, 30.0, 60.0], 0.02)),
        // m = 101: (90, 210, 20)/255, a = 0.6.
        (13.5, 8.0, c255([90.0, 210.0, 20.0], 0.6)),
        // m = 122: transparent.
        (20.75, 10.5, [0, 0, 0]),
    ] {
        for projection in [Projection::Perspective, Projection::Orthographic] {
            for ess in [false, true] {
                let cam = down_camera(x, y, 120.0, projection);
                let o = RenderOptions {
                    ess,
                    ..opts(RenderMode::Mip, 0.7)
                };
                let px = render(&scene, &cam, &shapes, &o).pixel(16, 16);
                assert_eq!(px, want, "({x}, {y}) {projection:?} ess {ess}");
            }
        }
    }
}

// ------------------------------------------------------------------ iso

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
    let f32_scene = Scene::new(LinearVolume::from_fn(grid, |v| {
        sphere.value(grid.voxel_to_world(v.as_vec3()))
    }));
    let u8_scene = Scene::new(LinearVolume::from_fn(grid, |v| {
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
    let scene = Scene::new(LinearVolume::from_fn(grid, |v| sphere.value(v.as_vec3())));
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
    let scene = Scene::new(LinearVolume::from_fn(grid, |v| sphere.value(v.as_vec3())));
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

// ------------------------------------------------------------- ESS and ERT

/// ESS must change nothing (SPEC §5): single rays integrated with and
/// without it give bit-identical DVR states and MIP maxima, and the same iso
/// hits, on random rays (from outside and from inside the box) through the
/// phantom data in both layouts.
#[test]
fn ess_changes_nothing_on_single_rays() {
    let dims = [37u32, 29, 41];
    let f = common::phantom(dims);
    let grid = Grid::new(UVec3::from_array(dims), Vec3::new(1.0, 1.5, 0.75));
    let lin = Scene::new(LinearVolume::from_fn(grid, |v| f(v.x, v.y, v.z)));
    let bri = Scene::new(BrickedVolume::from_fn(grid, 6, |v| f(v.x, v.y, v.z)).unwrap());
    let mut rng = fastrand::Rng::with_seed(9);
    let (lo, hi) = (grid.bounds().min, grid.bounds().max);
    let mut skipped = 0u64;
    let mut total = 0u64;
    for name in ["shapes", "skull", "ramp"] {
        let tf = TransferFunction::preset(name, SampleType::U8).unwrap();
        for step in [0.37f32, 0.8] {
            let rays: Vec<Ray> = (0..800)
                .map(|i| random_ray(&mut rng, lo, hi, i % 4 == 0))
                .collect();
            macro_rules! check {
                ($scene:expr) => {{
                    let lab = RayLab::dvr($scene, &tf, step);
                    for ray in &rays {
                        let Some((off, n_off)) = lab.dvr_state(ray, false) else {
                            continue;
                        };
                        let (on, n_on) = lab.dvr_state(ray, true).unwrap();
                        assert_eq!(
                            (off.color, off.alpha),
                            (on.color, on.alpha),
                            "{name} step {step}: DVR differs with ESS on {ray:?}"
                        );
                        assert_eq!(lab.mip_max(ray, false), lab.mip_max(ray, true), "{ray:?}");
                        skipped += n_off - n_on;
                        total += n_off;
                    }
                }};
            }
            check!(&lin);
            check!(&bri);
        }
    }
    // The shapes and skull TFs leave much of this volume empty.
    assert!(
        skipped * 8 > total,
        "ESS skipped only {skipped} of {total} samples"
    );
}

/// As above for iso: hits with ESS on are the hits with ESS off.
#[test]
fn ess_changes_no_iso_hit_on_random_rays() {
    let dims = [37u32, 29, 41];
    let f = common::phantom(dims);
    let grid = Grid::new(UVec3::from_array(dims), Vec3::new(1.0, 1.5, 0.75));
    let lin = Scene::new(LinearVolume::from_fn(grid, |v| f(v.x, v.y, v.z)));
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

/// LIBRARY BUG (SPEC §5, "ESS must change nothing"): in iso mode with ESS
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
        "with ESS on the iso hit is lost (ESS must change nothing, SPEC §5)"
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

/// Whole images: ESS on/off identical; ERT on/off within what the
/// threshold allows, (1 − thr)·255 levels plus one for rounding.
#[test]
fn ert_and_ess_change_images_only_within_the_spec() {
    let dims = [45u32, 38, 33];
    let pair = common::make_pair(
        dims,
        [1.0, 1.2, 0.9],
        common::TestLayout::Bricked(12),
        common::phantom(dims),
    );
    let scene = &pair.scene;
    let bounds = scene.grid().bounds();
    let c = bounds.center();
    let cams = [
        Camera::look_at(c + Vec3::new(10.0, 20.0, 70.0), c, 64, 48),
        Camera::look_at(c + Vec3::new(-60.0, -10.0, -30.0), c, 48, 64),
        Camera::look_at(
            c + Vec3::new(5.0, 3.0, 8.0),
            c + Vec3::new(-20.0, 0.0, -5.0),
            64,
            64,
        ),
    ];
    let mut worst_ert = [0u8; 2];
    for cam in &cams {
        for name in ["shapes", "skull", "ramp"] {
            let tf = TransferFunction::preset(name, SampleType::U8).unwrap();
            for (mode, iso) in [
                (RenderMode::Dvr, 0.0),
                (RenderMode::Mip, 0.0),
                (RenderMode::Avg, 0.0),
                (RenderMode::Iso, 97.5),
            ] {
                let base = RenderOptions {
                    iso_value: iso,
                    background: Vec3::new(0.1, 0.2, 0.3),
                    ..opts(mode, 0.45)
                };
                let plain = render(scene, cam, &tf, &base);
                let ess = render(
                    scene,
                    cam,
                    &tf,
                    &RenderOptions {
                        ess: true,
                        ..base.clone()
                    },
                );
                assert_eq!(plain.rgb, ess.rgb, "{name} {mode:?}: ESS changed the image");
                for (i, thr) in [0.99f32, 0.9].into_iter().enumerate() {
                    let ert = render(
                        scene,
                        cam,
                        &tf,
                        &RenderOptions {
                            ert: true,
                            ert_threshold: thr,
                            ..base.clone()
                        },
                    );
                    let d = common::compare_images(&plain.rgb, &ert.rgb, 0);
                    let allowed = ((1.0 - thr) * 255.0).ceil() as u8 + 1;
                    assert!(d.max <= allowed, "{name} {mode:?} ERT {thr}: {d}");
                    worst_ert[i] = worst_ert[i].max(d.max);
                }
            }
        }
    }
    println!(
        "ERT 0.99 changes pixels by up to {}, ERT 0.9 by up to {}",
        worst_ert[0], worst_ert[1]
    );
}

/// ESS takes fewer samples on a mostly empty volume, and a small object in a
/// huge empty box costs about as many samples as the object alone: skipping
/// costs nothing per skipped step.
#[test]
fn ess_sample_counts() {
    let ball = |centre: Vec3| {
        move |v: UVec3| {
            let d = (v.as_vec3() - centre).length();
            (200.0 * (1.0 - d / 9.0)).clamp(0.0, 200.0) as u8
        }
    };
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    // The ball alone (a 33³ box around it) and in a 161³ box, at the same
    // offset from a macrocell corner (64 = 8 macrocells).
    let small = Scene::new(u8_volume([33; 3], Vec3::ONE, ball(Vec3::splat(16.3))));
    let big = Scene::new(u8_volume([161; 3], Vec3::ONE, ball(Vec3::splat(80.3))));
    let count = |scene: &Scene<LinearVolume<u8>>, centre: Vec3, ess: bool, mode: RenderMode| {
        let mut cam = Camera::look_at(centre + Vec3::new(8.0, 5.0, 50.0), centre, 48, 48);
        cam.fov_y_deg = 40.0;
        let o = RenderOptions {
            ess,
            iso_value: 97.0,
            ..opts(mode, 0.5)
        };
        let f = render(scene, &cam, &tf, &o);
        (f.stats.samples, f.rgb)
    };
    for mode in [RenderMode::Dvr, RenderMode::Mip, RenderMode::Iso] {
        let (s_off, img_s_off) = count(&small, Vec3::splat(16.3), false, mode);
        let (s_on, img_s_on) = count(&small, Vec3::splat(16.3), true, mode);
        let (b_off, img_b_off) = count(&big, Vec3::splat(80.3), false, mode);
        let (b_on, img_b_on) = count(&big, Vec3::splat(80.3), true, mode);
        println!(
            "{mode:?}: samples object alone {s_off} (ESS off) / {s_on} (on); in a 161³ box {b_off} / {b_on}"
        );
        // Same picture either way (the camera sees the same ball).
        assert_eq!(img_s_off, img_s_on, "{mode:?}");
        assert_eq!(img_b_off, img_b_on, "{mode:?}");
        assert!(
            s_on < s_off,
            "{mode:?}: ESS took no fewer samples ({s_on} vs {s_off})"
        );
        assert!(
            b_on * 5 < b_off,
            "{mode:?}: ESS saved little in the big box ({b_on} vs {b_off})"
        );
        // Iso takes the samples that bracket each skipped run (to compare
        // values across it), so it pays a little per skipped box.
        let factor = if mode == RenderMode::Iso { 2.0 } else { 1.25 };
        assert!(
            b_on as f64 <= factor * s_on as f64 + 1000.0,
            "{mode:?}: the empty box costs samples with ESS on ({b_on} vs {s_on} for the object alone)"
        );
    }
}

// ------------------------------------------------------------------ camera

/// One bright voxel at a known world position shows up at the pixel given by
/// projecting it with SPEC §3's formula (computed independently in the
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

// --------------------------------------------- layouts, files and interop

/// Linear and bricked volumes of the same data, in memory and written to
/// and read back from `.vol` files (mapped and in RAM), render identically.
#[test]
fn linear_bricked_and_file_volumes_render_identically() {
    let dims = [37u32, 29, 23];
    let spacing = Vec3::new(1.0, 0.5, 2.0);
    let f = common::phantom(dims);
    let grid = Grid::new(UVec3::from_array(dims), spacing);
    let linear = LinearVolume::from_fn(grid, |v| f(v.x, v.y, v.z));
    let c = grid.bounds().center();
    let cams = [
        Camera::look_at(c + Vec3::new(20.0, 30.0, 60.0), c, 48, 40),
        Camera::look_at(
            c + Vec3::new(-3.0, 1.0, 4.0),
            c + Vec3::new(10.0, 0.0, -20.0),
            40,
            40,
        ),
    ];
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let modes = [
        (RenderMode::Dvr, true),
        (RenderMode::Mip, true),
        (RenderMode::Avg, false),
        (RenderMode::Iso, false),
    ];
    let images = |scene: &Scene<AnyVolume>| -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for cam in &cams {
            for (mode, ess) in modes {
                let o = RenderOptions {
                    ess,
                    ert: true,
                    iso_value: 99.5,
                    ..opts(mode, 0.3)
                };
                out.push(render(scene, cam, &tf, &o).rgb);
                let mut shaded = o.clone();
                shaded.shading = true;
                out.push(render(scene, cam, &tf, &shaded).rgb);
            }
        }
        out
    };
    let want_voxels = linear.samples().to_vec();
    let want = images(&Scene::new(AnyVolume::from(linear)));
    for side in [2u32, 5, 16] {
        let b = BrickedVolume::from_fn(grid, side, |v| f(v.x, v.y, v.z)).unwrap();
        assert_eq!(
            images(&Scene::new(AnyVolume::from(b))),
            want,
            "in-memory bricked B = {side}"
        );
    }
    let source = LinearVolume::from_fn(grid, |v| f(v.x, v.y, v.z));
    for layout in [
        VolLayout::Linear,
        VolLayout::Bricked { side: 2 },
        VolLayout::Bricked { side: 5 },
        VolLayout::Bricked { side: 16 },
        VolLayout::Bricked { side: 255 },
    ] {
        let file = TempFile::new("layout.vol");
        raycaster::format::vol::write(file.path(), &source, layout).unwrap();
        for mode in [LoadMode::Map, LoadMode::Ram] {
            let v = raycaster::format::open(file.path(), mode).unwrap();
            assert_eq!(*v.grid(), grid, "{layout:?}");
            assert_eq!(voxels_u8(&v), want_voxels, "{layout:?} {mode:?}");
            assert_eq!(images(&Scene::new(v)), want, "{layout:?} {mode:?}");
        }
    }
}

const INTEROP: &str = "/work/shared/data/interop";

/// The two files written by another implementation hold the same voxels in
/// the linear and the bricked (B = 16) layout: every voxel reads the same,
/// and the renders are identical.
#[test]
fn interop_files_read_the_same_and_render_identically() {
    let lin_path = Path::new(INTEROP).join("shapes_96x80x64_linear.vol");
    let bri_path = Path::new(INTEROP).join("shapes_96x80x64_block16.vol");
    if !lin_path.exists() || !bri_path.exists() {
        eprintln!("SKIPPED: interop files not found under {INTEROP}");
        return;
    }
    let lin = raycaster::format::open(&lin_path, LoadMode::Map).unwrap();
    let bri = raycaster::format::open(&bri_path, LoadMode::Map).unwrap();
    assert_eq!(lin.grid().dims, UVec3::new(96, 80, 64));
    assert_eq!(bri.grid().dims, UVec3::new(96, 80, 64));
    assert_eq!(lin.grid(), bri.grid());
    assert_eq!(lin.layout(), Layout::Linear);
    assert_eq!(bri.layout(), Layout::Bricked { side: 16 });
    let a = voxels_u8(&lin);
    let b = voxels_u8(&bri);
    let differing = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(
        differing, 0,
        "{differing} voxels differ between the interop files"
    );
    // The data is the shapes benchmark: some voxels in the shapes TF's range.
    assert!(a.iter().any(|v| (85..115).contains(v)));
    // The linear file's bytes are the voxels in SPEC §1 order.
    let raw = std::fs::read(&lin_path).unwrap();
    assert_eq!(&raw[26..], &a[..]);
    let (lin, bri) = (Scene::new(lin), Scene::new(bri));
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let c = lin.grid().bounds().center();
    for (pos, mode) in [
        (Vec3::new(0.0, 0.0, 150.0), RenderMode::Dvr),
        (Vec3::new(90.0, 60.0, 100.0), RenderMode::Dvr),
        (Vec3::new(-80.0, 30.0, -90.0), RenderMode::Mip),
        (Vec3::new(30.0, -90.0, 60.0), RenderMode::Iso),
    ] {
        let cam = Camera::look_at(c + pos, c, 64, 56);
        let o = RenderOptions {
            ess: true,
            ert: true,
            iso_value: 100.0,
            ..opts(mode, 0.5)
        };
        let x = render(&lin, &cam, &tf, &o);
        let y = render(&bri, &cam, &tf, &o);
        assert_eq!(x.rgb, y.rgb, "{mode:?} from {pos}");
        assert!(x.rgb.iter().any(|&v| v > 0), "{mode:?}: empty image");
    }
}

// ------------------------------------------------------------ .vol format

/// SPEC §1's bricked encoding, written independently of the library.
fn encode_bricked(dims: [u32; 3], b: u32, voxel: impl Fn(u32, u32, u32) -> u8) -> Vec<u8> {
    let n = |d: u32| if d == 1 { 1 } else { (d - 1).div_ceil(b - 1) };
    let (nx, ny, nz) = (n(dims[0]), n(dims[1]), n(dims[2]));
    let mut out = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                for lx in 0..b {
                    for ly in 0..b {
                        for lz in 0..b {
                            let (x, y, z) = (i * (b - 1) + lx, j * (b - 1) + ly, k * (b - 1) + lz);
                            let inside = x < dims[0] && y < dims[1] && z < dims[2];
                            out.push(if inside { voxel(x, y, z) } else { 0 });
                        }
                    }
                }
            }
        }
    }
    out
}

fn header(dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8) -> Vec<u8> {
    let mut h = Vec::with_capacity(26);
    for d in dims {
        h.extend_from_slice(&d.to_le_bytes());
    }
    for s in spacing {
        h.extend_from_slice(&s.to_le_bytes());
    }
    h.push(layout);
    h.push(extra);
    h
}

/// Write then read back, for odd sizes and several brick sides: the file is
/// byte for byte SPEC §1 (checked against an independent encoder) and reads
/// back voxel-identical.
#[test]
fn vol_round_trip() {
    let mut rng = fastrand::Rng::with_seed(5);
    for dims in [
        [1u32, 1, 1],
        [2, 3, 5],
        [17, 9, 13],
        [31, 1, 7],
        [6, 16, 31],
    ] {
        let spacing = [0.5f32, 1.25, 3.0];
        let data: Vec<u8> = (0..dims.iter().product::<u32>())
            .map(|_| rng.u8(..))
            .collect();
        let voxel = |x: u32, y: u32, z: u32| data[((x * dims[1] + y) * dims[2] + z) as usize];
        let grid = Grid::new(UVec3::from_array(dims), Vec3::from_array(spacing));
        let vol = LinearVolume::from_fn(grid, |v| voxel(v.x, v.y, v.z));
        for layout in [
            VolLayout::Linear,
            VolLayout::Bricked { side: 2 },
            VolLayout::Bricked { side: 3 },
            VolLayout::Bricked { side: 5 },
            VolLayout::Bricked { side: 16 },
            VolLayout::Bricked { side: 255 },
        ] {
            let file = TempFile::new("rt.vol");
            raycaster::format::vol::write(file.path(), &vol, layout).unwrap();
            let bytes = std::fs::read(file.path()).unwrap();
            let (lbyte, extra, body) = match layout {
                VolLayout::Linear => (1, 0, data.clone()),
                VolLayout::Bricked { side } => (2, side, encode_bricked(dims, side as u32, voxel)),
            };
            let mut want = header(dims, spacing, lbyte, extra);
            want.extend_from_slice(&body);
            assert_eq!(bytes.len(), want.len(), "{dims:?} {layout:?}: file length");
            assert!(
                bytes == want,
                "{dims:?} {layout:?}: file bytes differ from SPEC §1"
            );
            for mode in [LoadMode::Map, LoadMode::Ram] {
                let back = raycaster::format::open(file.path(), mode).unwrap();
                assert_eq!(back.grid().dims, UVec3::from_array(dims));
                assert_eq!(back.grid().spacing, Vec3::from_array(spacing));
                assert_eq!(voxels_u8(&back), data, "{dims:?} {layout:?} {mode:?}");
            }
        }
    }
}

/// Every bad header case of SPEC §1 is an error naming the file, never a panic.
#[test]
fn bad_vol_files_are_errors_that_name_the_file() {
    let ok = |dims: [u32; 3]| header(dims, [1.0; 3], 1, 0);
    let with_body = |mut h: Vec<u8>, n: usize| {
        h.resize(h.len() + n, 7);
        h
    };
    let cases: Vec<(&str, Vec<u8>, Vec<&str>)> = vec![
        ("empty file", vec![], vec![]),
        ("10 bytes", vec![1; 10], vec![]),
        ("25 bytes", ok([1, 1, 1])[..25].to_vec(), vec![]),
        ("zero X", with_body(ok([0, 4, 4]), 0), vec![]),
        ("zero Y", with_body(ok([4, 0, 4]), 0), vec![]),
        ("zero Z", with_body(ok([4, 4, 0]), 64), vec![]),
        (
            "NaN spacing",
            with_body(header([2, 2, 2], [1.0, f32::NAN, 1.0], 1, 0), 8),
            vec![],
        ),
        (
            "inf spacing",
            with_body(header([2, 2, 2], [f32::INFINITY, 1.0, 1.0], 1, 0), 8),
            vec![],
        ),
        (
            "-inf spacing",
            with_body(header([2, 2, 2], [1.0, 1.0, f32::NEG_INFINITY], 1, 0), 8),
            vec![],
        ),
        (
            "zero spacing",
            with_body(header([2, 2, 2], [1.0, 0.0, 1.0], 1, 0), 8),
            vec![],
        ),
        (
            "-0 spacing",
            with_body(header([2, 2, 2], [1.0, 1.0, -0.0], 1, 0), 8),
            vec![],
        ),
        (
            "negative spacing",
            with_body(header([2, 2, 2], [-1.0, 1.0, 1.0], 1, 0), 8),
            vec![],
        ),
        (
            "layout 0",
            with_body(header([2, 2, 2], [1.0; 3], 0, 0), 8),
            vec![],
        ),
        (
            "layout 3",
            with_body(header([2, 2, 2], [1.0; 3], 3, 0), 8),
            vec![],
        ),
        (
            "layout 255",
            with_body(header([2, 2, 2], [1.0; 3], 255, 0), 8),
            vec![],
        ),
        (
            "brick side 0",
            with_body(header([2, 2, 2], [1.0; 3], 2, 0), 8),
            vec![],
        ),
        (
            "brick side 1",
            with_body(header([2, 2, 2], [1.0; 3], 2, 1), 8),
            vec![],
        ),
        ("linear overflow", with_body(ok([u32::MAX; 3]), 16), vec![]),
        (
            "bricked overflow",
            with_body(header([u32::MAX; 3], [1.0; 3], 2, 2), 16),
            vec![],
        ),
        (
            "linear, one byte short",
            with_body(ok([4, 5, 6]), 119),
            vec!["expected", "146", "found", "145"],
        ),
        (
            "linear, one byte long",
            with_body(ok([4, 5, 6]), 121),
            vec!["expected", "146", "found", "147"],
        ),
        (
            "linear, header only",
            ok([4, 5, 6]),
            vec!["expected", "146", "found", "26"],
        ),
        (
            // 2 bricks of 3³ per axis: 8·27 = 216 samples.
            "bricked, short",
            with_body(header([5, 5, 5], [1.0; 3], 2, 3), 215),
            vec!["expected", "242", "found", "241"],
        ),
        (
            // Linear-sized body under a bricked header.
            "bricked, linear-sized body",
            with_body(header([5, 5, 5], [1.0; 3], 2, 3), 125),
            vec!["expected", "242", "found", "151"],
        ),
    ];
    for (what, bytes, must_say) in cases {
        let file = TempFile::new("bad-header.vol");
        std::fs::write(file.path(), &bytes).unwrap();
        let name = file
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        for mode in [LoadMode::Map, LoadMode::Ram] {
            let err = match raycaster::format::open(file.path(), mode) {
                Ok(v) => panic!("{what}: opened as {:?}", v.grid()),
                Err(e) => e.to_string(),
            };
            assert!(
                err.contains(&name),
                "{what}: message does not name the file: {err}"
            );
            for word in &must_say {
                assert!(err.contains(word), "{what}: message lacks {word:?}: {err}");
            }
        }
        if bytes.len() >= 26
            && !what.contains("short")
            && !what.contains("long")
            && !what.contains("body")
            && !what.contains("header only")
        {
            assert!(VolHeader::parse(&bytes).is_err(), "{what}: header parsed");
        }
    }
    // Missing files and directories are errors too.
    let missing = TempFile::new("missing.vol");
    let err = raycaster::format::open(missing.path(), LoadMode::Map)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.vol"), "{err}");
    let err = raycaster::format::open(&std::env::temp_dir(), LoadMode::Map).unwrap_err();
    assert!(!err.to_string().is_empty());
}

/// Random byte strings and randomly corrupted valid files never panic the
/// header parser or the reader.
#[test]
fn vol_reader_never_panics_on_garbage() {
    let mut rng = fastrand::Rng::with_seed(2024);
    // Header parser: pure random bytes, and valid headers with a few bytes changed.
    for i in 0..4000 {
        let bytes: Vec<u8> = if i % 2 == 0 {
            (0..rng.usize(0..200)).map(|_| rng.u8(..)).collect()
        } else {
            let mut h = header(
                [rng.u32(1..40), rng.u32(1..40), rng.u32(1..40)],
                [0.5, 1.0, 2.0],
                rng.u8(1..=2),
                rng.u8(2..20),
            );
            for _ in 0..rng.usize(1..4) {
                let at = rng.usize(0..26);
                h[at] = rng.u8(..);
            }
            h
        };
        let r = std::panic::catch_unwind(|| VolHeader::parse(&bytes));
        assert!(r.is_ok(), "VolHeader::parse panicked on {bytes:?}");
    }
    // The reader, through files: random bytes, and valid small files with a
    // corrupted header byte or a length off by a little.
    let file = TempFile::new("fuzz.vol");
    let mut opened = 0;
    for i in 0..2000 {
        let bytes: Vec<u8> = match i % 3 {
            0 => (0..rng.usize(0..200)).map(|_| rng.u8(..)).collect(),
            _ => {
                let dims = [rng.u32(1..6), rng.u32(1..6), rng.u32(1..6)];
                let bricked = rng.bool();
                let side = rng.u8(2..5);
                let body = if bricked {
                    let n = |d: u32| {
                        if d == 1 {
                            1
                        } else {
                            (d - 1).div_ceil(side as u32 - 1)
                        }
                    };
                    (n(dims[0]) * n(dims[1]) * n(dims[2])) as usize * (side as usize).pow(3)
                } else {
                    dims.iter().product::<u32>() as usize
                };
                let mut b = header(dims, [1.0, 0.5, 2.0], if bricked { 2 } else { 1 }, side);
                b.extend((0..body).map(|_| rng.u8(..)));
                if i % 3 == 1 {
                    let at = rng.usize(0..26);
                    b[at] = rng.u8(..);
                } else if rng.bool() {
                    let n = b.len();
                    b.truncate(n - rng.usize(0..3.min(n)));
                } else {
                    b.extend((0..rng.usize(0..3)).map(|_| 0u8));
                }
                b
            }
        };
        std::fs::write(file.path(), &bytes).unwrap();
        let mode = if i % 2 == 0 {
            LoadMode::Map
        } else {
            LoadMode::Ram
        };
        let path = file.path().to_path_buf();
        let r = std::panic::catch_unwind(move || {
            raycaster::format::open(&path, mode).map(|v| {
                // Whatever opened must be readable everywhere.
                let d = v.grid().dims;
                let _ = voxels_u8(&v);
                d
            })
        });
        match r {
            Err(_) => panic!("format::open panicked on {bytes:?}"),
            Ok(Ok(_)) => opened += 1,
            Ok(Err(e)) => {
                let name = file
                    .path()
                    .file_name()
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                assert!(
                    e.to_string().contains(&name),
                    "error without the file name: {e}"
                );
            }
        }
    }
    assert!(opened > 100, "only {opened} valid files opened");
}

// ------------------------------------------------------------- sample types

/// `avg` divides the mean by the sample type's maximum (SPEC §5), and the
/// `ramp` preset spans the type's range (SPEC §4).
#[test]
fn avg_and_ramp_follow_the_sample_type() {
    let dims = [9u32, 9, 9];
    let grid = Grid::new(UVec3::from_array(dims), Vec3::ONE);
    let cam = down_camera(4.0, 4.0, 50.0, Projection::Perspective);
    let avg = opts(RenderMode::Avg, 0.5);
    let grey = |scene: &Scene<AnyVolume>, t: SampleType| {
        let tf = TransferFunction::preset("ramp", t).unwrap();
        render(scene, &cam, &tf, &avg).pixel(16, 16)
    };
    let s = Scene::new(AnyVolume::from(LinearVolume::from_fn(grid, |_| 30000u16)));
    let g = (255.0 * 30000.0 / 65535.0f64).round() as u8;
    assert_eq!(grey(&s, SampleType::U16), [g; 3], "u16");
    let s = Scene::new(AnyVolume::from(LinearVolume::from_fn(grid, |_| 1000i16)));
    let g = (255.0 * 1000.0 / 32767.0f64).round() as u8;
    assert_eq!(grey(&s, SampleType::I16), [g; 3], "i16");
    let s = Scene::new(AnyVolume::from(LinearVolume::from_fn(grid, |_| 0.25f32)));
    assert_eq!(grey(&s, SampleType::F32), [64; 3], "f32");
    // MIP with the u16 ramp: a = c = 30000/65535.
    let s = Scene::new(AnyVolume::from(LinearVolume::from_fn(grid, |_| 30000u16)));
    let tf = TransferFunction::preset("ramp", SampleType::U16).unwrap();
    let px = render(&s, &cam, &tf, &opts(RenderMode::Mip, 0.5)).pixel(16, 16);
    let g = (255.0 * 30000.0 / 65535.0f64).round() as u8;
    assert_eq!(px, [g; 3]);
}

/// LIBRARY BUG (SPEC §4, "step": the RGBA of the last point whose value is
/// <= v): DVR looks the TF up in a table (`TfLut`) with `scale` entries per
/// value unit, a power of two chosen to keep ~4096 entries. When the TF's
/// points span more than 4096 value units (u16 data, or i16 CT data with a
/// wide TF), the scale drops below 1 (1/16 for a span near 65535), and a step
/// point that is not on a table boundary (here 1010, boundaries every 16
/// units from 1000) takes effect only at the next boundary (1016): values in
/// [1010, 1016) get the previous point's colour. The table's own doc claims
/// step TFs are exact; that holds only for spans <= 4096.
///
/// Homogeneous u16 volume of value 1012, TF step 1000 → red, 1010 → green,
/// 60000 → transparent: the image must be green (MIP, which evaluates the
/// TF exactly, is green; DVR is red).
#[test]
fn step_tf_is_exact_for_wide_value_spans() {
    let grid = Grid::new(UVec3::splat(9), Vec3::ONE);
    let scene = Scene::new(LinearVolume::from_fn(grid, |_| 1012u16));
    let tf = tf_points(
        Interpolation::Step,
        &[
            (1000.0, [1.0, 0.0, 0.0], 1.0),
            (1010.0, [0.0, 1.0, 0.0], 1.0),
            (60000.0, [0.0, 0.0, 0.0], 0.0),
        ],
    );
    let cam = down_camera(4.0, 4.0, 50.0, Projection::Perspective);
    let mip = render(&scene, &cam, &tf, &opts(RenderMode::Mip, 0.5)).pixel(16, 16);
    assert_eq!(mip, [0, 255, 0], "MIP evaluates the TF exactly");
    let dvr = render(&scene, &cam, &tf, &opts(RenderMode::Dvr, 0.5)).pixel(16, 16);
    assert_eq!(
        dvr,
        [0, 255, 0],
        "DVR shows the colour of TF(1012) = the point at 1010"
    );
}

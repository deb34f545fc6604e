//! Empty-space skipping and early ray termination: ESS changes no DVR state
//! or MIP maximum on single rays, ESS and ERT change whole images only within
//! what ERT's threshold allows, and ESS saves the samples of empty
//! space.

mod common;

use common::rays::{RayLab, random_ray};
use common::scenes::{opts, render, u8_volume};
use glam::{UVec3, Vec3};
use raycaster::geometry::Ray;
use raycaster::integrator::Phong;
use raycaster::prelude::*;

/// ESS must change nothing: single rays integrated with and
/// without it give bit-identical DVR states and MIP maxima, and the same iso
/// hits, on random rays (from outside and from inside the box) through the
/// phantom data in both layouts.
#[test]
fn ess_changes_nothing_on_single_rays() {
    let (grid, f) = common::phantom_on_grid([37, 29, 41], Vec3::new(1.0, 1.5, 0.75));
    let lin = Scene::new(AnyVolume::from_fn(grid, f));
    let bri = Scene::new(AnyVolume::bricked_from_fn(grid, 6, f).unwrap());
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
                            (off.color, off.transmittance),
                            (on.color, on.transmittance),
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

/// Blocks of one value (uniform macrocells inside) and blocks of two values
/// the `shapes` TF gives one colour (92 and 94 red, 97 and 100 blue) side
/// by side: macrocells whose samples are composited without being taken.
/// With ESS on, which finds those cells, single rays still end in states
/// bit-identical to marching every sample, shaded and unshaded. (A closed
/// form `T·(1 − α)ⁿ` for those runs does not.)
#[test]
fn cells_composited_without_sampling_give_the_marched_bits() {
    let blocks = |v: UVec3| -> u8 {
        let inside = |lo: u32, hi: u32, c: u32| (lo..hi).contains(&c);
        if inside(4, 20, v.x) && inside(4, 30, v.y) && inside(6, 30, v.z) {
            if v.x < 12 { 92 } else { 94 }
        } else if inside(24, 44, v.x) && inside(8, 36, v.y) && inside(4, 24, v.z) {
            if v.y < 20 { 97 } else { 100 }
        } else {
            0
        }
    };
    let grid = Grid::new(UVec3::new(48, 40, 36), Vec3::ONE);
    let scene = Scene::new(AnyVolume::from_fn(grid, blocks));
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let mut rng = fastrand::Rng::with_seed(21);
    let (lo, hi) = (grid.bounds().min, grid.bounds().max);
    for shaded in [false, true] {
        for step in [0.3f32, 0.7] {
            let lab = RayLab::dvr(&scene, &tf, step);
            let lab = if shaded {
                lab.shaded(Phong::default())
            } else {
                lab
            };
            let mut seen = 0;
            for i in 0..1500 {
                let ray = random_ray(&mut rng, lo, hi, i % 4 == 0);
                let Some((off, _)) = lab.dvr_state(&ray, false) else {
                    continue;
                };
                let (on, _) = lab.dvr_state(&ray, true).unwrap();
                assert_eq!(
                    (off.color, off.transmittance, off.terminated),
                    (on.color, on.transmittance, on.terminated),
                    "shaded {shaded} step {step}: DVR differs with ESS on {ray:?}"
                );
                seen += (off.alpha() > 0.5) as u32;
            }
            assert!(seen > 300, "only {seen} rays met the blocks");
        }
    }
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

/// Solid objects seen from outside: the rays' proxy depths come from the
/// occupied macrocells on the objects' surfaces only (those inside cannot
/// be met first), and the images are still those without skipping, from
/// every side, with a weak and an opaque TF: on a TF's first frame (the
/// plain surface runs) and on its second (the runs narrowed to their
/// visible voxels, which must save samples).
#[test]
fn proxy_of_surface_cells_changes_nothing() {
    let dims = [70u32, 64, 58];
    let pair = common::make_pair(
        dims,
        [1.0, 1.0, 1.0],
        common::TestLayout::Linear,
        |x, y, z| {
            let p = Vec3::new(x as f32, y as f32, z as f32);
            let ball = p.distance(Vec3::new(30.0, 34.0, 28.0)) < 22.0;
            let slab = (50..66).contains(&x) && (8..56).contains(&y) && (10..48).contains(&z);
            if ball || slab { 100 } else { 0 }
        },
    );
    let scene = &pair.scene;
    let c = scene.grid().bounds().center();
    let opaque = common::scenes::tf_points(
        Interpolation::Step,
        &[
            (0.0, [0.0; 3], 0.0),
            (50.0, [1.0, 0.5, 0.2], 0.0),
            (60.0, [1.0, 0.5, 0.2], 0.9),
        ],
    );
    let weak = common::scenes::tf_points(
        Interpolation::Linear,
        &[
            (0.0, [0.0; 3], 0.0),
            (100.0, [0.2, 0.6, 1.0], 0.05),
            (255.0, [1.0; 3], 0.05),
        ],
    );
    let mut narrowed = 0;
    for eye in [
        Vec3::new(0.0, 0.0, 150.0),
        Vec3::new(0.0, 0.0, -150.0),
        Vec3::new(160.0, 10.0, 5.0),
        Vec3::new(-90.0, 100.0, -70.0),
        Vec3::new(20.0, -140.0, 40.0),
    ] {
        let cam = Camera::look_at(c + eye, c, 80, 72);
        for tf in [&opaque, &weak] {
            let base = RenderOptions {
                background: Vec3::new(0.1, 0.2, 0.3),
                ..opts(RenderMode::Dvr, 0.4)
            };
            let plain = render(scene, &cam, tf, &base);
            let with_ess = RenderOptions {
                ess: true,
                ..base.clone()
            };
            // A TF's first frame draws the plain surface runs, the next
            // ones the runs narrowed to the visible voxels: the same image.
            let mut renderer = SerialRenderer::new();
            let mut frames = (0..2).map(|_| renderer.render(scene, &cam, tf, &with_ess).unwrap());
            let (first, second) = (frames.next().unwrap(), frames.next().unwrap());
            assert_eq!(plain.rgb, first.rgb, "eye {eye}: ESS changed the image");
            assert_eq!(
                plain.rgb, second.rgb,
                "eye {eye}: the narrowed proxy changed it"
            );
            assert!(second.stats.samples <= first.stats.samples, "eye {eye}");
            narrowed += (second.stats.samples < first.stats.samples) as u32;
        }
    }
    assert!(
        narrowed >= 5,
        "the narrowed proxy saved samples in {narrowed} frames"
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
    let count = |scene: &Scene, centre: Vec3, ess: bool, mode: RenderMode| {
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

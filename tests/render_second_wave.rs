//! SPEC §8's clipping, gradient opacity, MinIP and jitter: against the
//! independent f64 reference (`common/reference.rs`, `render_with`), every
//! renderer against the serial one, and ESS on against off.
//!
//! Checks per scene: the tiled and object renderers (bricks of 8, and its
//! default) equal the serial one byte for byte; ESS on equals ESS off byte
//! for byte;
//! against the reference the tolerances of `reference_images.rs` (PSNR >= 45
//! dB, at most 0.5% of the pixels, or 4, over 3 levels). Each feature is
//! also checked to change the image, so a feature that does nothing fails.

mod common;

use common::reference::{self as r, RefCamera, RefExtras, RefMode, RefOptions, RefTf, V3};
use common::{Pair, TestLayout, compare_images, lib_camera, lib_tf, make_pair, phantom};
use glam::Vec3;
use raycaster::clip::{Clip, ClipPlane};
use raycaster::integrator::{GradientOpacity, Occupancy};
use raycaster::prelude::*;
use raycaster::transfer::TfLut;

const DIMS: [u32; 3] = [40, 34, 30];
const SPACING: V3 = [1.0, 0.8, 1.2];

fn v3(v: V3) -> Vec3 {
    common::v3f(v)
}

/// The library's options for a reference scene.
fn lib_options(mode: RefMode, step: f64, ext: &RefExtras, ess: bool) -> RenderOptions {
    let (mode, iso_value) = match mode {
        RefMode::Dvr => (RenderMode::Dvr, 0.0),
        RefMode::Mip => (RenderMode::Mip, 0.0),
        RefMode::Minip => (RenderMode::Minip, 0.0),
        RefMode::Avg => (RenderMode::Avg, 0.0),
        RefMode::Iso(v) => (RenderMode::Iso, v as f32),
    };
    RenderOptions {
        mode,
        step: Some(step as f32),
        ert: false,
        ess,
        shading: false,
        iso_value,
        clip: Clip {
            clip_box: ext.clip_box.map(|(a, b)| (v3(a), v3(b))),
            planes: ext
                .planes
                .iter()
                .map(|&(n, d)| ClipPlane {
                    normal: v3(n),
                    offset: d as f32,
                })
                .collect(),
        },
        gradient_opacity: ext.gradient_opacity.map(|(g0, g1)| GradientOpacity {
            g0: g0 as f32,
            g1: g1 as f32,
        }),
        jitter: ext.jitter_seed.is_some(),
        seed: ext.jitter_seed.unwrap_or(0),
        ..RenderOptions::default()
    }
}

fn object(brick: u32) -> ObjectRenderer {
    ObjectRenderer::with_config(ObjectConfig {
        render_threads: 2,
        composite_threads: 0,
        tile: 8,
        brick,
        order: TaskOrder::TileFirst,
    })
    .unwrap()
}

/// Renders with every renderer, ESS on and off; checks that they agree and
/// returns the serial image (ESS on).
fn render_all(
    name: &str,
    scene: &Scene,
    cam: &Camera,
    tf: &TransferFunction,
    o: &RenderOptions,
) -> Vec<u8> {
    let mut images = Vec::new();
    for ess in [true, false] {
        let o = RenderOptions { ess, ..o.clone() };
        let serial = SerialRenderer::new()
            .render(scene, cam, tf, &o)
            .unwrap()
            .rgb;
        let tiled = TiledRenderer::new(3, 8)
            .unwrap()
            .render(scene, cam, tf, &o)
            .unwrap()
            .rgb;
        assert!(
            serial == tiled,
            "{name} ESS {ess}: tiled differs from serial"
        );
        for brick in [8, 0] {
            let obj = object(brick).render(scene, cam, tf, &o).unwrap().rgb;
            assert!(
                serial == obj,
                "{name} ESS {ess} object brick {brick}: {}",
                compare_images(&serial, &obj, 0)
            );
        }
        images.push(serial);
    }
    assert!(images[0] == images[1], "{name}: ESS changed the image");
    images.swap_remove(0)
}

/// Renders a scene with the library (every renderer) and the reference,
/// compares, and returns the library's image.
fn against_reference(
    name: &str,
    pair: &Pair,
    cam: &RefCamera,
    tf: &RefTf,
    mode: RefMode,
    step: f64,
    ext: &RefExtras,
) -> Vec<u8> {
    let opts = RefOptions {
        mode,
        ..RefOptions::dvr(step)
    };
    let want = r::render_with(&pair.reference, cam, tf, &opts, ext);
    let got = render_all(
        name,
        &pair.scene,
        &lib_camera(cam),
        &lib_tf(tf),
        &lib_options(mode, step, ext, true),
    );
    let d = compare_images(&got, &want, 3);
    let allowed = ((d.pixels as f64 * 0.005) as usize).max(4);
    println!("{name}: {d}");
    assert!(
        d.psnr >= 45.0 && d.over <= allowed,
        "{name} against the reference: {d}"
    );
    got
}

fn phantom_pair() -> Pair {
    make_pair(DIMS, SPACING, TestLayout::Linear, phantom(DIMS))
}

/// A camera looking at the middle of the phantom from an oblique direction.
fn oblique() -> RefCamera {
    RefCamera::perspective([70.0, 45.0, 80.0], [20.0, 13.0, 17.0], 48, 48)
}

fn dvr_tf() -> RefTf {
    RefTf::linear(vec![
        RefTf::point(30.0, [0.9, 0.4, 0.2], 0.0),
        RefTf::point(120.0, [0.3, 0.7, 0.9], 0.5),
        RefTf::point(250.0, [1.0, 1.0, 0.8], 0.9),
    ])
}

/// Share of pixels that are not black.
fn coverage(rgb: &[u8]) -> f64 {
    let n = rgb
        .chunks_exact(3)
        .filter(|p| p.iter().any(|&c| c > 0))
        .count();
    n as f64 / (rgb.len() / 3) as f64
}

fn box_ext() -> RefExtras {
    RefExtras {
        clip_box: Some(([4.3, 3.1, 6.7], [27.9, 21.3, 29.1])),
        ..Default::default()
    }
}

fn planes_ext() -> RefExtras {
    RefExtras {
        planes: vec![([1.0, 0.5, 0.2], 30.3), ([-0.3, 0.0, 1.0], 12.7)],
        ..Default::default()
    }
}

#[test]
fn clip_box_and_planes_match_the_reference_in_every_mode() {
    let pair = phantom_pair();
    let cam = oblique();
    let modes = [
        (RefMode::Dvr, dvr_tf()),
        (RefMode::Mip, RefTf::ramp(255.0)),
        (RefMode::Minip, RefTf::ramp(255.0)),
        (RefMode::Avg, RefTf::ramp(255.0)),
    ];
    for (mode, tf) in modes {
        let plain = against_reference(
            &format!("{mode:?} unclipped"),
            &pair,
            &cam,
            &tf,
            mode,
            0.7,
            &RefExtras::default(),
        );
        for (what, ext) in [("box", box_ext()), ("planes", planes_ext())] {
            let mut both = ext.clone();
            both.clip_box = box_ext().clip_box;
            for (tag, ext) in [(what, ext), ("box+planes", both)] {
                let img = against_reference(
                    &format!("{mode:?} {tag}"),
                    &pair,
                    &cam,
                    &tf,
                    mode,
                    0.7,
                    &ext,
                );
                let d = compare_images(&img, &plain, 3);
                assert!(d.over > 20, "{mode:?} {tag}: clipping changed little: {d}");
            }
        }
    }
}

#[test]
fn clipping_everything_away_leaves_the_background() {
    let pair = phantom_pair();
    let cam = lib_camera(&oblique());
    let tf = lib_tf(&RefTf::ramp(255.0));
    for mode in [
        RenderMode::Dvr,
        RenderMode::Mip,
        RenderMode::Minip,
        RenderMode::Avg,
        RenderMode::Iso,
    ] {
        for clip in [
            Clip {
                clip_box: Some((Vec3::splat(100.0), Vec3::splat(120.0))),
                planes: vec![],
            },
            Clip {
                clip_box: None,
                planes: vec![ClipPlane {
                    normal: Vec3::NEG_Y,
                    offset: -1000.0,
                }],
            },
        ] {
            let o = RenderOptions {
                mode,
                iso_value: 100.0,
                background: Vec3::new(0.2, 0.4, 0.6),
                clip,
                ..RenderOptions::default()
            };
            let img = render_all(
                &format!("{mode:?} nothing kept"),
                &pair.scene,
                &cam,
                &tf,
                &o,
            );
            assert!(
                img.chunks_exact(3).all(|p| p == [51, 102, 153]),
                "{mode:?}: something left"
            );
        }
    }
}

#[test]
fn clipped_space_is_empty_in_the_skip_grid() {
    let pair = make_pair(
        [64, 64, 64],
        [1.0; 3],
        TestLayout::Linear,
        phantom([64, 64, 64]),
    );
    let scene = &pair.scene;
    let tf = lib_tf(&RefTf::ramp(255.0));
    let lut = TfLut::new(&tf, 0.5);
    let clip = Clip {
        clip_box: Some((Vec3::splat(10.0), Vec3::splat(30.0))),
        planes: vec![ClipPlane {
            normal: Vec3::X,
            offset: 20.0,
        }],
    };
    let region = clip.region(scene.grid()).unwrap();
    for occ in [Occupancy::Visible, Occupancy::Every, Occupancy::IsoValue] {
        let full = occ.skip_grid(scene, &lut, 100.0, None).occupied_count();
        let clipped = occ.skip_grid(scene, &lut, 100.0, Some(&region));
        let n = clipped.count();
        let total = (n.x * n.y * n.z) as usize;
        assert!(
            clipped.occupied_count() * 10 < total && clipped.occupied_count() <= full,
            "{occ:?}: {} of {total} cells occupied with the clip",
            clipped.occupied_count()
        );
        if occ == Occupancy::Every {
            assert!(clipped.occupied_count() > 0);
        }
    }
    // The object renderer takes fewer samples... and the same image.
    let cam = Camera::look_at(Vec3::new(90.0, 70.0, 100.0), Vec3::splat(20.0), 40, 40);
    let o = RenderOptions {
        clip,
        ert: false,
        ..RenderOptions::default()
    };
    render_all("skip grid scene", scene, &cam, &tf, &o);
}

/// A ramp along x, `v = 4x`, with x spacing 0.5: `|∇f| = 8` per world unit
/// everywhere inside. The TF is opaque only in 12..=140, so the border
/// cells along x (where the stencil is clamped) never show.
fn ramp_pair() -> Pair {
    make_pair(
        [40, 24, 24],
        [0.5, 1.0, 1.0],
        TestLayout::Linear,
        |x, _, _| (4 * x) as u8,
    )
}

fn ramp_tf(opacity: f64) -> RefTf {
    let c = [0.8, 0.6, 0.3];
    RefTf::linear(vec![
        RefTf::point(11.9, c, 0.0),
        RefTf::point(12.0, c, opacity),
        RefTf::point(140.0, c, opacity),
        RefTf::point(140.1, c, 0.0),
    ])
}

/// Blocks of one value (uniform macrocells inside) side by side with blocks
/// of another value that the `shapes` TF gives the same colour (92 and 94
/// red, 97 and 100 blue, 105 green): macrocells whose samples are
/// composited without being taken. Skipping (which finds those cells)
/// changes no pixel, with ERT and shading on or off, and every renderer
/// gives the same image.
#[test]
fn cells_composited_without_sampling_change_no_pixel() {
    let pair = make_pair(
        [48, 40, 36],
        [1.0, 1.0, 1.0],
        TestLayout::Linear,
        |x, y, z| {
            let inside = |lo: u32, hi: u32, v: u32| (lo..hi).contains(&v);
            if inside(4, 20, x) && inside(4, 30, y) && inside(6, 30, z) {
                if x < 12 { 92 } else { 94 }
            } else if inside(24, 44, x) && inside(8, 36, y) && inside(4, 24, z) {
                if y < 20 { 97 } else { 100 }
            } else if inside(26, 40, x) && inside(10, 20, y) && inside(26, 34, z) {
                105
            } else {
                0
            }
        },
    );
    let cells = pair.scene.macrocells();
    assert!(cells.uniform.iter().any(|&u| u), "no uniform macrocell");
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let lut = TfLut::new(&tf, 0.3);
    let one_colour = cells
        .ranges
        .iter()
        .zip(&cells.uniform)
        .filter(|&(&(lo, hi), &u)| !u && lo < hi && lut.constant_over(lo, hi))
        .count();
    assert!(one_colour > 0, "no mixed macrocell of one colour");
    let cam = lib_camera(&RefCamera::perspective(
        [90.0, 70.0, 80.0],
        [24.0, 20.0, 18.0],
        48,
        40,
    ));
    for (ert, shading) in [(false, false), (true, false), (true, true)] {
        let o = RenderOptions {
            step: Some(0.3),
            ert,
            shading,
            ..RenderOptions::default()
        };
        let rgb = render_all("blocks", &pair.scene, &cam, &tf, &o);
        assert!(coverage(&rgb) > 0.1, "blocks: {}", coverage(&rgb));
    }
}

#[test]
fn gradient_opacity_on_a_linear_ramp_scales_opacity_by_the_known_weight() {
    let pair = ramp_pair();
    let cam = RefCamera::perspective([10.0, 40.0, 45.0], [10.0, 11.0, 11.0], 40, 40);
    let go = |g0, g1| RefExtras {
        gradient_opacity: Some((g0, g1)),
        ..Default::default()
    };
    let none = RefExtras::default();
    let full = against_reference("ramp", &pair, &cam, &ramp_tf(0.6), RefMode::Dvr, 0.5, &none);
    assert!(coverage(&full) > 0.5);
    // |∇f| = 8: (4, 12) gives w = 0.5, the image of half the opacity.
    let half = against_reference(
        "ramp w=0.5",
        &pair,
        &cam,
        &ramp_tf(0.6),
        RefMode::Dvr,
        0.5,
        &go(4.0, 12.0),
    );
    let want = against_reference(
        "ramp a/2",
        &pair,
        &cam,
        &ramp_tf(0.3),
        RefMode::Dvr,
        0.5,
        &none,
    );
    let d = compare_images(&half, &want, 2);
    assert!(d.over == 0, "w = 0.5 is not half the opacity: {d}");
    assert!(
        compare_images(&half, &full, 3).over > 100,
        "w = 0.5 changed nothing"
    );
    // (1, 7.5): w = 1 — the TF's own opacity.
    let one = against_reference(
        "ramp w=1",
        &pair,
        &cam,
        &ramp_tf(0.6),
        RefMode::Dvr,
        0.5,
        &go(1.0, 7.5),
    );
    assert!(one == full, "w = 1 changed the image");
    // (8.5, 20): w = 0 — nothing.
    let zero = against_reference(
        "ramp w=0",
        &pair,
        &cam,
        &ramp_tf(0.6),
        RefMode::Dvr,
        0.5,
        &go(8.5, 20.0),
    );
    assert_eq!(coverage(&zero), 0.0, "w = 0 left something visible");
}

#[test]
fn gradient_opacity_on_the_phantom_matches_the_reference() {
    let pair = phantom_pair();
    let cam = oblique();
    let plain = against_reference(
        "phantom",
        &pair,
        &cam,
        &dvr_tf(),
        RefMode::Dvr,
        0.6,
        &RefExtras::default(),
    );
    let ext = RefExtras {
        gradient_opacity: Some((15.0, 60.0)),
        ..Default::default()
    };
    let img = against_reference(
        "phantom gradient opacity",
        &pair,
        &cam,
        &dvr_tf(),
        RefMode::Dvr,
        0.6,
        &ext,
    );
    assert!(compare_images(&img, &plain, 3).over > 50);
    // With clipping and jitter at once.
    let all = RefExtras {
        jitter_seed: Some(3),
        ..planes_ext()
    };
    let all = RefExtras {
        gradient_opacity: Some((15.0, 60.0)),
        ..all
    };
    against_reference(
        "phantom everything",
        &pair,
        &cam,
        &dvr_tf(),
        RefMode::Dvr,
        0.6,
        &all,
    );
}

#[test]
fn minip_matches_the_reference_and_skipping_saves_samples() {
    // The inverted phantom: dark balls in a bright room.
    let f = phantom(DIMS);
    let pair = make_pair(DIMS, SPACING, TestLayout::Linear, move |x, y, z| {
        255 - f(x, y, z)
    });
    let cam = oblique();
    let tf = RefTf::linear(vec![
        RefTf::point(0.0, [1.0, 0.9, 0.2], 1.0),
        RefTf::point(255.0, [0.1, 0.2, 0.9], 0.3),
    ]);
    let img = against_reference(
        "minip",
        &pair,
        &cam,
        &tf,
        RefMode::Minip,
        0.5,
        &RefExtras::default(),
    );
    let mip = against_reference(
        "mip",
        &pair,
        &cam,
        &tf,
        RefMode::Mip,
        0.5,
        &RefExtras::default(),
    );
    assert!(
        compare_images(&img, &mip, 3).over > 100,
        "minip looks like mip"
    );
    let bricked = make_pair(DIMS, SPACING, TestLayout::Bricked(8), move |x, y, z| {
        255 - f(x, y, z)
    });
    against_reference(
        "minip bricked",
        &bricked,
        &cam,
        &tf,
        RefMode::Minip,
        0.5,
        &RefExtras::default(),
    );
    // ESS skips cells that cannot lower the minimum: fewer samples.
    let o = lib_options(RefMode::Minip, 0.5, &RefExtras::default(), true);
    let (c, t) = (lib_camera(&cam), lib_tf(&tf));
    let on = SerialRenderer::new()
        .render(&pair.scene, &c, &t, &o)
        .unwrap();
    let off = SerialRenderer::new()
        .render(&pair.scene, &c, &t, &RenderOptions { ess: false, ..o })
        .unwrap();
    assert_eq!(on.rgb, off.rgb);
    assert!(
        on.stats.samples * 10 < off.stats.samples * 9,
        "ESS took {} of {} samples",
        on.stats.samples,
        off.stats.samples
    );
}

#[test]
fn the_jitter_hash_is_the_documented_one_and_in_range() {
    for seed in [0, 1, 77, u32::MAX] {
        for j in (0..2000).step_by(37) {
            for i in (0..2000).step_by(53) {
                let a = raycaster::integrator::jitter(i, j, seed);
                assert!((0.0..1.0).contains(&a));
                assert_eq!(
                    a as f64,
                    r::ref_jitter(i, j, seed),
                    "({i}, {j}) seed {seed}"
                );
            }
        }
    }
}

#[test]
fn jitter_is_deterministic_identical_across_renderers_and_changes_the_image() {
    let pair = phantom_pair();
    let cam = oblique();
    let jit = |seed| RefExtras {
        jitter_seed: Some(seed),
        ..Default::default()
    };
    for (mode, tf) in [
        (RefMode::Dvr, dvr_tf()),
        (RefMode::Mip, RefTf::ramp(255.0)),
        (RefMode::Avg, RefTf::ramp(255.0)),
    ] {
        // A coarse step, where jitter matters.
        let plain = against_reference(
            &format!("{mode:?}"),
            &pair,
            &cam,
            &tf,
            mode,
            2.5,
            &RefExtras::default(),
        );
        let a = against_reference(
            &format!("{mode:?} jitter 0"),
            &pair,
            &cam,
            &tf,
            mode,
            2.5,
            &jit(0),
        );
        let again = against_reference(
            &format!("{mode:?} jitter 0 again"),
            &pair,
            &cam,
            &tf,
            mode,
            2.5,
            &jit(0),
        );
        let b = against_reference(
            &format!("{mode:?} jitter 9"),
            &pair,
            &cam,
            &tf,
            mode,
            2.5,
            &jit(9),
        );
        assert!(a == again, "{mode:?}: jitter is not deterministic");
        assert!(
            compare_images(&a, &plain, 2).over > 50,
            "{mode:?}: jitter changed little"
        );
        assert!(
            compare_images(&a, &b, 2).over > 50,
            "{mode:?}: the seed changed little"
        );
        // With clipping.
        let both = RefExtras {
            jitter_seed: Some(5),
            ..box_ext()
        };
        against_reference(
            &format!("{mode:?} jitter+box"),
            &pair,
            &cam,
            &tf,
            mode,
            2.5,
            &both,
        );
    }
}

#[test]
fn iso_is_clipped_alike_in_every_renderer_and_ignores_jitter() {
    let pair = phantom_pair();
    let cam = lib_camera(&oblique());
    let tf = lib_tf(&RefTf::ramp(255.0));
    let base = RenderOptions {
        mode: RenderMode::Iso,
        iso_value: 100.0,
        ..RenderOptions::default()
    };
    let plain = render_all("iso", &pair.scene, &cam, &tf, &base);
    for ext in [box_ext(), planes_ext()] {
        let o = lib_options(RefMode::Iso(100.0), 0.5, &ext, true);
        let o = RenderOptions { step: None, ..o };
        let img = render_all("iso clipped", &pair.scene, &cam, &tf, &o);
        assert!(compare_images(&img, &plain, 3).over > 20);
        // Explicit bricks split iso rays too: the pieces must join up.
        let bricks = object(6).render(&pair.scene, &cam, &tf, &o).unwrap().rgb;
        assert!(compare_images(&img, &bricks, 2).over == 0);
    }
    let jittered = RenderOptions {
        jitter: true,
        seed: 4,
        ..base.clone()
    };
    assert!(render_all("iso jitter", &pair.scene, &cam, &tf, &jittered) == plain);
}

#[test]
fn bad_clip_and_gradient_options_are_errors_naming_the_option() {
    let pair = phantom_pair();
    let cam = lib_camera(&oblique());
    let tf = lib_tf(&RefTf::ramp(255.0));
    let cases: Vec<(RenderOptions, &str)> = vec![
        (
            RenderOptions {
                clip: Clip {
                    clip_box: Some((Vec3::new(5.0, 0.0, 0.0), Vec3::new(4.0, 9.0, 9.0))),
                    planes: vec![],
                },
                ..RenderOptions::default()
            },
            "clip-box",
        ),
        (
            RenderOptions {
                clip: Clip {
                    clip_box: None,
                    planes: vec![ClipPlane {
                        normal: Vec3::ZERO,
                        offset: 0.0,
                    }],
                },
                ..RenderOptions::default()
            },
            "clip-plane",
        ),
        (
            RenderOptions {
                clip: Clip {
                    clip_box: None,
                    planes: vec![
                        ClipPlane {
                            normal: Vec3::X,
                            offset: 0.0
                        };
                        7
                    ],
                },
                ..RenderOptions::default()
            },
            "clip-plane",
        ),
        (
            RenderOptions {
                gradient_opacity: Some(GradientOpacity { g0: 5.0, g1: 5.0 }),
                ..RenderOptions::default()
            },
            "gradient-opacity",
        ),
    ];
    for (o, needle) in cases {
        let e = SerialRenderer::new()
            .render(&pair.scene, &cam, &tf, &o)
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle) && !e.contains('\n'), "{e}");
    }
}

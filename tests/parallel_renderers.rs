//! The parallel renderers against the serial one (every renderer takes the
//! same samples, so the images agree).
//!
//! Every scene — linear and bricked volumes, cameras outside, grazing,
//! orthographic and inside the volume, every mode, ERT and ESS on and off,
//! shading on and off — is rendered by `SerialRenderer`, by `TiledRenderer`
//! and by `ObjectRenderer` in several configurations (1–3 render threads,
//! with and without compositing threads, tiny to large bricks and tiles).
//!
//! The tiled renderer integrates each ray whole, exactly as the serial one;
//! the object renderer integrates a ray brick by brick, taking the same
//! samples and compositing them in the same order (runs of samples that
//! are composited without being taken, too, sample by sample): every image
//! must be identical. (Where the comparisons below allow a tolerance, it
//! is checked to be unused; the figures are printed with `--nocapture`.)

mod common;

use std::sync::atomic::AtomicBool;

use common::scenes::tf_points;
use common::{TestLayout, compare_images, make_pair, phantom};
use glam::Vec3;
use raycaster::prelude::*;

const MIN_PSNR: f64 = 50.0;
const MAX_LEVELS: u8 = 2;

/// Library cameras around, beside and inside a box.
fn cameras(scene: &Scene) -> Vec<(&'static str, Camera)> {
    let b = scene.grid().bounds();
    let c = b.center();
    let diag = (b.max - b.min).length();
    let at = |off: Vec3| c + off * diag;
    let mut v = Vec::new();
    v.push(("front", Camera::look_at(at(Vec3::Z), c, 40, 32)));
    let mut oblique = Camera::look_at(at(Vec3::new(0.7, 0.5, 0.8)), c, 44, 44);
    oblique.fov_y_deg = 38.0;
    oblique.up = Vec3::new(0.1, 1.0, 0.0);
    v.push(("oblique", oblique));
    // Down the x axis from the far side, image rows along the box's faces.
    let mut axis = Camera::look_at(at(Vec3::new(-1.2, 0.0, 0.0)), c, 36, 30);
    axis.fov_y_deg = 50.0;
    v.push(("axis", axis));
    // Inside, near a corner, looking across: t_in = 0 for every ray and
    // bricks all around the eye.
    let inner = |u: Vec3| b.min + u * (b.max - b.min);
    let mut inside = Camera::look_at(
        inner(Vec3::new(0.8, 0.2, 0.85)),
        inner(Vec3::new(0.4, 0.5, 0.3)),
        48,
        48,
    );
    inside.fov_y_deg = 90.0;
    v.push(("inside", inside));
    // Inside, in the middle, looking along -z (axis-aligned rays).
    let mut centre = Camera::look_at(
        c + Vec3::new(0.3, 0.2, 0.1),
        c + Vec3::new(0.3, 0.2, -5.0),
        40,
        40,
    );
    centre.fov_y_deg = 100.0;
    v.push(("inside-centre", centre));
    let mut ortho = Camera::look_at(at(Vec3::new(0.6, 0.45, 1.0)), c, 40, 32);
    ortho.projection = Projection::Orthographic;
    ortho.fov_y_deg = 30.0;
    v.push(("ortho", ortho));
    let mut ortho_inside = Camera::look_at(c, c + Vec3::new(-1.0, 0.3, -0.2), 40, 32);
    ortho_inside.projection = Projection::Orthographic;
    ortho_inside.fov_y_deg = 60.0;
    v.push(("ortho-inside", ortho_inside));
    v
}

/// A linear TF that lets rays go deep (so bricks far from the eye matter)
/// and a step TF that stops them early.
fn tfs() -> Vec<(&'static str, TransferFunction)> {
    let soft = tf_points(
        Interpolation::Linear,
        &[
            (20.0, [0.2, 0.4, 1.0], 0.0),
            (120.0, [1.0, 0.8, 0.3], 0.08),
            (250.0, [1.0, 1.0, 1.0], 0.5),
        ],
    );
    let hard = tf_points(
        Interpolation::Step,
        &[
            (100.0, [0.9, 0.3, 0.2], 0.4),
            (150.0, [0.2, 0.9, 0.3], 1.0),
            (230.0, [1.0, 1.0, 1.0], 0.0),
        ],
    );
    vec![("soft", soft), ("hard", hard)]
}

/// The parallel renderers under test, by name.
fn parallel_renderers() -> Vec<(String, Box<dyn Renderer>)> {
    let mut v: Vec<(String, Box<dyn Renderer>)> = vec![
        (
            "tiles t2 s7".into(),
            Box::new(TiledRenderer::new(2, 7).expect("tiles")),
        ),
        (
            "object default".into(),
            RendererKind::Object.renderer(2).expect("object"),
        ),
    ];
    for (r, c, tile, brick, order) in [
        (1, 0, 16, 8, TaskOrder::TileFirst),
        (2, 1, 5, 4, TaskOrder::TileFirst),
        (3, 0, 9, 7, TaskOrder::Queue),
        (2, 0, 64, 100, TaskOrder::Queue),
    ] {
        v.push((
            format!("object r{r} c{c} t{tile} b{brick} {order:?}"),
            Box::new(
                ObjectRenderer::with_config(ObjectConfig {
                    render_threads: r,
                    composite_threads: c,
                    tile,
                    brick,
                    order,
                })
                .expect("object"),
            ),
        ));
    }
    v
}

struct Worst {
    psnr: f64,
    max: u8,
    identical: usize,
    total: usize,
    scene: String,
}

#[test]
fn parallel_renderers_match_serial() {
    let volumes = [
        (
            "linear 40x34x30",
            [40, 34, 30],
            [1.0, 1.0, 1.0],
            TestLayout::Linear,
        ),
        (
            "bricked(8) 40x34x30",
            [40, 34, 30],
            [1.0, 1.0, 1.0],
            TestLayout::Bricked(8),
        ),
        (
            "bricked(5) 23x17x31 aniso",
            [23, 17, 31],
            [1.0, 0.5, 2.0],
            TestLayout::Bricked(5),
        ),
    ];
    let modes = [
        (RenderMode::Dvr, 0.0),
        (RenderMode::Mip, 0.0),
        (RenderMode::Avg, 0.0),
        (RenderMode::Iso, 120.0),
    ];
    let mut renderers = parallel_renderers();
    let mut worst: Vec<Worst> = renderers
        .iter()
        .map(|_| Worst {
            psnr: f64::INFINITY,
            max: 0,
            identical: 0,
            total: 0,
            scene: String::new(),
        })
        .collect();
    let mut serial = SerialRenderer::new();
    let mut scenes = 0;
    let mut lit = 0;
    for (vname, dims, spacing, layout) in volumes {
        let pair = make_pair(dims, spacing, layout, phantom(dims));
        let scene = &pair.scene;
        for (cname, camera) in cameras(scene) {
            for (tname, tf) in tfs() {
                for (mode, iso) in modes {
                    // ERT only changes DVR; the TF only colours the other
                    // modes' result, so one TF is enough for them.
                    if mode != RenderMode::Dvr && tname != "soft" {
                        continue;
                    }
                    let switches: &[(bool, bool, bool)] = if mode == RenderMode::Dvr {
                        &[
                            (true, true, false),
                            (false, true, false),
                            (true, false, false),
                            (false, false, false),
                            (true, true, true),
                        ]
                    } else {
                        &[(true, true, false), (true, false, false)]
                    };
                    for &(ert, ess, shading) in switches {
                        let options = RenderOptions {
                            mode,
                            step: Some(0.45),
                            ert,
                            ess,
                            shading,
                            iso_value: iso,
                            background: Vec3::new(0.1, 0.2, 0.3),
                            ..RenderOptions::default()
                        };
                        let name = format!(
                            "{vname} {cname} {tname} {} ert={ert} ess={ess} shading={shading}",
                            mode.name()
                        );
                        let want = serial
                            .render(scene, &camera, &tf, &options)
                            .unwrap_or_else(|e| panic!("{name}: serial: {e}"));
                        scenes += 1;
                        let bg = [26u8, 51, 77];
                        if want.rgb.chunks_exact(3).any(|p| p != bg) {
                            lit += 1;
                        }
                        for ((rname, r), w) in renderers.iter_mut().zip(&mut worst) {
                            let got = r
                                .render(scene, &camera, &tf, &options)
                                .unwrap_or_else(|e| panic!("{name}: {rname}: {e}"));
                            assert_eq!((got.width, got.height), (want.width, want.height));
                            assert_eq!(got.stats.rays, want.stats.rays, "{name}: {rname}");
                            assert!(got.rgb == want.rgb, "{name}: {rname} differs");
                            if r.name() == "tiles" {
                                assert_eq!(got.stats.samples, want.stats.samples);
                            }
                            let d = compare_images(&got.rgb, &want.rgb, MAX_LEVELS);
                            assert!(
                                d.psnr >= MIN_PSNR && d.max <= MAX_LEVELS,
                                "{name}: {rname}: {d}"
                            );
                            w.total += 1;
                            if d.max == 0 {
                                w.identical += 1;
                            }
                            if d.psnr < w.psnr || d.max > w.max {
                                w.psnr = w.psnr.min(d.psnr);
                                w.max = w.max.max(d.max);
                                w.scene = name.clone();
                            }
                        }
                    }
                }
            }
        }
    }
    // Nearly every scene shows something (a few inside views may look into
    // empty space).
    assert!(
        lit * 10 >= scenes * 9,
        "only {lit} of {scenes} scenes are lit"
    );
    println!("{scenes} scenes, {lit} lit");
    for ((name, _), w) in renderers.iter().zip(&worst) {
        println!(
            "{name:<28} identical {}/{}, lowest PSNR {:.1} dB, max diff {} ({})",
            w.identical, w.total, w.psnr, w.max, w.scene
        );
    }
}

/// A volume with large empty regions, a thin shell and a dense core: brick
/// culling (ESS), the occupied-cell footprints and ERT across bricks all
/// matter. Rendered larger than the scenes above.
#[test]
fn object_renderer_on_a_sparse_volume() {
    let dims = [72, 64, 80];
    let f = move |x: u32, y: u32, z: u32| -> u8 {
        let p = Vec3::new(x as f32, y as f32, z as f32);
        let c = Vec3::new(36.0, 30.0, 44.0);
        let r = (p - c).length();
        if r < 10.0 {
            230
        } else if (22.0..24.5).contains(&r) {
            140
        } else if x.is_multiple_of(23) && y.is_multiple_of(19) {
            // Thin rods along z.
            200
        } else {
            0
        }
    };
    for layout in [TestLayout::Linear, TestLayout::Bricked(16)] {
        let pair = make_pair(dims, [1.0, 1.0, 1.0], layout, f);
        let scene = &pair.scene;
        let tf = TransferFunction::preset("skull", SampleType::U8).expect("preset");
        let mut soft = tf.clone();
        soft.points[0].opacity = 0.05;
        for (cname, camera) in cameras(scene) {
            for tf in [&tf, &soft] {
                for (ert, ess) in [(true, true), (false, false)] {
                    let options = RenderOptions {
                        step: Some(0.5),
                        ert,
                        ess,
                        ..RenderOptions::default()
                    };
                    let want = SerialRenderer::new()
                        .render(scene, &camera, tf, &options)
                        .expect("serial");
                    for brick in [0, 6, 40] {
                        let mut r = ObjectRenderer::with_config(ObjectConfig {
                            render_threads: 2,
                            composite_threads: 0,
                            tile: 12,
                            brick,
                            order: if brick == 6 {
                                TaskOrder::Queue
                            } else {
                                TaskOrder::TileFirst
                            },
                        })
                        .expect("object");
                        let got = r.render(scene, &camera, tf, &options).expect("object");
                        let d = compare_images(&got.rgb, &want.rgb, MAX_LEVELS);
                        assert!(
                            d.psnr >= MIN_PSNR && d.max <= MAX_LEVELS,
                            "{layout:?} {cname} brick {brick} ert={ert} ess={ess}: {d}"
                        );
                    }
                }
            }
        }
    }
}

/// A raised cancel flag stops every renderer: `Ok(None)`, no frame.
#[test]
fn cancelled_frames_are_not_delivered() {
    let dims = [40, 34, 30];
    let pair = make_pair(dims, [1.0; 3], TestLayout::Linear, phantom(dims));
    let camera = Camera::framing(&pair.scene.grid().bounds(), 64, 64, 45.0);
    let tf = TransferFunction::preset("skull", SampleType::U8).expect("preset");
    let flag = AtomicBool::new(true);
    for kind in RendererKind::ALL {
        let mut r = kind.renderer(2).expect("renderer");
        // The same renderer, first cancelled, then not.
        for (cancel, delivers, problem) in [
            (Cancel::flag(&flag), false, "delivered a cancelled frame"),
            (Cancel::never(), true, "delivered no frame"),
        ] {
            let got = r
                .render_cancellable(&pair.scene, &camera, &tf, &RenderOptions::default(), cancel)
                .expect("render");
            assert_eq!(got.is_some(), delivers, "{kind:?} {problem}");
        }
    }
}

/// Invalid settings are errors, not panics.
#[test]
fn bad_configurations_are_errors() {
    let bad = ObjectRenderer::with_config(ObjectConfig {
        render_threads: 0,
        composite_threads: 1,
        tile: 16,
        brick: 0,
        order: TaskOrder::TileFirst,
    });
    assert!(bad.is_err());
    let dims = [8, 8, 8];
    let pair = make_pair(dims, [1.0; 3], TestLayout::Linear, phantom(dims));
    let camera = Camera::look_at(Vec3::splat(3.0), Vec3::splat(3.0), 8, 8);
    let tf = TransferFunction::preset("skull", SampleType::U8).expect("preset");
    for kind in RendererKind::ALL {
        let mut r = kind.renderer(2).expect("renderer");
        assert!(
            r.render(&pair.scene, &camera, &tf, &RenderOptions::default())
                .is_err(),
            "{kind:?}: degenerate camera accepted"
        );
        let options = RenderOptions {
            step: Some(-1.0),
            ..RenderOptions::default()
        };
        let ok_camera = Camera::framing(&pair.scene.grid().bounds(), 8, 8, 45.0);
        assert!(r.render(&pair.scene, &ok_camera, &tf, &options).is_err());
    }
}

/// A frame cancelled while it renders stops early: well before the time the
/// whole frame takes.
#[test]
fn cancellation_stops_a_frame_in_progress() {
    use std::sync::atomic::Ordering;
    use std::time::{Duration, Instant};
    let dims = [64, 64, 64];
    let pair = make_pair(dims, [1.0; 3], TestLayout::Bricked(16), phantom(dims));
    let scene = &pair.scene;
    let b = scene.grid().bounds();
    let mut camera = Camera::look_at(
        b.center() + Vec3::new(40.0, 50.0, 90.0),
        b.center(),
        160,
        160,
    );
    camera.fov_y_deg = 50.0;
    let mut tf = TransferFunction::preset("skull", SampleType::U8).expect("preset");
    tf.points[0].opacity = 0.02;
    let options = RenderOptions {
        step: Some(0.1),
        ert: false,
        ess: false,
        ..RenderOptions::default()
    };
    for kind in RendererKind::ALL {
        let mut r = kind.renderer(2).expect("renderer");
        let start = Instant::now();
        r.render(scene, &camera, &tf, &options).expect("render");
        let full = start.elapsed();
        let flag = AtomicBool::new(false);
        let start = Instant::now();
        let got = std::thread::scope(|s| {
            s.spawn(|| {
                std::thread::sleep(full / 10);
                flag.store(true, Ordering::Relaxed);
            });
            r.render_cancellable(scene, &camera, &tf, &options, Cancel::flag(&flag))
                .expect("render")
        });
        let cancelled = start.elapsed();
        assert!(got.is_none(), "{kind:?}: a cancelled frame was delivered");
        println!(
            "{kind:?}: full frame {full:?}, cancelled after {:?} in {cancelled:?}",
            full / 10
        );
        assert!(
            // Cancelled at 10% of a frame; allow for a loaded machine.
            cancelled < full.mul_f32(0.75) + Duration::from_millis(50),
            "{kind:?}: cancelling took {cancelled:?} of a {full:?} frame"
        );
    }
}

/// The phantom's u8 value `v` as a sample of another type, by an affine map
/// that keeps the values exact (`to_data`) and the same map for TF values.
struct TypedData {
    name: &'static str,
    to_data: fn(f32) -> f32,
}

const TYPES: [TypedData; 5] = [
    TypedData {
        name: "u8",
        to_data: |v| v,
    },
    TypedData {
        name: "i8",
        to_data: |v| (v / 2.0).floor() - 64.0,
    },
    TypedData {
        name: "u16",
        to_data: |v| v * 200.0,
    },
    TypedData {
        name: "i16",
        to_data: |v| v * 16.0 - 1024.0,
    },
    TypedData {
        name: "f32",
        to_data: |v| v / 255.0 * 2.0 - 0.5,
    },
];

/// The phantom as `S` in z-fast and in x-fast order.
fn typed_volumes<S: Sample>(
    dims: [u32; 3],
    map: fn(f32) -> f32,
    cast: fn(f32) -> S,
) -> [AnyVolume; 2] {
    use raycaster::storage::Storage;
    let f = phantom(dims);
    let value = |x, y, z| cast(map(f(x, y, z) as f32));
    let grid = Grid::new(glam::UVec3::from_array(dims), Vec3::new(1.0, 0.8, 1.3));
    let z_fast = AnyVolume::from_fn(grid, |v| value(v.x, v.y, v.z));
    let mut samples = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                samples.push(value(x, y, z));
            }
        }
    }
    let x_fast = AnyVolume::linear(grid, Storage::from_vec(samples), AxisOrder::XFast)
        .expect("x-fast volume");
    [z_fast, x_fast]
}

/// Every sample type, in both linear orders, through every renderer and
/// mode: the x-fast volume renders exactly like the z-fast one, the parallel
/// renderers like the serial one, and data of another type (values and TF
/// mapped alike, exactly for u16, i16 and f32) like the u8 original (DVR,
/// MIP and iso; `avg` divides by the type's maximum, so it is compared only
/// across orders and renderers).
#[test]
fn every_sample_type_and_axis_order_renders_alike() {
    let dims = [30, 26, 22];
    let mut serial = SerialRenderer::new();
    let mut renderers = parallel_renderers();
    let (_, soft) = tfs().remove(0);
    let camera_of = |scene: &Scene| {
        let c = scene.grid().bounds().center();
        let diag = scene.grid().extent().length();
        let mut cam = Camera::look_at(c + Vec3::new(0.7, 0.5, 0.8) * diag, c, 40, 36);
        cam.fov_y_deg = 40.0;
        cam
    };
    let mut u8_images: Vec<Vec<u8>> = Vec::new();
    for t in &TYPES {
        let volumes = match t.name {
            "u8" => typed_volumes::<u8>(dims, t.to_data, |v| v as u8),
            "i8" => typed_volumes::<i8>(dims, t.to_data, |v| v as i8),
            "u16" => typed_volumes::<u16>(dims, t.to_data, |v| v as u16),
            "i16" => typed_volumes::<i16>(dims, t.to_data, |v| v as i16),
            _ => typed_volumes::<f32>(dims, t.to_data, |v| v),
        };
        let tf = TransferFunction::new(
            soft.interpolation,
            soft.points
                .iter()
                .map(|p| TfPoint {
                    value: (t.to_data)(p.value),
                    ..*p
                })
                .collect(),
        )
        .expect("mapped TF");
        let mut images = Vec::new();
        for (order, volume) in ["z-fast", "x-fast"].into_iter().zip(volumes) {
            let scene = Scene::new(volume);
            let camera = camera_of(&scene);
            for (i, (mode, iso)) in [
                (RenderMode::Dvr, 0.0),
                (RenderMode::Mip, 0.0),
                (RenderMode::Avg, 0.0),
                (RenderMode::Iso, 120.0),
            ]
            .into_iter()
            .enumerate()
            {
                let options = RenderOptions {
                    mode,
                    step: Some(0.45),
                    iso_value: (t.to_data)(iso),
                    shading: mode == RenderMode::Dvr,
                    ..RenderOptions::default()
                };
                let name = format!("{} {order} {}", t.name, mode.name());
                let want = serial
                    .render(&scene, &camera, &tf, &options)
                    .expect("serial");
                // (avg of mostly negative i8 data is black: a negative mean
                // over the type's maximum clamps to 0.)
                if mode != RenderMode::Avg {
                    assert!(want.rgb.iter().any(|&c| c > 30), "{name}: blank image");
                }
                for (rname, r) in renderers.iter_mut() {
                    let got = r.render(&scene, &camera, &tf, &options).expect("render");
                    let d = compare_images(&got.rgb, &want.rgb, MAX_LEVELS);
                    assert!(
                        d.psnr >= MIN_PSNR && d.max <= MAX_LEVELS,
                        "{name}: {rname}: {d}"
                    );
                }
                if order == "z-fast" {
                    images.push(want.rgb);
                } else {
                    assert_eq!(want.rgb, images[i], "{name}: x-fast differs from z-fast");
                }
                if t.name == "u8" {
                    u8_images.push(images[i].clone());
                } else if order == "z-fast" && mode != RenderMode::Avg && t.name != "i8" {
                    // (i8 halves the values, losing the low bit: not an
                    // exact copy of the u8 data.)
                    let d = compare_images(&images[i], &u8_images[i], 255);
                    assert!(d.psnr >= 35.0, "{name}: differs from the u8 original: {d}");
                }
            }
        }
    }
}

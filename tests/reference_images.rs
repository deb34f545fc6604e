//! The library's images against the independent f64 reference of
//! `tests/common/reference.rs`, scene by scene.
//!
//! Every scene is rendered by `SerialRenderer` and `TiledRenderer` (which must
//! agree byte for byte: every renderer takes the same samples) with
//! shading off, and by the reference. Run with `--nocapture` to see the error
//! figures of every scene.
//!
//! # Tolerances
//!
//! The library works in f32 and tabulates the TF (16 entries per value unit,
//! linear TFs interpolated between entries); the reference evaluates
//! everything exactly in f64. Away from discontinuities that costs at most a
//! level or two per channel (rounding of `round(255·x)` near .5, `powf` in f32,
//! interpolation of the premultiplied table). Where the TF is a step, or the
//! data has hard edges, a sample whose interpolated value lies within ~1e-5
//! of a step (e.g. exactly 85.0 in f64 and 84.99999 in f32) lands on the other
//! side of it, and that pixel can be off by tens of levels; likewise a ray
//! grazing the box may get one sample more or less at `t_out`. Such pixels are
//! isolated, so the checks are: PSNR >= 45 dB over the image and at most 0.5%
//! of the pixels (and never more than 4) differing by more than 3 levels.
//! Iso scenes (exact crossings, SPEC §8) are two-coloured: a ray grazing the
//! surface within rounding hits in one precision and misses in the other,
//! so instead of PSNR each differing pixel must lie on the reference's
//! silhouette.
//!
//! Observed (450 scenes, 2.9k-4k pixels each): 399 scenes are identical or
//! within 1 level everywhere (all MIP, avg and iso scenes, all bricked
//! layouts, the skull and ramp presets). The rest are DVR scenes with the
//! custom TF (a vertical edge at 120, which the library's table blurs over
//! 1/16 of a value unit) or single pixels at a `shapes` step: worst max diff
//! 55 levels on 12 px, worst count 14 px of 4096 (0.34%) over 3 levels,
//! lowest PSNR 49.8 dB.

mod common;

use common::reference::{self as r, RefCamera, RefMode, RefOptions, RefProjection, RefTf, V3};
use common::{
    ImageDiff, Pair, TestLayout, compare_images, lib_camera, lib_tf, make_pair, make_pair_typed,
    phantom,
};
use raycaster::prelude::*;

/// Levels a pixel may differ by without counting as "different".
const LEVELS: u8 = 3;
/// Minimum PSNR of a scene against the reference.
const MIN_PSNR: f64 = 45.0;
/// Share of pixels allowed to differ by more than `LEVELS`.
const MAX_SHARE_OVER: f64 = 0.005;
/// ...but at least this many may, in small images.
const MIN_ALLOWED_OVER: usize = 4;

const DIMS_A: [u32; 3] = [48, 40, 36];
const DIMS_B: [u32; 3] = [23, 17, 31];
const SPACING_B: V3 = [1.0, 0.5, 2.0];

/// One scene: data, camera, TF, options.
struct Case<'a> {
    name: String,
    pair: &'a Pair,
    camera: RefCamera,
    tf: RefTf,
    /// The library's TF (a preset or the reference TF's points).
    lib_tf: TransferFunction,
    opts: RefOptions,
    ert: bool,
    ess: bool,
    /// Give the library `step: None` (its default, half the smallest spacing).
    default_step: bool,
}

fn lib_options(c: &Case) -> RenderOptions {
    let (mode, iso) = match c.opts.mode {
        RefMode::Dvr => (RenderMode::Dvr, 0.0),
        RefMode::Mip => (RenderMode::Mip, 0.0),
        RefMode::Minip => (RenderMode::Minip, 0.0),
        RefMode::Avg => (RenderMode::Avg, 0.0),
        RefMode::Iso(v) => (RenderMode::Iso, v as f32),
    };
    RenderOptions {
        mode,
        step: (!c.default_step).then_some(c.opts.step as f32),
        ert: c.ert,
        ert_threshold: c.opts.ert.unwrap_or(0.99) as f32,
        ess: c.ess,
        shading: false,
        phong: None,
        iso_value: iso,
        lights: Vec::new(),
        shadows: false,
        iso_normals: Default::default(),
        background: common::v3f(c.opts.background),
        ..RenderOptions::default()
    }
}

struct Outcome {
    name: String,
    diff: ImageDiff,
    /// Share of pixels not showing the background.
    coverage: f64,
    /// Number of distinct colours in the library's image.
    colours: usize,
    ok: bool,
}

/// Renders a case three ways and compares.
fn run(c: &Case) -> Outcome {
    assert_eq!(
        c.ert,
        c.opts.ert.is_some(),
        "{}: ERT flags disagree",
        c.name
    );
    let cam = lib_camera(&c.camera);
    let opts = lib_options(c);
    let serial = SerialRenderer::new()
        .render(&c.pair.scene, &cam, &c.lib_tf, &opts)
        .unwrap_or_else(|e| panic!("{}: serial render failed: {e}", c.name));
    let tiled = TiledRenderer::new(3, 8)
        .unwrap()
        .render(&c.pair.scene, &cam, &c.lib_tf, &opts)
        .unwrap_or_else(|e| panic!("{}: tiled render failed: {e}", c.name));
    assert_eq!(
        serial.rgb, tiled.rgb,
        "{}: serial and tiled renderers differ",
        c.name
    );
    assert_eq!(serial.stats.samples, tiled.stats.samples, "{}", c.name);
    let reference = r::render(&c.pair.reference, &c.camera, &c.tf, &c.opts);
    let diff = compare_images(&serial.rgb, &reference, LEVELS);
    let allowed = ((diff.pixels as f64 * MAX_SHARE_OVER) as usize).max(MIN_ALLOWED_OVER);
    let ok = if let RefMode::Iso(_) = c.opts.mode {
        // Exact iso images are two-coloured (unshaded): a ray grazing the
        // surface within f32 rounding of a tangent hits in one precision
        // and not in the other, a whole pixel apart, which PSNR cannot
        // absorb. So: as many differing pixels as elsewhere, each on the
        // reference's silhouette (a neighbour there has our colour).
        diff.over <= allowed && silhouette_only(&serial.rgb, &reference, c.camera.width)
    } else {
        diff.psnr >= MIN_PSNR && diff.over <= allowed
    };
    let bg = common::to_rgb8(c.opts.background);
    let lit = serial.rgb.chunks_exact(3).filter(|p| *p != bg).count();
    let mut colours: Vec<&[u8]> = serial.rgb.chunks_exact(3).collect();
    colours.sort();
    colours.dedup();
    Outcome {
        name: c.name.clone(),
        diff,
        coverage: lit as f64 / diff.pixels as f64,
        colours: colours.len(),
        ok,
    }
}

/// Whether every pixel where `ours` differs from `reference` (by more than
/// [`LEVELS`]) has a 4-neighbour in `reference` with our colour.
fn silhouette_only(ours: &[u8], reference: &[u8], width: u32) -> bool {
    let w = width as usize;
    let h = ours.len() / 3 / w;
    let px = |img: &[u8], x: usize, y: usize| {
        let i = 3 * (y * w + x);
        [img[i], img[i + 1], img[i + 2]]
    };
    let close = |a: [u8; 3], b: [u8; 3]| (0..3).all(|c| a[c].abs_diff(b[c]) <= LEVELS);
    (0..h).all(|y| {
        (0..w).all(|x| {
            let mine = px(ours, x, y);
            if close(mine, px(reference, x, y)) {
                return true;
            }
            let neighbours = [(0, 1), (2, 1), (1, 0), (1, 2)];
            neighbours.iter().any(|&(dx, dy)| {
                let (nx, ny) = ((x + dx).wrapping_sub(1), (y + dy).wrapping_sub(1));
                nx < w && ny < h && close(mine, px(reference, nx, ny))
            })
        })
    })
}

/// Prints every outcome, then fails if any scene is out of tolerance.
fn report(title: &str, outcomes: &[Outcome]) {
    println!("--- {title}");
    for o in outcomes {
        println!(
            "{} {:<44} {}  (lit {:3.0}%, {:4} colours)",
            if o.ok { "  ok " } else { "FAIL " },
            o.name,
            o.diff,
            100.0 * o.coverage,
            o.colours
        );
    }
    let bad: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.ok)
        .map(|o| o.name.as_str())
        .collect();
    assert!(bad.is_empty(), "{title}: scenes out of tolerance: {bad:?}");
}

/// Named cameras around (and one inside) the box of `pair`, at distances
/// proportional to the box's diagonal so the volume fills much of the image.
fn cameras(pair: &Pair) -> Vec<(&'static str, RefCamera)> {
    let (lo, hi) = pair.reference.bounds();
    let c = r::scale(r::add(lo, hi), 0.5);
    let diag = r::length(r::sub(hi, lo));
    let at = |off: V3| r::add(c, r::scale(off, diag));
    let front = RefCamera::perspective(at([0.0, 0.0, 1.0]), c, 64, 48);
    let mut oblique = RefCamera::perspective(at([0.7, 0.5, 0.8]), c, 56, 56);
    oblique.fov_deg = 38.0;
    oblique.up = [0.1, 1.0, 0.0];
    // Looking up along +y: the default up vector would be parallel to d.
    let mut below = RefCamera::perspective(at([0.05, -1.1, 0.15]), c, 60, 48);
    below.up = [0.0, 0.0, 1.0];
    let mut close =
        RefCamera::perspective(at([0.1, 0.05, 0.6]), r::add(c, [2.0, -1.0, 0.0]), 72, 56);
    close.fov_deg = 55.0;
    // Inside the box, in a nearly empty corner, looking at the centre:
    // t_in = 0 for every ray.
    let inner = |u: V3| [0, 1, 2].map(|a| lo[a] + u[a] * (hi[a] - lo[a]));
    let mut inside =
        RefCamera::perspective(inner([0.88, 0.15, 0.92]), inner([0.4, 0.5, 0.3]), 64, 64);
    inside.fov_deg = 75.0;
    let mut ortho = RefCamera::perspective(at([0.6, 0.45, 1.0]), c, 64, 48);
    ortho.projection = RefProjection::Orthographic;
    ortho.fov_deg = 30.0;
    vec![
        ("front", front),
        ("oblique", oblique),
        ("below", below),
        ("close-up", close),
        ("inside", inside),
        ("ortho", ortho),
    ]
}

/// A linear TF with a sharp edge at 120 (two points at the same value) and
/// a smooth part above.
fn custom_tf() -> RefTf {
    let pt = RefTf::point;
    RefTf::linear(vec![
        pt(30.0, [0.2, 0.4, 1.0], 0.0),
        pt(120.0, [0.2, 0.4, 1.0], 0.05),
        pt(120.0, [1.0, 0.8, 0.2], 0.5),
        pt(200.0, [1.0, 0.3, 0.3], 0.9),
        pt(255.0, [1.0, 1.0, 1.0], 0.9),
    ])
}

/// (name, reference TF, library TF): the `shapes`, `skull` and `ramp`
/// presets (library side: the library's own presets) and the custom one.
fn tfs() -> Vec<(&'static str, RefTf, TransferFunction)> {
    let preset = |n: &str| TransferFunction::preset(n, SampleType::U8).expect("preset");
    vec![
        ("shapes", RefTf::shapes(), preset("shapes")),
        ("skull", RefTf::skull(), preset("skull")),
        ("ramp", RefTf::ramp(255.0), preset("ramp")),
        ("custom", custom_tf(), lib_tf(&custom_tf())),
    ]
}

fn dvr_opts(step: f64, ert: bool, background: V3) -> RefOptions {
    RefOptions {
        mode: RefMode::Dvr,
        step,
        ert: ert.then_some(0.99),
        background,
    }
}

#[test]
fn dvr_every_camera_and_tf_linear_volume() {
    let pair = make_pair(DIMS_A, [1.0; 3], TestLayout::Linear, phantom(DIMS_A));
    let mut out = Vec::new();
    for (cam_name, cam) in cameras(&pair) {
        for (tf_name, tf, ltf) in tfs() {
            out.push(run(&Case {
                name: format!("dvr {cam_name} {tf_name}"),
                pair: &pair,
                camera: cam,
                tf,
                lib_tf: ltf,
                opts: dvr_opts(0.5, true, [0.0; 3]),
                ert: true,
                ess: true,
                default_step: true,
            }));
        }
    }
    report("DVR, 48x40x36 linear, ERT+ESS on, default step 0.5", &out);
}

#[test]
fn bricked_layouts_match_linear_and_reference() {
    let f = phantom(DIMS_A);
    let linear = make_pair(DIMS_A, [1.0; 3], TestLayout::Linear, f);
    let cams = cameras(&linear);
    let mut out = Vec::new();
    for side in [2u32, 5, 16] {
        let bricked = make_pair(DIMS_A, [1.0; 3], TestLayout::Bricked(side), f);
        for &(cam_name, cam) in [&cams[1], &cams[4], &cams[5]] {
            for (tf_name, tf, ltf) in tfs().into_iter().take(2) {
                for (mode_name, mode) in [("dvr", RefMode::Dvr), ("mip", RefMode::Mip)] {
                    let case = Case {
                        name: format!("B={side} {mode_name} {cam_name} {tf_name}"),
                        pair: &bricked,
                        camera: cam,
                        tf: tf.clone(),
                        lib_tf: ltf.clone(),
                        opts: RefOptions {
                            mode,
                            ..dvr_opts(0.5, true, [0.0; 3])
                        },
                        ert: true,
                        ess: true,
                        default_step: false,
                    };
                    // The same data in the linear layout gives the same image.
                    let cam_l = lib_camera(&cam);
                    let opts = lib_options(&case);
                    let a = SerialRenderer::new()
                        .render(&linear.scene, &cam_l, &ltf, &opts)
                        .unwrap();
                    let b = SerialRenderer::new()
                        .render(&bricked.scene, &cam_l, &ltf, &opts)
                        .unwrap();
                    assert_eq!(a.rgb, b.rgb, "{}: linear and bricked differ", case.name);
                    out.push(run(&case));
                }
            }
        }
    }
    report("bricked B = 2, 5, 16 (identical to linear)", &out);
}

#[test]
fn non_uniform_spacing_on_an_odd_grid() {
    let f = phantom(DIMS_B);
    let mut out = Vec::new();
    for layout in [
        TestLayout::Linear,
        TestLayout::Bricked(5),
        TestLayout::Bricked(16),
    ] {
        let pair = make_pair(DIMS_B, SPACING_B, layout, f);
        for (cam_name, cam) in cameras(&pair) {
            for (tf_name, tf, ltf) in tfs() {
                if layout != TestLayout::Linear && tf_name != "shapes" && tf_name != "custom" {
                    continue;
                }
                out.push(run(&Case {
                    name: format!("{layout:?} dvr {cam_name} {tf_name}"),
                    pair: &pair,
                    camera: cam,
                    tf,
                    lib_tf: ltf,
                    // Default step: half the smallest spacing, 0.25.
                    opts: dvr_opts(0.25, true, [0.0; 3]),
                    ert: true,
                    ess: true,
                    default_step: true,
                }));
            }
        }
    }
    report("23x17x31, spacing (1, 0.5, 2)", &out);
}

#[test]
fn mip_avg_and_iso_modes() {
    let mut out = Vec::new();
    let a = make_pair(DIMS_A, [1.0; 3], TestLayout::Linear, phantom(DIMS_A));
    let b = make_pair(DIMS_B, SPACING_B, TestLayout::Bricked(5), phantom(DIMS_B));
    let iso_tf = custom_tf();
    for (pair, data) in [(&a, "A"), (&b, "B")] {
        for (cam_name, cam) in cameras(pair) {
            let modes: [(&str, RefMode, RefTf); 5] = [
                ("mip ramp", RefMode::Mip, RefTf::ramp(255.0)),
                ("mip custom", RefMode::Mip, custom_tf()),
                ("avg", RefMode::Avg, RefTf::ramp(255.0)),
                ("iso 100", RefMode::Iso(100.0), iso_tf.clone()),
                ("iso 60.5", RefMode::Iso(60.5), iso_tf.clone()),
            ];
            for (mode_name, mode, tf) in modes {
                for ess in [true, false] {
                    out.push(run(&Case {
                        name: format!("{data} {mode_name} {cam_name} ess={ess}"),
                        pair,
                        camera: cam,
                        lib_tf: lib_tf(&tf),
                        tf: tf.clone(),
                        opts: RefOptions {
                            mode,
                            step: 0.4,
                            ert: Some(0.99),
                            background: [0.0; 3],
                        },
                        ert: true,
                        ess,
                        default_step: false,
                    }));
                }
            }
        }
    }
    report("MIP / avg / iso", &out);
}

#[test]
fn ert_and_ess_switches() {
    let pair = make_pair(DIMS_A, [1.0; 3], TestLayout::Bricked(9), phantom(DIMS_A));
    let cams = cameras(&pair);
    let mut out = Vec::new();
    for &(cam_name, cam) in [&cams[0], &cams[1], &cams[4]] {
        for (tf_name, tf, ltf) in tfs() {
            for ert in [false, true] {
                for ess in [false, true] {
                    out.push(run(&Case {
                        name: format!("dvr {cam_name} {tf_name} ert={ert} ess={ess}"),
                        pair: &pair,
                        camera: cam,
                        tf: tf.clone(),
                        lib_tf: ltf.clone(),
                        opts: dvr_opts(0.7, ert, [0.0; 3]),
                        ert,
                        ess,
                        default_step: false,
                    }));
                }
            }
        }
    }
    report("ERT / ESS on and off, step 0.7", &out);
}

#[test]
fn non_black_background() {
    let bg = [0.2, 0.35, 0.6];
    let pair = make_pair(DIMS_A, [1.0; 3], TestLayout::Linear, phantom(DIMS_A));
    let mut out = Vec::new();
    for (cam_name, cam) in cameras(&pair) {
        let modes: [(&str, RefMode, RefTf); 5] = [
            ("dvr shapes", RefMode::Dvr, RefTf::shapes()),
            ("dvr custom", RefMode::Dvr, custom_tf()),
            ("mip custom", RefMode::Mip, custom_tf()),
            ("avg", RefMode::Avg, RefTf::ramp(255.0)),
            ("iso 150", RefMode::Iso(150.0), custom_tf()),
        ];
        for (mode_name, mode, tf) in modes {
            out.push(run(&Case {
                name: format!("bg {mode_name} {cam_name}"),
                pair: &pair,
                camera: cam,
                lib_tf: lib_tf(&tf),
                tf,
                opts: RefOptions {
                    mode,
                    step: 0.5,
                    ert: Some(0.99),
                    background: bg,
                },
                ert: true,
                ess: true,
                default_step: false,
            }));
        }
    }
    report("background (0.2, 0.35, 0.6)", &out);
}

/// A grid origin away from 0, volumes one or two samples thick along an
/// axis (flat boxes: a ray meets them in one point or a short chord), and
/// u16 data (the `ramp` preset spans 0..65535, `avg` divides by 65535).
#[test]
fn origin_thin_volumes_and_u16() {
    let mut out = Vec::new();
    let modes = |tf: RefTf| -> Vec<(&'static str, RefMode, RefTf)> {
        vec![
            ("dvr", RefMode::Dvr, tf.clone()),
            ("mip", RefMode::Mip, tf.clone()),
            ("avg", RefMode::Avg, tf.clone()),
            ("iso", RefMode::Iso(90.5), tf),
        ]
    };
    let mut scenes: Vec<(String, Pair, RefTf, TransferFunction)> = Vec::new();
    let d = [30u32, 26, 22];
    scenes.push((
        "origin (-12.5, 4, 7.25)".into(),
        make_pair_typed(
            d,
            [0.8, 1.1, 0.6],
            [-12.5, 4.0, 7.25],
            TestLayout::Bricked(7),
            phantom(d),
        ),
        custom_tf(),
        lib_tf(&custom_tf()),
    ));
    // Varies along every axis, so a slab of one or two samples shows it.
    let wavy = |x: u32, y: u32, z: u32| {
        let (x, y, z) = (x as f64, y as f64, z as f64);
        (127.5 + 127.0 * (0.45 * x + 0.9 * y).sin() * (0.35 * z - 1.1 * y).cos()).round() as u8
    };
    for d in [[26u32, 1, 20], [24, 2, 18], [1, 21, 17]] {
        for layout in [TestLayout::Linear, TestLayout::Bricked(4)] {
            scenes.push((
                format!("{}x{}x{} {layout:?}", d[0], d[1], d[2]),
                make_pair(d, [1.0, 1.3, 0.9], layout, wavy),
                RefTf::ramp(255.0),
                TransferFunction::preset("ramp", SampleType::U8).unwrap(),
            ));
        }
    }
    let d = [28u32, 24, 20];
    let p = phantom(d);
    scenes.push((
        "u16".into(),
        make_pair_typed(
            d,
            [1.0; 3],
            [0.0; 3],
            TestLayout::Bricked(8),
            move |x, y, z| p(x, y, z) as u16 * 200,
        ),
        RefTf::ramp(65535.0),
        TransferFunction::preset("ramp", SampleType::U16).unwrap(),
    ));
    for (name, pair, tf, ltf) in &scenes {
        let iso = if name == "u16" { 90.5 * 200.0 } else { 90.5 };
        for (cam_name, cam) in cameras(pair) {
            // Edge-on views of the flat boxes show (almost) nothing.
            let thin = name.contains('x');
            if thin && (cam_name == "front" || cam_name == "close-up") {
                continue;
            }
            for (mode_name, mode, tf) in modes(tf.clone()) {
                let mode = if let RefMode::Iso(_) = mode {
                    RefMode::Iso(iso)
                } else {
                    mode
                };
                out.push(run(&Case {
                    name: format!("{name} {mode_name} {cam_name}"),
                    pair,
                    camera: cam,
                    tf,
                    lib_tf: ltf.clone(),
                    opts: RefOptions {
                        mode,
                        step: 0.35,
                        ert: Some(0.99),
                        background: [0.1, 0.1, 0.1],
                    },
                    ert: true,
                    ess: true,
                    default_step: false,
                }));
            }
        }
    }
    report("origin, thin volumes, u16", &out);
}

/// The library's camera rays follow the camera's ray formula (checked
/// against the reference's f64 rays directly, pixel by pixel).
#[test]
fn camera_rays_match_the_spec_formula() {
    let pair = make_pair([9, 9, 9], [1.0; 3], TestLayout::Linear, |_, _, _| 0);
    for (name, cam) in cameras(&pair) {
        let f = lib_camera(&cam).frame().expect("camera frame");
        for j in 0..cam.height {
            for i in 0..cam.width {
                let (o, d) = cam.ray(i, j);
                let ray = f.ray(i, j);
                let ed = (ray.dir - common::v3f(d)).length();
                let eo = (ray.origin - common::v3f(o)).length();
                assert!(ed < 1e-5, "{name} pixel ({i}, {j}): direction off by {ed}");
                assert!(eo < 1e-3, "{name} pixel ({i}, {j}): origin off by {eo}");
            }
        }
    }
}

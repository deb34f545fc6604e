//! UI tests of the viewer: the real [`ViewerApp`] (real loading thread, real
//! render thread) driven headlessly through `egui_kittest`, by the labels a
//! user sees.

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{TempDir, radial_vol_file};
use egui::{Event, Modifiers, PointerButton};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::{UVec3, Vec3};
use raycaster::format::vol::VolLayout;
use raycaster::integrator::RenderMode;
use raycaster::render::RendererKind;
use raycaster::sample::SampleType;
use raycaster::transfer::TransferFunction;
use vol_app::viewer::progressive::{Level, REFINEMENT};
use vol_app::viewer::state::{LightAngles, ResolutionChoice};
use vol_app::viewer::{Settings, StartOptions, ViewerApp};

const TIMEOUT: Duration = Duration::from_secs(25);

type H = Harness<'static, Option<ViewerApp>>;

/// A `dims` volume holding a ball of value 100 (inside the `shapes` TF's
/// bands) and a smaller one of 200, written as a `.vol` file.
fn volume_file(dir: &TempDir, name: &str, dims: UVec3, layout: VolLayout) -> PathBuf {
    let r = dims.min_element() as f32 * 0.4;
    radial_vol_file(dir, name, dims, layout, |d| {
        if d < r * 0.4 {
            200
        } else if d < r {
            100
        } else {
            0
        }
    })
}

/// Settings that render quickly: a small fixed-size image.
fn quick_settings() -> Settings {
    Settings {
        resolution: ResolutionChoice::Fixed,
        fixed_size: 240,
        ..Settings::default()
    }
}

fn harness(start: StartOptions, settings: Settings) -> H {
    let mut h: H = Harness::builder()
        .with_size(egui::vec2(1000.0, 1300.0))
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(
            |ui, app: &mut Option<ViewerApp>| {
                if let Some(app) = app {
                    app.show(ui);
                }
            },
            None,
        );
    let ctx = h.ctx.clone();
    *h.state_mut() = Some(ViewerApp::new(&ctx, settings, start));
    h
}

fn app(h: &H) -> &ViewerApp {
    h.state().as_ref().unwrap()
}

fn app_mut(h: &mut H) -> &mut ViewerApp {
    h.state_mut().as_mut().unwrap()
}

/// Steps the UI until `cond` holds.
fn step_until(h: &mut H, what: &str, cond: impl Fn(&ViewerApp) -> bool) {
    let start = Instant::now();
    loop {
        h.step();
        if cond(app(h)) {
            return;
        }
        assert!(start.elapsed() < TIMEOUT, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(3));
    }
}

/// Steps until nothing is loading or rendering and a frame is on screen.
fn settle(h: &mut H) {
    step_until(h, "the viewer to settle", |a| {
        !a.is_loading() && !a.is_rendering() && a.frames_received() > 0
    });
    // One more frame so that panels show the final state.
    h.step();
}

/// Distinct RGB values in the frame on screen.
fn distinct_colours(a: &ViewerApp) -> usize {
    let f = &a.last_frame().expect("a frame").frame;
    let mut seen: Vec<[u8; 3]> = f.rgb.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    seen.sort_unstable();
    seen.dedup();
    seen.len()
}

/// The frame on screen answers the newest request (nothing stale is shown).
fn frame_is_current(a: &ViewerApp) -> bool {
    match (a.last_frame(), a.last_request()) {
        (Some(f), Some(r)) => f.camera == r.camera && f.preview == r.preview && f.level == r.level,
        _ => false,
    }
}

#[derive(Debug)]
struct Dropped(PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

/// A viewer started on `start` with [`quick_settings`], settled.
fn settled_harness(start: StartOptions) -> H {
    let mut h = harness(start, quick_settings());
    settle(&mut h);
    h
}

fn open_file(dir: &TempDir) -> (H, PathBuf) {
    let path = volume_file(dir, "ball.vol", UVec3::new(40, 36, 32), VolLayout::Linear);
    let h = settled_harness(StartOptions {
        file: Some(path.clone()),
        tf_preset: Some("shapes".into()),
        tf: None,
        raw: None,
        ..Default::default()
    });
    (h, path)
}

/// `--no-cache`: the viewer opens a volume without writing the macrocell
/// cache beside it; without it the cache appears.
#[test]
fn no_cache_leaves_no_cache_file() {
    let dir = TempDir::new("no_cache");
    let path = volume_file(&dir, "ball.vol", UVec3::new(30, 26, 22), VolLayout::Linear);
    let caches = || {
        std::fs::read_dir(dir.path("."))
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().ends_with(".rcidx"))
            })
            .count()
    };
    let h = settled_harness(StartOptions {
        file: Some(path.clone()),
        no_cache: true,
        ..Default::default()
    });
    assert!(app(&h).volume().is_some(), "{:?}", app(&h).error());
    assert_eq!(caches(), 0, "--no-cache wrote a cache file");
    drop(h);
    let h = settled_harness(StartOptions {
        file: Some(path),
        ..Default::default()
    });
    assert!(app(&h).volume().is_some());
    assert_eq!(caches(), 1, "the cache was not written");
}

/// Drops `path` on the window and steps until it is open and rendered.
fn drop_file(h: &mut H, path: &Path) {
    h.input_mut()
        .dropped_files
        .push(Arc::new(Dropped(path.to_path_buf())));
    step_until(h, &format!("the dropped {}", path.display()), |a| {
        a.volume()
            .is_some_and(|v| v.info.path.as_deref() == Some(path))
    });
    settle(h);
}

/// Presses or releases `button` at `pos`.
fn button(h: &mut H, pos: egui::Pos2, button: PointerButton, pressed: bool) {
    h.event(Event::PointerButton {
        pos,
        button,
        pressed,
        modifiers: Modifiers::NONE,
    });
}

/// Presses `which` at `start` and moves the pointer `moves` times by
/// `delta` (the button stays down); returns where the pointer ends.
fn press_and_move(
    h: &mut H,
    start: egui::Pos2,
    which: PointerButton,
    delta: egui::Vec2,
    moves: usize,
) -> egui::Pos2 {
    h.event(Event::PointerMoved(start));
    button(h, start, which, true);
    let mut p = start;
    for _ in 0..moves {
        p += delta;
        h.event(Event::PointerMoved(p));
    }
    p
}

/// Opens the combo box `combo` and picks `item`.
fn choose(h: &mut H, combo: &str, item: &str) {
    h.get_by_label(combo).click();
    h.step();
    h.step();
    h.get_by_label(item).click();
    h.step();
}

#[test]
fn starts_on_the_demo_volume_and_renders_it() {
    // The defaults: the render resolution follows the canvas.
    let mut h = harness(StartOptions::default(), Settings::default());
    let t = Instant::now();
    settle(&mut h);
    let a = app(&h);
    let v = a.volume().expect("the demo volume");
    assert_eq!(v.info.name, "built-in demo");
    assert!(a.error().is_none());
    assert_eq!(
        a.settings().tf_preset.as_deref(),
        Some(vol_app::demo::DEMO_TF)
    );
    assert!(
        distinct_colours(a) > 50,
        "the canvas is not a rendered volume"
    );
    assert!(frame_is_current(a));
    eprintln!("demo: first full frame after {:?}", t.elapsed());
    h.get_by_label("built-in demo");
    h.get_by_label("160 × 160 × 160");
    h.get_by_label_contains("samples");
    // Settled: refined to full quality, at the default step of half the
    // smallest spacing (the demo's is 1), as `vol_app render`.
    h.get_by_label_contains("full quality");
    let shown = app(&h).last_frame().unwrap();
    assert_eq!(shown.level, Level::FULL);
    assert_eq!(shown.step, 0.5);
    let f = &shown.frame;
    let canvas = h.get_by_label("Volume canvas").rect();
    assert!(
        canvas.width() > 500.0,
        "the left panel leaves room for the canvas"
    );
    assert_eq!(
        (f.width, f.height),
        (
            canvas.width().round() as u32,
            canvas.height().round() as u32
        ),
        "the image follows the canvas"
    );
    // Every control a user can act on has a name (screen readers, tests).
    h.check_accessibility();
}

#[test]
fn opens_a_dropped_file_and_shows_its_information() {
    let dir = TempDir::new("drop");
    let (mut h, _) = open_file(&dir);
    let before = app(&h).frames_received();
    let bricked = volume_file(
        &dir,
        "bricked.vol",
        UVec3::new(30, 26, 22),
        VolLayout::Bricked { side: 8 },
    );
    drop_file(&mut h, &bricked);
    let a = app(&h);
    let info = &a.volume().unwrap().info;
    assert_eq!(info.dims, UVec3::new(30, 26, 22));
    assert!(a.frames_received() > before);
    assert!(frame_is_current(a));
    assert!(distinct_colours(a) > 10);
    for label in [
        "bricked.vol",
        "30 × 26 × 22",
        "u8",
        "0 … 200",
        "bricked (B = 8)",
        "memory-mapped",
    ] {
        h.get_by_label(label);
    }
    h.get_by_label_contains("KiB");
}

#[test]
fn opens_a_16_bit_nifti_with_a_rescale_and_shows_what_the_file_stores() {
    let dir = TempDir::new("nifti");
    let (mut h, _) = open_file(&dir);
    // A ball stored as u16 0/500 with slope 2, intercept -100: data units
    // -100 and 900, held as i16.
    let dims = UVec3::new(28, 24, 20);
    let c = (dims.as_vec3() - 1.0) * 0.5;
    let mut bytes = Vec::new();
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let inside = (UVec3::new(x, y, z).as_vec3() - c).length() < 8.0;
                bytes.extend_from_slice(&(if inside { 500u16 } else { 0 }).to_le_bytes());
            }
        }
    }
    let path = dir.path("ball.nii.gz");
    raycaster::format::nifti::write(
        &path,
        dims,
        Vec3::new(1.0, 1.0, 2.0),
        SampleType::U16,
        Some(raycaster::format::Rescale {
            slope: 2.0,
            intercept: -100.0,
        }),
        raycaster::format::samples::bytes(&bytes),
    )
    .unwrap();
    drop_file(&mut h, &path);
    let a = app(&h);
    assert!(a.error().is_none(), "{:?}", a.error());
    let info = &a.volume().unwrap().info;
    assert_eq!(info.sample_type, SampleType::I16);
    assert_eq!(info.value_range, (-100.0, 900.0));
    assert!(frame_is_current(a));
    for label in [
        "NIfTI-1",
        "28 × 24 × 20",
        "i16",
        "-100 … 900",
        "linear (x fastest)",
        "u16, little-endian, gzip",
        "value = stored × 2 + -100",
    ] {
        h.get_by_label(label);
    }
}

#[test]
fn opens_a_raw_file_described_on_the_command_line() {
    let dir = TempDir::new("raw");
    let vol_path = volume_file(&dir, "ball.vol", UVec3::new(30, 26, 22), VolLayout::Linear);
    // The .vol's samples are z fastest: the same bytes as a z-fast raw file.
    let raw_path = dir.path("ball.raw");
    std::fs::write(&raw_path, &std::fs::read(&vol_path).unwrap()[26..]).unwrap();
    let mut raw = raycaster::format::RawOptions::new(
        UVec3::new(30, 26, 22),
        SampleType::U8,
        raycaster::format::Endian::Little,
    );
    raw.order = raycaster::volume::AxisOrder::ZFast;
    let h = settled_harness(StartOptions {
        file: Some(raw_path.clone()),
        tf_preset: Some("shapes".into()),
        raw: Some(raw),
        ..Default::default()
    });
    let a = app(&h);
    assert!(a.error().is_none(), "{:?}", a.error());
    let info = &a.volume().expect("the raw volume").info;
    assert_eq!(info.path.as_deref(), Some(raw_path.as_path()));
    assert_eq!(info.value_range, (0.0, 200.0));
    assert!(distinct_colours(a) > 10);
    h.get_by_label("raw");
    h.get_by_label("30 × 26 × 22");
}

#[test]
fn switching_tf_preset_and_mode_renders_new_frames() {
    let dir = TempDir::new("tf_mode");
    let (mut h, _) = open_file(&dir);
    assert_eq!(app(&h).settings().tf_preset.as_deref(), Some("shapes"));
    let first = app(&h).last_frame().unwrap().frame.rgb.clone();

    choose(&mut h, "Preset", "skull");
    let skull = TransferFunction::preset("skull", SampleType::U8).unwrap();
    assert_eq!(app(&h).settings().tf, skull);
    settle(&mut h);
    let a = app(&h);
    assert_eq!(a.last_request().unwrap().tf, skull);
    assert!(frame_is_current(a));
    assert_ne!(
        a.last_frame().unwrap().frame.rgb,
        first,
        "the new TF changed nothing"
    );

    let n = app(&h).frames_received();
    h.get_by_label("MIP").click();
    h.step();
    assert_eq!(app(&h).settings().mode, RenderMode::Mip);
    settle(&mut h);
    let a = app(&h);
    assert_eq!(a.last_request().unwrap().options.mode, RenderMode::Mip);
    assert!(a.frames_received() > n);
    assert!(frame_is_current(a));

    // Iso mode shows its slider.
    h.get_by_label("Iso").click();
    h.step();
    settle(&mut h);
    assert!(h.query_all_by_label("Iso value").count() > 0);
    assert_eq!(
        app(&h).last_request().unwrap().options.mode,
        RenderMode::Iso
    );
}

#[test]
fn iso_shadows_and_lights_reach_the_renderer() {
    let dir = TempDir::new("lights");
    let (mut h, _) = open_file(&dir);
    let opts = |h: &H| app(h).last_request().unwrap().options.clone();
    // The light controls belong to iso mode.
    assert_eq!(h.query_all_by_label("Shadows").count(), 0);
    h.get_by_label("Iso").click();
    h.step();
    settle(&mut h);
    assert_eq!(opts(&h).mode, RenderMode::Iso);
    assert!(opts(&h).lights.is_empty() && !opts(&h).shadows);
    h.get_by_label("Headlight");
    let headlit = app(&h).last_frame().unwrap().frame.rgb.clone();

    h.get_by_label("Faceted normals").click();
    h.step();
    settle(&mut h);
    assert_eq!(
        opts(&h).iso_normals,
        raycaster::integrator::IsoNormals::Analytic
    );
    assert_ne!(
        app(&h).last_frame().unwrap().frame.rgb,
        headlit,
        "faceted normals changed nothing"
    );
    h.get_by_label("Faceted normals").click();
    h.step();
    settle(&mut h);
    assert_eq!(opts(&h).iso_normals, Default::default());

    // The reflection slider reaches the renderer and changes the picture.
    assert_eq!(opts(&h).reflection, 0.0);
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "Reflection")
        .set_value_accesskit(0.5);
    h.step();
    settle(&mut h);
    assert_eq!(opts(&h).reflection, 0.5);
    assert!(frame_is_current(app(&h)));
    assert_ne!(
        app(&h).last_frame().unwrap().frame.rgb,
        headlit,
        "the reflection changed nothing"
    );
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "Reflection")
        .set_value_accesskit(0.0);
    h.step();
    settle(&mut h);
    assert_eq!(opts(&h).reflection, 0.0);

    h.get_by_label("Shadows").click();
    h.get_by_label("Add light").click();
    h.step();
    settle(&mut h);
    assert!(app(&h).settings().shadows);
    assert_eq!(app(&h).settings().lights, vec![LightAngles::default()]);
    assert!(opts(&h).shadows);
    assert_eq!(opts(&h).lights, vec![LightAngles::default().direction()]);
    assert!(frame_is_current(app(&h)));
    assert_ne!(
        app(&h).last_frame().unwrap().frame.rgb,
        headlit,
        "the light changed nothing"
    );
    assert_eq!(h.query_all_by_label("Headlight").count(), 0);

    // Azimuth 90°, elevation 0°: the light is on the +x side.
    let slider = |h: &H, label: &str, value: f64| {
        h.get_by_role_and_label(egui::accesskit::Role::Slider, label)
            .set_value_accesskit(value);
    };
    slider(&h, "Light 1 azimuth °", 90.0);
    slider(&h, "Light 1 elevation °", 0.0);
    h.step();
    settle(&mut h);
    let l = opts(&h).lights;
    assert_eq!(l.len(), 1);
    assert!((l[0] - Vec3::X).length() < 1e-6, "{l:?}");
    assert!(frame_is_current(app(&h)));

    // Up to four lights; removing them all is the headlight again.
    for _ in 0..5 {
        h.get_by_label("Add light").click();
        h.step();
    }
    assert_eq!(app(&h).settings().lights.len(), 4);
    settle(&mut h);
    assert_eq!(opts(&h).lights.len(), 4);
    while !app(&h).settings().lights.is_empty() {
        h.get_all_by_label("Remove").next().unwrap().click();
        h.step();
    }
    settle(&mut h);
    assert!(opts(&h).lights.is_empty() && opts(&h).shadows);
    h.get_by_label("Headlight");
}

#[test]
fn ert_and_ess_toggles_reach_the_renderer() {
    let dir = TempDir::new("ert_ess");
    let (mut h, _) = open_file(&dir);
    let opts = |h: &H| app(h).last_request().unwrap().options.clone();
    assert!(opts(&h).ert && opts(&h).ess);
    let samples_with = app(&h).last_frame().unwrap().frame.stats.samples;

    h.get_by_label("Early ray termination (ERT)").click();
    h.step();
    settle(&mut h);
    assert!(!app(&h).settings().ert);
    assert!(!opts(&h).ert && opts(&h).ess);

    h.get_by_label("Empty-space skipping (ESS)").click();
    h.step();
    settle(&mut h);
    assert!(!opts(&h).ert && !opts(&h).ess);
    assert!(frame_is_current(app(&h)));
    let samples_without = app(&h).last_frame().unwrap().frame.stats.samples;
    assert!(
        samples_without > samples_with,
        "turning ERT and ESS off should take more samples ({samples_without} vs {samples_with})"
    );

    // The renderer choice reaches the status line.
    choose(&mut h, "Renderer", "serial");
    settle(&mut h);
    assert_eq!(app(&h).settings().renderer, RendererKind::Serial);
    assert_eq!(app(&h).last_frame().unwrap().renderer, "serial");
    h.get_by_label_contains("serial ×1");
}

/// Sets the slider labelled `label` as a screen reader would.
fn set_slider(h: &H, label: &str, value: f64) {
    h.get_by_role_and_label(egui::accesskit::Role::Slider, label)
        .set_value_accesskit(value);
}

#[test]
fn the_crop_box_sliders_reach_the_renderer_and_reset() {
    let dir = TempDir::new("crop");
    let (mut h, _) = open_file(&dir);
    let opts = |h: &H| app(h).last_request().unwrap().options.clone();
    assert!(opts(&h).clip.clip_box.is_none());
    let full = app(&h).last_frame().unwrap().frame.clone();
    let bounds = app(&h).volume().unwrap().scene.grid().bounds();

    set_slider(&h, "x max", 0.5);
    set_slider(&h, "z min", 0.25);
    h.step();
    settle(&mut h);
    assert_eq!(
        app(&h).settings().clip.crop,
        [0.0, 0.0, 0.25, 0.5, 1.0, 1.0]
    );
    let (lo, hi) = opts(&h).clip.clip_box.expect("a crop box");
    let size = bounds.max - bounds.min;
    let want_lo = bounds.min + glam::Vec3::new(0.0, 0.0, 0.25) * size;
    let want_hi = bounds.min + glam::Vec3::new(0.5, 1.0, 1.0) * size;
    assert!((lo - want_lo).length() < 1e-4, "{lo} vs {want_lo}");
    assert!((hi - want_hi).length() < 1e-4, "{hi} vs {want_hi}");
    assert!(frame_is_current(app(&h)));
    let cropped = app(&h).last_frame().unwrap().frame.clone();
    assert!(
        cropped.stats.samples < full.stats.samples,
        "cropping a quarter and a half away took {} samples against {}",
        cropped.stats.samples,
        full.stats.samples
    );
    assert_ne!(cropped.rgb, full.rgb);

    // A min slider dragged past its max pushes the max along.
    set_slider(&h, "x min", 0.75);
    h.step();
    let c = app(&h).settings().clip.crop;
    assert!(c[0] <= c[3], "{c:?}");

    h.get_by_label("Reset crop box").click_accesskit();
    h.step();
    settle(&mut h);
    assert!(opts(&h).clip.clip_box.is_none());
    assert_eq!(app(&h).last_frame().unwrap().frame.rgb, full.rgb);
}

#[test]
fn gradient_opacity_shows_the_gradient_histogram_and_reaches_the_renderer() {
    let dir = TempDir::new("gradient_opacity");
    let (mut h, _) = open_file(&dir);
    let opts = |h: &H| app(h).last_request().unwrap().options.clone();
    assert!(opts(&h).gradient_opacity.is_none());
    assert!(h.query_by_label("Gradient-magnitude histogram").is_none());
    let plain = app(&h).last_frame().unwrap().frame.rgb.clone();
    // The balls' edges: a gradient of 100 per voxel side and more.
    let gh = &app(&h).volume().unwrap().gradient_histogram;
    assert!(gh.hi > 10.0, "{}", gh.hi);
    assert!(gh.counts[gh.bin_of(0.0)] > 0);

    h.get_by_label("Gradient opacity (DVR)").click();
    h.step();
    h.get_by_label("Gradient-magnitude histogram");
    set_slider(&h, "g0: hidden below", 1.0);
    set_slider(&h, "g1: full from", 5.0);
    h.step();
    settle(&mut h);
    let go = opts(&h).gradient_opacity.expect("gradient opacity on");
    assert_eq!((go.g0, go.g1), (1.0, 5.0));
    assert!(frame_is_current(app(&h)));
    // The balls' flat insides disappear: the image changes.
    assert_ne!(app(&h).last_frame().unwrap().frame.rgb, plain);

    h.get_by_label("Gradient opacity (DVR)").click();
    h.step();
    settle(&mut h);
    assert!(opts(&h).gradient_opacity.is_none());
    assert_eq!(app(&h).last_frame().unwrap().frame.rgb, plain);
}

#[test]
fn dragging_on_the_canvas_orbits_pans_and_renders_new_frames() {
    let dir = TempDir::new("drag");
    let (mut h, _) = open_file(&dir);
    let canvas = h.get_by_label("Volume canvas").rect();
    let cam0 = *app(&h).camera();
    let n0 = app(&h).frames_received();

    // Left drag: orbit, with preview frames while the button is down.
    let p0 = canvas.center();
    let p = press_and_move(&mut h, p0, PointerButton::Primary, egui::vec2(15.0, 5.0), 6);
    h.step();
    let during = app(&h).last_request().unwrap().clone();
    assert!(during.preview, "a moving camera should get preview frames");
    button(&mut h, p, PointerButton::Primary, false);
    settle(&mut h);
    let a = app(&h);
    let cam1 = *a.camera();
    assert!(
        cam1.azimuth < cam0.azimuth - 20.0,
        "{} -> {}",
        cam0.azimuth,
        cam1.azimuth
    );
    assert!(cam1.elevation > cam0.elevation);
    assert_eq!(cam1.target, cam0.target);
    assert!(a.frames_received() > n0);
    assert!(frame_is_current(a));
    // (A preview can be full quality already, when that is fast enough.)
    assert_eq!(
        a.last_frame().unwrap().level,
        Level::FULL,
        "full quality once the drag ends"
    );
    let f = a.last_frame().unwrap();
    assert_eq!(
        f.camera.position,
        cam1.camera(f.frame.width, f.frame.height).position
    );

    // Right drag: pan.
    let n1 = a.frames_received();
    let end = press_and_move(
        &mut h,
        p0,
        PointerButton::Secondary,
        egui::vec2(-10.0, 0.0),
        5,
    );
    button(&mut h, end, PointerButton::Secondary, false);
    settle(&mut h);
    let a = app(&h);
    assert_ne!(a.camera().target, cam1.target, "right drag pans");
    assert_eq!(a.camera().azimuth, cam1.azimuth);
    assert!(a.frames_received() > n1);
    assert!(frame_is_current(a));

    // Wheel: zoom in.
    let d = a.camera().distance;
    h.event(Event::PointerMoved(p0));
    h.event(Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 120.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Unknown,
        modifiers: Modifiers::NONE,
    });
    settle(&mut h);
    step_until(&mut h, "the zoom to settle", |a| {
        !a.is_rendering() && a.last_request().unwrap().level == Level::FULL
    });
    assert!(app(&h).camera().distance < d, "the wheel zooms in");

    // Reset camera.
    h.get_by_label("Reset camera").click();
    h.step();
    assert_eq!(*app(&h).camera(), cam0);
}

#[test]
fn a_corrupt_file_shows_an_error_and_keeps_the_volume() {
    let dir = TempDir::new("corrupt");
    let (mut h, good) = open_file(&dir);
    let frames = app(&h).frames_received();
    let corrupt = dir.path("corrupt.vol");
    std::fs::write(&corrupt, b"not a volume at all").unwrap();

    // Through the path field and its Load button.
    h.get_by_label("Path:")
        .set_text_value_accesskit(&corrupt.display().to_string());
    h.step();
    h.get_by_label("Load").click();
    h.step();
    assert!(app(&h).is_loading() || app(&h).error().is_some());
    step_until(&mut h, "the load to fail", |a| !a.is_loading());
    h.step();
    let a = app(&h);
    let err = a.error().expect("an error is shown").to_string();
    assert!(err.contains("corrupt.vol"), "{err}");
    assert_eq!(
        a.volume().unwrap().info.path.as_deref(),
        Some(good.as_path())
    );
    assert!(a.last_frame().is_some());
    h.get_by_label_contains("corrupt.vol");
    h.get_by_label("ball.vol");

    // A header that promises more bytes than the file holds.
    let truncated = dir.path("truncated.vol");
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    app_mut(&mut h).open(&truncated);
    step_until(&mut h, "the load to fail", |a| !a.is_loading());
    h.step();
    let err = app(&h).error().unwrap().to_string();
    assert!(err.contains("truncated.vol"), "{err}");
    assert_eq!(
        app(&h).volume().unwrap().info.path.as_deref(),
        Some(good.as_path())
    );

    // The app keeps working: dismiss the error, change the mode, get a frame.
    h.get_by_label("Dismiss").click();
    h.step();
    assert!(app(&h).error().is_none());
    h.get_by_label("X-ray").click();
    h.step();
    settle(&mut h);
    assert!(app(&h).frames_received() > frames);
    assert!(frame_is_current(app(&h)));
}

#[test]
fn a_bad_file_argument_falls_back_to_the_demo_with_an_error() {
    let mut h = harness(
        StartOptions {
            file: Some("/nonexistent/head.vol".into()),
            ..Default::default()
        },
        Settings {
            resolution: ResolutionChoice::Fixed,
            fixed_size: 96,
            ..Settings::default()
        },
    );
    settle(&mut h);
    let a = app(&h);
    assert!(a.error().unwrap().contains("/nonexistent/head.vol"));
    assert_eq!(a.volume().unwrap().info.name, "built-in demo");
    assert_eq!(a.last_frame().unwrap().frame.width, 96);
}

#[test]
fn the_tf_editor_adds_points_and_the_tf_round_trips_through_json() {
    let dir = TempDir::new("tf_edit");
    let (mut h, _) = open_file(&dir);
    let n = app(&h).settings().tf.points.len();
    let curve = h.get_by_label("Transfer function curve").rect();
    // Double-click empty space high up in the curve area: a new point.
    let at = curve.left_top() + egui::vec2(curve.width() * 0.2, 20.0);
    for _ in 0..2 {
        for pressed in [true, false] {
            button(&mut h, at, PointerButton::Primary, pressed);
        }
    }
    h.event(Event::PointerMoved(at));
    h.step();
    h.step();
    let s = app(&h).settings();
    assert_eq!(s.tf.points.len(), n + 1, "double-click adds a point");
    assert_eq!(s.tf_preset, None, "an edited TF is no longer the preset");
    assert!(s.tf.points.windows(2).all(|w| w[0].value <= w[1].value));
    h.get_by_label_contains("Point 1 of");
    settle(&mut h);
    assert_eq!(app(&h).last_request().unwrap().tf, app(&h).settings().tf);

    // Drag the last-but-one point up and to the left: higher opacity, lower
    // value, never past its neighbour; previews while the point moves.
    let k = app(&h).settings().tf.points.len() - 2;
    let before = app(&h).settings().tf.points[k];
    let start = app(&h).tf_editor().point_positions()[k];
    let p = press_and_move(
        &mut h,
        start,
        PointerButton::Primary,
        egui::vec2(-6.0, -8.0),
        5,
    );
    h.step();
    assert!(app(&h).tf_editor().is_dragging());
    assert!(
        app(&h).last_request().unwrap().preview,
        "TF drags render previews"
    );
    button(&mut h, p, PointerButton::Primary, false);
    settle(&mut h);
    let tf = &app(&h).settings().tf;
    assert!(tf.points[k].opacity > before.opacity);
    assert!(tf.points[k].value < before.value);
    assert!(tf.points[k].value >= tf.points[k - 1].value);
    assert_eq!(app(&h).last_request().unwrap().level, Level::FULL);
    assert_eq!(app(&h).last_frame().unwrap().frame.width, 240);

    let json = dir.path("tf.json");
    app_mut(&mut h).save_tf_file(&json).unwrap();
    let saved = app(&h).settings().tf.clone();
    app_mut(&mut h).set_tf_preset("ramp");
    assert_ne!(app(&h).settings().tf, saved);
    app_mut(&mut h).load_tf_file(&json).unwrap();
    assert_eq!(app(&h).settings().tf, saved);
    assert!(
        app_mut(&mut h)
            .load_tf_file(&dir.path("missing.json"))
            .is_err()
    );

    let png = dir.path("frame.png");
    app_mut(&mut h).save_frame_png(&png).unwrap();
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

/// The level and stage of every frame that reaches the screen until the
/// viewer is settled.
fn frames_until_settled(h: &mut H) -> Vec<(Level, bool)> {
    let mut seen = Vec::new();
    let mut n = app(h).frames_received();
    let start = Instant::now();
    loop {
        h.step();
        let a = app(h);
        if a.frames_received() != n {
            n = a.frames_received();
            let f = a.last_frame().unwrap();
            seen.push((f.level, f.preview));
        }
        if !a.is_rendering() && !a.is_loading() {
            return seen;
        }
        assert!(start.elapsed() < TIMEOUT, "timed out; frames {seen:?}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_moving_camera_gets_previews_and_a_still_one_refines_quarter_half_full() {
    let dir = TempDir::new("progressive");
    let (mut h, _) = open_file(&dir);
    // No time for anything: previews are the coarsest level that keeps a
    // usable image, whatever this machine's speed.
    app_mut(&mut h).set_preview_budget(Duration::ZERO);
    let full_step = app(&h).last_frame().unwrap().step;
    let canvas = h.get_by_label("Volume canvas").rect();
    for round in 0..2 {
        // Dragging: every request is a reduced, coarser preview, and no
        // refinement is asked for while the button is down.
        let p = press_and_move(
            &mut h,
            canvas.center(),
            PointerButton::Primary,
            egui::vec2(8.0, 3.0),
            4,
        );
        for _ in 0..4 {
            h.step();
            let r = app(&h).last_request().unwrap();
            assert!(r.preview, "round {round}: {:?}", r.level);
            assert_eq!(r.level, Level::new(8, 3), "240 px / 8 = 30 px");
            assert_eq!(r.step(), full_step * 3.0);
            std::thread::sleep(Duration::from_millis(5));
        }
        // Still holding the button: the preview arrives and stays.
        step_until(&mut h, "a preview on screen", |a| {
            a.last_frame()
                .is_some_and(|f| f.preview && f.frame.width == 30)
        });
        assert!(app(&h).last_request().unwrap().preview);
        // Released: ¼ → ½ → full, in order, then nothing more.
        button(&mut h, p, PointerButton::Primary, false);
        let seen = frames_until_settled(&mut h);
        let refined: Vec<Level> = seen.iter().filter(|f| !f.1).map(|f| f.0).collect();
        assert_eq!(refined, REFINEMENT, "round {round}: {seen:?}");
        assert!(
            seen.iter().skip_while(|f| f.1).all(|f| !f.1),
            "no preview after the refinement started: {seen:?}"
        );
        let a = app(&h);
        assert!(frame_is_current(a));
        assert_eq!(a.last_frame().unwrap().frame.width, 240);
        assert_eq!(a.last_frame().unwrap().step, full_step);
        h.get_by_label_contains("full quality");
        // The second round's drag is new input on a refined view: it
        // starts over with previews (checked by the loop above).
    }
    // A setting switched while still: a preview, then the refinement.
    h.get_by_label("Shading (Phong)").click();
    let seen = frames_until_settled(&mut h);
    assert_eq!(seen.first().map(|f| f.1), Some(true), "{seen:?}");
    let refined: Vec<Level> = seen.iter().filter(|f| !f.1).map(|f| f.0).collect();
    assert_eq!(refined, REFINEMENT, "{seen:?}");

    // A drag that interrupts the refinement: the refinement request in
    // progress is replaced by previews at once.
    h.get_by_label("Shading (Phong)").click();
    let mut interrupted = false;
    for _ in 0..200 {
        h.step();
        let r = app(&h).last_request().unwrap();
        if !r.preview {
            let p = press_and_move(
                &mut h,
                canvas.center(),
                PointerButton::Primary,
                egui::vec2(-5.0, 0.0),
                2,
            );
            h.step();
            let r = app(&h).last_request().unwrap();
            assert!(r.preview && r.level == Level::new(8, 3), "{:?}", r.level);
            button(&mut h, p, PointerButton::Primary, false);
            interrupted = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(interrupted, "the refinement never started");
    settle(&mut h);
    assert!(frame_is_current(app(&h)));
    assert_eq!(app(&h).last_frame().unwrap().level, Level::FULL);
}

#[test]
fn without_progressive_refinement_every_frame_is_full_quality() {
    let dir = TempDir::new("no_progressive");
    let (mut h, _) = open_file(&dir);
    h.get_by_label("Progressive refinement").click();
    h.step();
    assert!(!app(&h).settings().progressive);
    let canvas = h.get_by_label("Volume canvas").rect();
    let p = press_and_move(
        &mut h,
        canvas.center(),
        PointerButton::Primary,
        egui::vec2(8.0, 3.0),
        3,
    );
    h.step();
    let r = app(&h).last_request().unwrap();
    assert!(!r.preview && r.level == Level::FULL, "{:?}", r.level);
    button(&mut h, p, PointerButton::Primary, false);
    let seen = frames_until_settled(&mut h);
    assert!(
        seen.iter().all(|&(l, p)| l == Level::FULL && !p),
        "{seen:?}"
    );
}

#[test]
fn the_ui_keeps_running_while_a_slow_frame_renders() {
    let dir = TempDir::new("slow");
    let (mut h, _) = open_file(&dir);
    // One thread, a fine step and a large image: a slow frame.
    {
        let s = app_mut(&mut h).settings_mut();
        s.renderer = RendererKind::Serial;
        s.resolution = ResolutionChoice::Fixed;
        s.fixed_size = 1400;
        s.step_factor = 0.2;
        s.ert = false;
        s.ess = false;
    }
    h.step();
    assert!(app(&h).is_rendering());
    let mut slowest = Duration::ZERO;
    let mut steps_while_rendering = 0;
    let start = Instant::now();
    while app(&h).is_rendering() && steps_while_rendering < 30 {
        let t = Instant::now();
        h.step();
        slowest = slowest.max(t.elapsed());
        steps_while_rendering += 1;
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        steps_while_rendering >= 5,
        "the frame finished too fast to tell ({:?})",
        start.elapsed()
    );
    // Generous for loaded CI machines: a UI that waited for the frame would
    // stall for the frame's whole duration (seconds), not for a fraction.
    assert!(
        slowest < Duration::from_millis(1000),
        "a UI frame took {slowest:?}"
    );
}

/// eframe storage in memory.
#[derive(Default)]
struct MemStorage(std::collections::HashMap<String, String>);

impl eframe::Storage for MemStorage {
    fn get_string(&self, key: &str) -> Option<String> {
        self.0.get(key).cloned()
    }
    fn set_string(&mut self, key: &str, value: String) {
        self.0.insert(key.into(), value);
    }
    fn remove_string(&mut self, key: &str) {
        self.0.remove(key);
    }
    fn flush(&mut self) {}
}

#[test]
fn settings_persist_through_eframe_storage() {
    let dir = TempDir::new("persist");
    let (mut h, path) = open_file(&dir);
    h.get_by_label("MIP").click();
    h.get_by_label("Empty-space skipping (ESS)").click();
    h.step();
    h.get_by_label("Progressive refinement").click();
    h.step();
    let light = LightAngles {
        azimuth: -120.0,
        elevation: 30.0,
    };
    app_mut(&mut h).settings_mut().lights = vec![light];
    app_mut(&mut h).settings_mut().shadows = true;
    app_mut(&mut h).settings_mut().play_loop = false;
    app_mut(&mut h).settings_mut().play_fps = 24.0;
    let mut storage = MemStorage::default();
    eframe::App::save(app_mut(&mut h), &mut storage);
    let restored = Settings::load(Some(&storage));
    assert_eq!(&restored, app(&h).settings());
    assert_eq!(restored.mode, RenderMode::Mip);
    assert!(!restored.ess);
    assert!(!restored.progressive);
    assert!(restored.shadows);
    assert_eq!(restored.lights, vec![light]);
    assert!(!restored.play_loop);
    assert_eq!(restored.play_fps, 24.0);
    assert_eq!(restored.last_dir.as_deref(), path.parent());
    assert_eq!(Settings::load(None), Settings::default());
}

#[test]
fn long_file_names_do_not_widen_the_panel() {
    let dir = TempDir::new("a_rather_long_directory_name_without_any_spaces_in_it");
    let name = "a_volume_file_with_a_rather_long_name_that_must_not_widen_the_panel.vol";
    let path = volume_file(&dir, name, UVec3::new(20, 20, 20), VolLayout::Linear);
    let mut h = settled_harness(StartOptions {
        file: Some(path),
        ..Default::default()
    });
    h.run_steps(5);
    assert_eq!(app(&h).volume().unwrap().info.name, name);
    assert!(h.query_all_by_label_contains("the_panel.vol").count() > 0);
    let canvas = h.get_by_label("Volume canvas").rect();
    assert!(
        canvas.left() < 400.0,
        "the left panel grew: canvas {canvas:?}"
    );
}

/// A packed sequence of `frames` 24³ u8 frames: a ball of value 100 (inside
/// the `shapes` TF's bands) that moves along x from frame to frame.
fn sequence_file(dir: &TempDir, name: &str, frames: u32) -> PathBuf {
    let path = dir.path(name);
    let grid = raycaster::volume::Grid::new(UVec3::splat(24), Vec3::ONE);
    let frame = |k: u32| {
        let c = Vec3::new(6.0 + 3.0 * k as f32, 11.5, 11.5);
        raycaster::volume::AnyVolume::from_fn(grid, move |p| {
            if (p.as_vec3() - c).length() < 5.0 {
                100u8
            } else {
                0
            }
        })
    };
    raycaster::format::vseq::pack(&path, frames, |k| Ok(frame(k)), &Default::default(), None)
        .unwrap();
    path
}

fn sequence_harness(path: &Path, settings: Settings) -> H {
    let mut h = harness(
        StartOptions {
            file: Some(path.to_path_buf()),
            tf_preset: Some("shapes".into()),
            ..Default::default()
        },
        settings,
    );
    settle(&mut h);
    h
}

/// The number of the sequence frame on screen (from 0).
fn frame_index(a: &ViewerApp) -> u32 {
    a.timeline().expect("a timeline").current().index
}

/// Steps until frame `k` is on screen and rendered.
fn show_frame(h: &mut H, k: u32) {
    step_until(h, &format!("frame {k}"), |a| frame_index(a) == k);
    settle(h);
}

fn image(a: &ViewerApp) -> Vec<u8> {
    a.last_frame().expect("a frame").frame.rgb.clone()
}

#[test]
fn frame_starts_on_a_frame_and_space_plays_and_pauses() {
    let dir = TempDir::new("sequence_start");
    let path = sequence_file(&dir, "moving.vseq", 5);
    let start = |frame| StartOptions {
        file: Some(path.clone()),
        tf_preset: Some("shapes".into()),
        frame: Some(frame),
        ..Default::default()
    };
    let mut h = harness(start(3), quick_settings());
    settle(&mut h);
    show_frame(&mut h, 3);
    assert!(app(&h).error().is_none(), "{:?}", app(&h).error());
    h.get_by_label("Frame 4/5");

    h.key_press(egui::Key::Space);
    h.step();
    assert!(app(&h).timeline().unwrap().is_playing());
    h.key_press(egui::Key::Space);
    h.step();
    assert!(!app(&h).timeline().unwrap().is_playing());

    // A frame past the end is an error on screen; frame 0 stays.
    let mut h = harness(start(5), quick_settings());
    settle(&mut h);
    let err = app(&h).error().expect("an error").to_string();
    assert!(err.contains("--frame 5") && err.contains("0 to 4"), "{err}");
    assert_eq!(frame_index(app(&h)), 0);
}

#[test]
fn a_sequence_shows_a_timeline_that_steps_with_buttons_and_keys() {
    let dir = TempDir::new("sequence");
    let path = sequence_file(&dir, "moving.vseq", 5);
    let mut h = sequence_harness(&path, quick_settings());
    let a = app(&h);
    assert!(a.error().is_none(), "{:?}", a.error());
    assert_eq!(a.timeline().unwrap().frames(), 5);
    assert_eq!(frame_index(a), 0);
    assert!(distinct_colours(a) > 10);
    for label in ["Frame 1/5", "−1", "+1", "Loop"] {
        h.get_by_label(label);
    }
    h.get_by_label("Play");
    h.get_by_label_contains("decode");
    h.check_accessibility();
    let (camera, tf, first) = (*a.camera(), a.settings().tf.clone(), image(a));

    // +1: the next frame, rendered with the same camera and TF.
    h.get_by_label("+1").click();
    show_frame(&mut h, 1);
    h.get_by_label("Frame 2/5");
    let a = app(&h);
    assert!(frame_is_current(a));
    assert_ne!(image(a), first, "the frame on screen did not change");
    assert!(Arc::ptr_eq(
        &a.last_request().unwrap().scene,
        &a.volume().unwrap().scene
    ));
    assert_eq!(*a.camera(), camera);
    assert_eq!(a.settings().tf, tf);
    let second = image(a);

    // M and N, as in the seed's viewer.
    h.key_press(egui::Key::M);
    show_frame(&mut h, 2);
    h.get_by_label("Frame 3/5");
    h.key_press(egui::Key::N);
    h.key_press(egui::Key::N);
    show_frame(&mut h, 0);
    assert_eq!(image(app(&h)), first);
    // −1 from the first frame wraps to the last while looping.
    h.get_by_label("−1").click();
    show_frame(&mut h, 4);
    h.get_by_label("Frame 5/5");
    assert_ne!(image(app(&h)), second);
}

#[test]
fn playing_advances_the_frames_and_stops_at_the_end_without_loop() {
    let dir = TempDir::new("play");
    let path = sequence_file(&dir, "moving.vseq", 4);
    let settings = Settings {
        play_fps: 30.0,
        play_loop: false,
        ..quick_settings()
    };
    let mut h = sequence_harness(&path, settings);
    h.get_by_label("Play").click();
    h.step();
    assert!(app(&h).timeline().unwrap().is_playing());
    h.step();
    h.get_by_label("Pause");
    // Every frame is shown, in order, until the last.
    let mut seen = vec![0];
    let start = Instant::now();
    while app(&h).timeline().unwrap().is_playing() {
        h.step();
        let k = frame_index(app(&h));
        if seen.last() != Some(&k) {
            seen.push(k);
        }
        assert!(start.elapsed() < TIMEOUT, "playing did not end: {seen:?}");
        std::thread::sleep(Duration::from_millis(3));
    }
    assert_eq!(seen, [0, 1, 2, 3]);
    settle(&mut h);
    h.get_by_label("Frame 4/4");
    h.get_by_label("Play");

    // Looping: past the last frame to the first again; then pause.
    h.get_by_label("Loop").click();
    h.step();
    h.get_by_label("Play").click();
    step_until(&mut h, "the loop to start over", |a| frame_index(a) == 1);
    h.get_by_label("Pause").click();
    h.step();
    assert!(!app(&h).timeline().unwrap().is_playing());
    settle(&mut h);
    assert!(app(&h).settings().play_loop);
}

#[test]
fn a_folder_of_frames_is_a_sequence_and_a_single_volume_has_no_timeline() {
    let dir = TempDir::new("frames_dir");
    let (mut h, _) = open_file(&dir);
    assert!(app(&h).timeline().is_none());
    assert!(h.query_by_label("+1").is_none());
    assert!(h.query_by_label("Play").is_none());

    let frames = dir.path("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for (k, r) in [4.0f32, 8.0, 12.0].into_iter().enumerate() {
        let name = format!("frames/f{k}.vol");
        radial_vol_file(&dir, &name, UVec3::splat(30), VolLayout::Linear, |d| {
            if d < r { 100 } else { 0 }
        });
    }
    drop_file(&mut h, &frames);
    assert_eq!(app(&h).timeline().unwrap().frames(), 3);
    h.get_by_label("Frame 1/3");
    h.key_press(egui::Key::M);
    show_frame(&mut h, 1);
    h.get_by_label("Frame 2/3");

    // Back to one volume: the timeline goes.
    drop_file(&mut h, &dir.path("ball.vol"));
    assert!(app(&h).timeline().is_none());
    assert!(h.query_by_label("+1").is_none());
}

#[test]
fn a_corrupt_frame_is_an_error_line_not_a_panic() {
    let dir = TempDir::new("corrupt_frame");
    let path = sequence_file(&dir, "moving.vseq", 3);
    let entry = raycaster::format::vseq::VseqFile::open(&path)
        .unwrap()
        .index()[1];
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = (entry.offset + entry.len / 2) as usize;
    bytes[mid] ^= 0xff;
    std::fs::write(&path, bytes).unwrap();
    let mut h = sequence_harness(&path, quick_settings());
    h.get_by_label("+1").click();
    step_until(&mut h, "the frame's error", |a| {
        a.timeline().unwrap().error().is_some()
    });
    h.step();
    let a = app(&h);
    let e = a.timeline().unwrap().error().unwrap().to_string();
    assert!(e.contains("Frame 2"), "{e}");
    assert_eq!(frame_index(a), 0, "the first frame stays on screen");
    h.get_by_label_contains("Frame 2:");
    // Stepping goes on past the bad frame.
    h.get_by_label("+1").click();
    show_frame(&mut h, 2);
    assert!(app(&h).timeline().unwrap().error().is_none());
}

/// The crop box, clip planes, gradient opacity and jitter of the settings
/// reach the renderer and change the image.
#[test]
fn crop_box_planes_gradient_opacity_and_jitter_reach_the_renderer() {
    let dir = TempDir::new("clip");
    let (mut h, _) = open_file(&dir);
    let opts = |h: &H| app(h).last_request().unwrap().options.clone();
    assert!(opts(&h).clip.is_empty() && opts(&h).gradient_opacity.is_none());
    assert!(opts(&h).jitter, "frames are jittered by default");
    let first = app(&h).last_frame().unwrap().frame.rgb.clone();

    // The crop box (what its six sliders edit): the left 40% of the volume.
    app_mut(&mut h).settings_mut().clip.crop[3] = 0.4;
    h.step();
    settle(&mut h);
    let (lo, hi) = opts(&h).clip.clip_box.expect("a crop box");
    assert!(lo.x <= 0.0 && (hi.x - 0.4 * 39.0).abs() < 1e-3, "{lo} {hi}");
    assert!(frame_is_current(app(&h)));
    let cropped = app(&h).last_frame().unwrap().frame.rgb.clone();
    assert_ne!(cropped, first, "the crop box changed nothing");

    // A plane (what "Add clip plane" adds; the section may be scrolled
    // out of the test's window).
    let plane = vol_app::viewer::state::PlaneSetting {
        offset: 0.3,
        ..Default::default()
    };
    app_mut(&mut h).settings_mut().clip.planes.push(plane);
    h.step();
    settle(&mut h);
    assert_eq!(opts(&h).clip.planes.len(), 1);
    h.get_by_label("Gradient opacity (DVR)").click();
    h.step();
    settle(&mut h);
    assert!(opts(&h).gradient_opacity.is_some());
    app_mut(&mut h).settings_mut().clip.jitter = false;
    h.step();
    settle(&mut h);
    assert!(!opts(&h).jitter);
    assert!(h.query_all_by_label("MinIP").count() > 0);
}

/// The Metaballs mode: its controls make the balls the library makes from
/// the volume, the frame is the library's `MetaballRenderer` image of them,
/// and a change rebuilds the balls only when it must.
#[test]
fn metaballs_mode_renders_the_librarys_balls_and_rebuilds_only_what_it_must() {
    use raycaster::metaballs::{Balls, Extraction, Kernel, MetaballOptions, MetaballRenderer};

    let dir = TempDir::new("metaballs");
    let (mut h, _) = open_file(&dir);
    assert_eq!(h.query_all_by_label("Stride").count(), 0);
    h.get_by_label("Metaballs").click();
    h.step();
    settle(&mut h);
    assert_eq!(app(&h).settings().mode, RenderMode::Metaballs);

    // The frame on screen against the library, from the request's
    // parameters (full quality, after refinement).
    let check = |h: &H| {
        let a = app(h);
        let f = a.last_frame().expect("a frame");
        let r = a.last_request().expect("a request");
        assert!(frame_is_current(a));
        assert_eq!(f.level, Level::FULL);
        let p = r.metaballs;
        let balls = Balls::from_volume(
            r.scene.volume(),
            &Extraction {
                threshold: p.threshold,
                stride: p.stride,
                radius: Some(p.radius),
                max_balls: None,
            },
        )
        .unwrap();
        let info = f.metaballs.expect("a metaball frame");
        assert_eq!(info.balls, balls.len());
        assert!(info.balls > 0);
        let options = MetaballOptions {
            kernel: p.kernel,
            field_threshold: p.field_threshold,
            shading: r.options.shading,
            phong: None,
            lights: r.options.lights.clone(),
            background: r.options.background,
            shadows: r.options.shadows,
        };
        let (want, _) = MetaballRenderer::new(RendererKind::Serial, 1)
            .unwrap()
            .render(&balls, &r.camera, Some(&r.tf), &options)
            .unwrap();
        assert_eq!(
            f.frame.rgb, want.rgb,
            "the viewer's frame is not the library's"
        );
        (info, f.frame.rgb.clone(), p)
    };
    let (first, image, p0) = check(&h);
    assert_eq!(p0.stride, 2);
    h.get_by_label_contains(&format!("{} balls", first.balls));

    // The kernel changes the image, not the balls.
    h.get_by_label("murakami").click();
    h.step();
    settle(&mut h);
    let (info, murakami, p) = check(&h);
    assert_eq!(p.kernel, Kernel::Murakami);
    assert_eq!(info.builds, first.builds, "a kernel change made new balls");
    assert_ne!(murakami, image);

    // The stride makes new balls (fewer).
    set_slider(&h, "Stride", 3.0);
    h.step();
    settle(&mut h);
    let (info, _, p) = check(&h);
    assert_eq!(p.stride, 3);
    assert!(info.builds > first.builds);
    assert!(
        info.balls < first.balls,
        "{} !< {}",
        info.balls,
        first.balls
    );

    // Back to DVR: volume frames again.
    h.get_by_label("DVR").click();
    h.step();
    settle(&mut h);
    assert!(app(&h).last_frame().unwrap().metaballs.is_none());
    assert!(frame_is_current(app(&h)));
}

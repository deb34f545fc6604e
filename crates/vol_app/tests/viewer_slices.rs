//! UI tests of the slice views and the turntable export: the real
//! [`ViewerApp`] driven headlessly through `egui_kittest` by the labels a
//! user sees. Expected positions and values are computed here from the
//! test volume's formula and the slice's on-screen rectangle, not from the
//! viewer's own mapping.

mod common;

use std::time::{Duration, Instant};

use common::TempDir;
use egui::{Event, Modifiers, PointerButton};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::{UVec3, Vec3};
use raycaster::format::vol::{self, VolLayout};
use raycaster::volume::slice::SliceAxis;
use raycaster::volume::{AnyVolume, Grid};
use vol_app::viewer::slices::Layout;
use vol_app::viewer::state::ResolutionChoice;
use vol_app::viewer::{Settings, StartOptions, ViewerApp};

const TIMEOUT: Duration = Duration::from_secs(25);
const DIMS: UVec3 = UVec3::new(40, 30, 20);
/// Non-square pixels in every slice.
const SPACING: Vec3 = Vec3::new(1.0, 1.5, 2.5);

type H = Harness<'static, Option<ViewerApp>>;

/// The test volume's value at voxel-space `p`: linear, so the trilinear
/// interpolation reproduces it exactly anywhere.
fn formula(p: Vec3) -> f32 {
    p.x + 2.0 * p.y + 3.0 * p.z
}

fn volume_file(dir: &TempDir, layout: VolLayout) -> std::path::PathBuf {
    let v = AnyVolume::from_fn(Grid::new(DIMS, SPACING), |p| formula(p.as_vec3()) as u8);
    let path = dir.path("ramp.vol");
    vol::write(&path, &v, layout).unwrap();
    path
}

fn harness(dir: &TempDir, layout: VolLayout) -> H {
    let mut h: H = Harness::builder()
        .with_size(egui::vec2(1200.0, 900.0))
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
    let settings = Settings {
        resolution: ResolutionChoice::Fixed,
        fixed_size: 160,
        ..Settings::default()
    };
    let start = StartOptions {
        file: Some(volume_file(dir, layout)),
        tf_preset: Some("ramp".into()),
        ..Default::default()
    };
    *h.state_mut() = Some(ViewerApp::new(&ctx, settings, start));
    step_until(&mut h, "the volume", |a| {
        a.volume().is_some() && a.frames_received() > 0
    });
    h
}

fn app(h: &H) -> &ViewerApp {
    h.state().as_ref().unwrap()
}

fn step_until(h: &mut H, what: &str, cond: impl Fn(&ViewerApp) -> bool) {
    let start = Instant::now();
    loop {
        h.step();
        if cond(app(h)) {
            h.step();
            return;
        }
        assert!(start.elapsed() < TIMEOUT, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(3));
    }
}

fn slices_ready(a: &ViewerApp) -> bool {
    SliceAxis::ALL
        .iter()
        .all(|&s| a.slices().image(s).is_some())
}

fn click(h: &mut H, pos: egui::Pos2, button: PointerButton) {
    h.event(Event::PointerMoved(pos));
    for pressed in [true, false] {
        h.event(Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    h.step();
    h.step();
}

/// The world position under fraction `(fx, fy)` of a slice's rectangle
/// (from its top left), computed from the slice's geometry: pixel k of
/// the image spans [k, k + 1) of it, voxel k sits at its centre, the
/// second in-plane axis points up.
fn world_at(axis: SliceAxis, fx: f32, fy: f32, cursor: Vec3) -> Vec3 {
    let (u, v) = axis.in_plane();
    let mut w = cursor;
    w[u] = (fx * DIMS[u] as f32 - 0.5) * SPACING[u];
    w[v] = ((1.0 - fy) * DIMS[v] as f32 - 0.5) * SPACING[v];
    w
}

#[test]
fn the_layout_switch_shows_the_slices_and_a_click_moves_the_cursor() {
    let dir = TempDir::new("layout");
    let mut h = harness(&dir, VolLayout::Linear);
    assert_eq!(app(&h).slices().layout, Layout::View3d);
    assert!(h.query_by_label("Axial slice").is_none());

    h.get_by_label("2×2").click();
    step_until(&mut h, "the slices", slices_ready);
    assert_eq!(app(&h).slices().layout, Layout::Grid);
    assert!(
        h.query_by_label("Volume canvas").is_some(),
        "2×2 keeps the 3D view"
    );
    let centre = Grid::new(DIMS, SPACING).bounds().center();
    assert_eq!(app(&h).slices().cursor, centre);

    // Each view keeps the physical aspect of its slice.
    for axis in SliceAxis::ALL {
        let r = h.get_by_label(&format!("{} slice", axis.label())).rect();
        let (u, v) = axis.in_plane();
        let want = (DIMS[u] as f32 * SPACING[u]) / (DIMS[v] as f32 * SPACING[v]);
        let got = r.width() / r.height();
        assert!(
            (got - want).abs() < 0.02,
            "{axis:?}: aspect {got}, want {want}"
        );
    }

    // A click a quarter in from the top left of the axial slice.
    let r = h.get_by_label("Axial slice").rect();
    click(&mut h, r.min + r.size() * 0.25, PointerButton::Primary);
    let want = world_at(SliceAxis::Axial, 0.25, 0.25, centre);
    let got = app(&h).slices().cursor;
    assert!(got.abs_diff_eq(want, 0.02), "cursor {got}, want {want}");
    assert_eq!(got.z, centre.z, "a click in the axial slice keeps z");
    // The coronal slice follows the cursor's new y.
    step_until(&mut h, "the coronal slice at the new y", |a| {
        a.slices()
            .image(SliceAxis::Coronal)
            .is_some_and(|s| (s.position - want.y).abs() < 1e-3)
    });

    // A click in the sagittal slice moves y and z, keeps x.
    let r = h.get_by_label("Sagittal slice").rect();
    click(
        &mut h,
        r.min + r.size() * egui::vec2(0.8, 0.1),
        PointerButton::Primary,
    );
    let want = world_at(SliceAxis::Sagittal, 0.8, 0.1, got);
    let now = app(&h).slices().cursor;
    assert!(now.abs_diff_eq(want, 0.02), "cursor {now}, want {want}");

    // Slices only: no 3D view.
    h.get_by_label("Slices").click();
    h.step();
    h.step();
    assert!(h.query_by_label("Volume canvas").is_none());
    assert!(h.query_by_label("Coronal slice").is_some());
    h.get_by_label("3D").click();
    h.step();
    h.step();
    assert!(h.query_by_label("Coronal slice").is_none());
    assert!(h.query_by_label("Volume canvas").is_some());
}

#[test]
fn the_readout_shows_the_position_and_value_under_the_mouse() {
    let dir = TempDir::new("readout");
    // Bricked storage: the slices and the value come through its addressing.
    let mut h = harness(&dir, VolLayout::Bricked { side: 6 });
    h.get_by_label("Slices").click();
    step_until(&mut h, "the slices", slices_ready);
    let r = h.get_by_label("Coronal slice").rect();
    let cursor = app(&h).slices().cursor;
    h.event(Event::PointerMoved(r.min + r.size() * egui::vec2(0.3, 0.6)));
    h.step();
    h.step();
    let hover = app(&h).slices().hover.expect("a readout");
    let world = world_at(SliceAxis::Coronal, 0.3, 0.6, cursor);
    assert!(
        hover.world.abs_diff_eq(world, 0.02),
        "{} vs {world}",
        hover.world
    );
    let want = formula(world / SPACING);
    let value = hover.value.expect("inside the volume");
    assert!((value - want).abs() < 0.05, "value {value}, want {want}");
    let text = format!(
        "x {:.1} y {:.1} z {:.1} mm",
        hover.world.x, hover.world.y, hover.world.z
    );
    assert!(
        h.query_by_label_contains(&text).is_some(),
        "no '{text}' on screen"
    );
    assert!(h.query_by_label_contains("value ").is_some());
    // Leaving the slice clears it.
    h.event(Event::PointerMoved(egui::pos2(5.0, 5.0)));
    h.step();
    assert!(app(&h).slices().hover.is_none());
}

#[test]
fn window_presets_and_a_right_drag_set_the_window() {
    let dir = TempDir::new("window");
    let mut h = harness(&dir, VolLayout::Linear);
    h.get_by_label("Slices").click();
    step_until(&mut h, "the slices and the auto window", |a| {
        slices_ready(a) && a.slices().window_name.is_some()
    });
    h.get_by_label("Window").click();
    h.step();
    h.step();
    h.get_by_label("CT Brain (W80 L40)").click();
    h.step();
    let w = app(&h).slices().window;
    assert_eq!((w.width, w.level), (80.0, 40.0));
    assert_eq!(app(&h).slices().window_name, Some("Brain"));

    // Right drag to the right widens the window, upwards raises the level.
    let r = h.get_by_label("Axial slice").rect();
    let start = r.center();
    h.event(Event::PointerMoved(start));
    h.event(Event::PointerButton {
        pos: start,
        button: PointerButton::Secondary,
        pressed: true,
        modifiers: Modifiers::NONE,
    });
    for k in 1..=5 {
        h.event(Event::PointerMoved(
            start + egui::vec2(10.0 * k as f32, -4.0 * k as f32),
        ));
        h.step();
    }
    h.event(Event::PointerButton {
        pos: start + egui::vec2(50.0, -20.0),
        button: PointerButton::Secondary,
        pressed: false,
        modifiers: Modifiers::NONE,
    });
    h.step();
    let s = app(&h).slices();
    assert!(
        s.window.width > 80.0 && s.window.level > 40.0,
        "{:?}",
        s.window
    );
    assert_eq!(s.window_name, None);
    assert_eq!(
        s.cursor,
        Grid::new(DIMS, SPACING).bounds().center(),
        "a right drag keeps the cursor"
    );
}

/// Clicks "Export turntable…" and steps until the window is up (a new
/// window's first frame only measures it).
fn open_export_window(h: &mut H) {
    h.get_by_label("Export turntable…").click();
    for _ in 0..4 {
        h.step();
    }
    assert!(h.query_by_label("Export").is_some(), "no export window");
}

#[test]
fn the_viewer_exports_a_turntable_gif() {
    let dir = TempDir::new("export");
    let mut h = harness(&dir, VolLayout::Linear);
    open_export_window(&mut h);
    let gif = dir.path("movie.gif");
    {
        let app = h.state_mut().as_mut().unwrap();
        let e = app.export_settings_mut();
        e.frames = 5;
        e.size = 48;
        e.path = gif.display().to_string();
    }
    h.get_by_label("Export").click();
    h.step();
    step_until(&mut h, "the export", |a| !a.is_exporting());
    assert!(app(&h).error().is_none(), "{:?}", app(&h).error());
    use image::AnimationDecoder;
    let file = std::io::BufReader::new(std::fs::File::open(&gif).unwrap());
    let frames = image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap();
    assert_eq!(frames.len(), 5);
    assert_eq!(frames[0].buffer().dimensions(), (48, 48));
}

#[test]
fn a_cancelled_export_leaves_no_file() {
    let dir = TempDir::new("cancel");
    let mut h = harness(&dir, VolLayout::Linear);
    open_export_window(&mut h);
    let gif = dir.path("never.gif");
    {
        let e = h.state_mut().as_mut().unwrap().export_settings_mut();
        e.frames = 3600;
        e.size = 400;
        e.path = gif.display().to_string();
    }
    h.get_by_label("Export").click();
    h.step();
    assert!(app(&h).is_exporting());
    h.step();
    h.step();
    h.get_by_label("Cancel").click();
    step_until(&mut h, "the cancel", |a| !a.is_exporting());
    assert!(!gif.exists());
    assert!(h.query_by_label_contains("cancelled").is_some());
}

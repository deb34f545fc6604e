//! The interactive viewer: an eframe/egui window around the ray caster.
//!
//! | module | concept |
//! |---|---|
//! | [`app`] | [`ViewerApp`]: state and the frame loop, wired to eframe |
//! | [`state`] | [`Settings`]: the user's choices, persisted between runs |
//! | `panels` | the left panel: file, volume info, TF, rendering, camera |
//! | `canvas` | the frame, mouse control of the camera, the status line |
//! | [`tf_editor`] | the transfer-function curve editor over the histogram |
//! | [`camera_control`] | orbit / pan / zoom math |
//! | [`loading`] | opening volumes on a background thread, with progress |
//! | [`render_link`] | the renderer on its own thread, newest request wins |
//! | [`metaball_link`] | the Metaballs mode: balls from the volume and their frames on a thread of their own |
//! | [`progressive`] | previews within a time budget while the view changes, refinement ¼ → ½ → full when still |
//! | [`timeline`] | a sequence's player: play/pause, loop, speed, step ±1 (N/M), scrub |
//! | [`dialogs`] | native file dialogs on a background thread |
//! | [`slices`] | axial, coronal, sagittal slices through a cursor, window/level, readout; the layout switch (3D, slices, 2×2) |
//! | [`export`] | "Export turntable…": a turntable movie rendered on a background thread, with progress and cancel |
//!
//! [`ViewerApp`] runs without a window too: give it an [`egui::Context`] and
//! call [`ViewerApp::show`] each frame (this is how the UI tests drive it).

pub mod app;
pub mod camera_control;
mod canvas;
pub mod dialogs;
pub mod export;
pub mod loading;
pub mod metaball_link;
mod panels;
pub mod progressive;
pub mod render_link;
pub mod slices;
pub mod state;
pub mod tf_editor;
pub mod timeline;

pub use app::{StartOptions, ViewerApp};
pub use state::Settings;

/// Opens the viewer window and runs it until it is closed.
pub fn run(start: StartOptions) -> Result<(), String> {
    if cfg!(target_os = "linux")
        && std::env::var_os("DISPLAY").is_none()
        && std::env::var_os("WAYLAND_DISPLAY").is_none()
    {
        return Err(
            "no display to open the viewer on (neither DISPLAY nor WAYLAND_DISPLAY is set); \
             render without a window with `vol_app render FILE --out image.png`"
                .into(),
        );
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("vol_app")
            .with_app_id("vol_app")
            .with_inner_size([1280.0, 800.0])
            .with_min_inner_size([640.0, 400.0])
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Glow,
        ..Default::default()
    };
    eframe::run_native(
        "vol_app",
        options,
        Box::new(move |cc| {
            let settings = Settings::load(cc.storage);
            Ok(Box::new(ViewerApp::new(&cc.egui_ctx, settings, start)))
        }),
    )
    .map_err(|e| format!("the viewer failed: {e}"))
}

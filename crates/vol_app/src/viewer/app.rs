//! [`ViewerApp`]: the viewer's state and its frame loop, wired to eframe.
//!
//! Each UI frame: take in dropped files, dialog answers, a finished load and
//! a finished render; draw the left panel, the status line and the canvas;
//! turn mouse input on the canvas into camera moves; and, when what should
//! be on screen differs from what was last requested, send one new request
//! to the [`RenderLink`]. Nothing here waits: loads, dialogs and frames all
//! run on other threads and wake the UI when they have news.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use egui::{TextureHandle, TextureOptions, Ui};
use glam::Vec3;
use raycaster::prelude::*;

use super::camera_control::OrbitCamera;
use super::dialogs::{Answer, Dialogs, Purpose};
use super::loading::{
    GradientHistogram, Histogram, LoadJob, LoadOptions, Loaded, Source, VolumeInfo,
    default_memory_limit,
};
use super::progressive::Progressive;
use super::render_link::{RenderLink, RenderRequest, RenderedFrame};
use super::state::Settings;
use super::tf_editor::TfEditor;
use super::timeline::Timeline;

/// How the viewer starts.
#[derive(Debug, Clone, Default)]
pub struct StartOptions {
    /// Volume to open; the built-in demo when `None`.
    pub file: Option<PathBuf>,
    /// Transfer function for the first volume: a preset name...
    pub tf_preset: Option<String>,
    /// ...or a TF (e.g. read from a JSON file).
    pub tf: Option<TransferFunction>,
    /// How to read `file` when it is headerless (raw).
    pub raw: Option<raycaster::format::RawOptions>,
    /// Neither read nor write macrocell cache files (`--no-cache`).
    pub no_cache: bool,
    /// The most memory a volume read or decoded into RAM may take
    /// (`--max-memory`); `None`: [`default_memory_limit`].
    pub max_memory: Option<u64>,
    /// The layout to start in (`--layout`); 3D only by default.
    pub layout: Option<super::slices::Layout>,
    /// The frame of a sequence `file` to show first (`--frame`, from 0).
    pub frame: Option<u32>,
}

/// The volume on screen.
#[derive(Debug)]
pub struct Volume {
    /// Volume and acceleration data.
    pub scene: Arc<Scene>,
    /// Facts for the info panel.
    pub info: VolumeInfo,
    /// Value histogram.
    pub histogram: Histogram,
    /// Gradient-magnitude histogram.
    pub gradient_histogram: GradientHistogram,
}

/// The last finished frame, uploaded as a texture.
pub(super) struct ShownFrame {
    pub(super) texture: TextureHandle,
    pub(super) frame: RenderedFrame,
}

/// The viewer.
pub struct ViewerApp {
    pub(super) ctx: egui::Context,
    pub(super) settings: Settings,
    pub(super) volume: Option<Volume>,
    /// The player of a sequence of several frames; `None` for one volume.
    pub(super) timeline: Option<Timeline>,
    pub(super) loading: Option<LoadJob>,
    /// The start options, until they have been applied to the first volume.
    start: Option<StartOptions>,
    pub(super) camera: OrbitCamera,
    pub(super) link: RenderLink,
    /// Which level to render next (previews, then refinement).
    pub(super) progressive: Progressive,
    /// The full-quality request for the view of the last UI frame (to tell
    /// when the view changes).
    pub(super) last_view: Option<RenderRequest>,
    pub(super) last_request: Option<RenderRequest>,
    pub(super) shown: Option<ShownFrame>,
    pub(super) render_error: Option<String>,
    pub(super) error: Option<String>,
    pub(super) notice: Option<String>,
    pub(super) tf_editor: TfEditor,
    pub(super) dialogs: Dialogs,
    pub(super) path_input: String,
    /// A continuous control (camera slider, TF point, iso slider) is being
    /// dragged: it renders previews and no refinement, like camera motion.
    pub(super) controls_moving: bool,
    frames_received: u64,
    pub(super) last_scroll: Option<Instant>,
    pub(super) canvas_aspect: f32,
    /// How every volume is opened (`--no-cache`, `--max-memory`).
    load_options: LoadOptions,
    /// Slice views and the layout of the central area.
    pub(super) slices: super::slices::SliceViews,
    /// The turntable export window and its job.
    pub(super) export: super::export::Export,
}

impl ViewerApp {
    /// A viewer on `ctx` with `settings`, starting to load `start.file` (or
    /// the demo volume) in the background.
    pub fn new(ctx: &egui::Context, settings: Settings, start: StartOptions) -> Self {
        let wake = ctx.clone();
        let link = RenderLink::new(move || wake.request_repaint());
        let mut app = ViewerApp {
            ctx: ctx.clone(),
            camera: OrbitCamera::framing(
                &raycaster::geometry::Aabb::new(Vec3::ZERO, Vec3::ONE),
                1.0,
            ),
            settings,
            volume: None,
            timeline: None,
            loading: None,
            start: None,
            link,
            progressive: Progressive::default(),
            last_view: None,
            last_request: None,
            shown: None,
            render_error: None,
            error: None,
            notice: None,
            tf_editor: TfEditor::default(),
            dialogs: Dialogs::default(),
            path_input: String::new(),
            controls_moving: false,
            frames_received: 0,
            last_scroll: None,
            canvas_aspect: 1.0,
            load_options: LoadOptions {
                no_cache: start.no_cache,
                max_memory: start.max_memory.or_else(default_memory_limit),
            },
            slices: Default::default(),
            export: Default::default(),
        };
        app.slices.layout = start.layout.unwrap_or_default();
        match &start.file {
            Some(p) => app.open_with(p, start.raw.clone()),
            None => app.open_demo(),
        }
        app.start = Some(start);
        app
    }

    /// Starts loading `path` in the background; the current volume stays on
    /// screen until the new one is ready (and stays if loading fails).
    pub fn open(&mut self, path: &Path) {
        self.open_with(path, None);
    }

    /// As [`ViewerApp::open`], reading a headerless file as `raw` describes.
    pub fn open_with(&mut self, path: &Path, raw: Option<raycaster::format::RawOptions>) {
        let mode = if self.settings.load_in_ram {
            LoadMode::Ram
        } else {
            LoadMode::Map
        };
        self.path_input = path.display().to_string();
        self.error = None;
        self.start_loading(Source::File(path.to_path_buf(), mode, raw));
    }

    /// Starts generating the built-in demo volume.
    pub fn open_demo(&mut self) {
        self.error = None;
        self.start_loading(Source::Demo);
    }

    fn start_loading(&mut self, source: Source) {
        let wake = self.ctx.clone();
        self.loading = Some(LoadJob::start(source, self.load_options, move || {
            wake.request_repaint()
        }));
    }

    /// The settings (persisted between runs).
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The settings, to change them as the panel would.
    pub fn settings_mut(&mut self) -> &mut Settings {
        &mut self.settings
    }

    /// The camera.
    pub fn camera(&self) -> &OrbitCamera {
        &self.camera
    }

    /// The volume on screen.
    pub fn volume(&self) -> Option<&Volume> {
        self.volume.as_ref()
    }

    /// The timeline, when the volume on screen is a sequence of frames.
    pub fn timeline(&self) -> Option<&Timeline> {
        self.timeline.as_ref()
    }

    /// True while a volume is loading.
    pub fn is_loading(&self) -> bool {
        self.loading.is_some()
    }

    /// True while frames of the current view are still to come: the newest
    /// request has not been answered, or refinement levels are left.
    pub fn is_rendering(&self) -> bool {
        self.link.is_busy() || (self.settings.progressive && self.progressive.is_refining())
    }

    /// Aims preview frames at `budget` instead of
    /// [`PREVIEW_BUDGET`](super::progressive::PREVIEW_BUDGET) (zero: always
    /// the coarsest preview level).
    pub fn set_preview_budget(&mut self, budget: std::time::Duration) {
        self.progressive.set_budget(budget);
    }

    /// Frames received from the renderer so far.
    pub fn frames_received(&self) -> u64 {
        self.frames_received
    }

    /// The frame on screen.
    pub fn last_frame(&self) -> Option<&RenderedFrame> {
        self.shown.as_ref().map(|s| &s.frame)
    }

    /// The newest render request.
    pub fn last_request(&self) -> Option<&RenderRequest> {
        self.last_request.as_ref()
    }

    /// The transfer-function editor.
    pub fn tf_editor(&self) -> &TfEditor {
        &self.tf_editor
    }

    /// The error shown to the user, if any.
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// Saves the frame on screen as a PNG.
    pub fn save_frame_png(&mut self, path: &Path) -> Result<(), String> {
        let shown = self
            .shown
            .as_ref()
            .ok_or("no frame has been rendered yet")?;
        shown
            .frame
            .frame
            .save_png(path)
            .map_err(|e| e.to_string())?;
        self.remember_dir(path);
        Ok(())
    }

    /// Replaces the TF with one read from a JSON file.
    pub fn load_tf_file(&mut self, path: &Path) -> Result<(), String> {
        let tf = TransferFunction::from_json_file(path).map_err(|e| e.to_string())?;
        self.settings.tf = tf;
        self.settings.tf_preset = None;
        self.remember_dir(path);
        Ok(())
    }

    /// Writes the TF as JSON (the format that `--tf` reads).
    pub fn save_tf_file(&mut self, path: &Path) -> Result<(), String> {
        std::fs::write(path, self.settings.tf.to_json())
            .map_err(|e| format!("{}: {e}", path.display()))?;
        self.remember_dir(path);
        Ok(())
    }

    /// Switches to a named TF preset for the volume's sample type.
    pub fn set_tf_preset(&mut self, name: &str) {
        let (sample_type, range) = self
            .volume
            .as_ref()
            .map_or((SampleType::U8, (0.0, 255.0)), |v| {
                (v.info.sample_type, v.info.value_range)
            });
        if let Some(tf) = TransferFunction::preset_for_data(name, sample_type, range) {
            self.settings.tf = tf;
            self.settings.tf_preset = Some(name.to_string());
        }
    }

    fn remember_dir(&mut self, path: &Path) {
        if let Some(dir) = path.parent().filter(|d| d.is_dir()) {
            self.settings.last_dir = Some(dir.to_path_buf());
        }
    }

    /// Shows a file dialog for `purpose`.
    pub(super) fn show_dialog(&mut self, purpose: Purpose) {
        let wake = self.ctx.clone();
        self.dialogs
            .show(purpose, self.settings.last_dir.clone(), move || {
                wake.request_repaint()
            });
    }

    /// One UI frame.
    pub fn show(&mut self, ui: &mut Ui) {
        self.take_dropped_files(ui.ctx());
        self.poll_dialogs();
        self.poll_loading();
        self.poll_frames(ui.ctx());
        self.poll_timeline();
        if ui.input_mut(|i| i.consume_key(egui::Modifiers::COMMAND, egui::Key::O)) {
            self.show_dialog(Purpose::OpenVolume);
        }
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(340.0)
            .size_range(260.0..=640.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.left_panel(ui));
            });
        egui::Panel::bottom("status").show(ui, |ui| self.status_line(ui));
        if self.timeline.is_some() {
            egui::Panel::bottom("timeline").show(ui, |ui| self.timeline_bar(ui));
        }
        self.export_window(ui);
        egui::CentralPanel::default().show(ui, |ui| self.central(ui));
    }

    fn take_dropped_files(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()));
        if let Some(path) = dropped {
            self.open(&path);
        }
    }

    fn poll_dialogs(&mut self) {
        let (purpose, path) = match self.dialogs.poll() {
            Some((purpose, Answer::Chosen(path))) => (purpose, path),
            Some((_, Answer::Unavailable)) => {
                self.notice = Some(
                    "No file dialog could be shown (is xdg-desktop-portal running?): \
                     type a path above, or drop the file on the window."
                        .into(),
                );
                return;
            }
            Some((_, Answer::Cancelled)) | None => return,
        };
        let result = match purpose {
            Purpose::OpenVolume | Purpose::OpenFolder => {
                self.open(&path);
                Ok(())
            }
            Purpose::LoadTf => self.load_tf_file(&path),
            Purpose::SaveTf => self.save_tf_file(&path),
            Purpose::SavePng => self.save_frame_png(&path),
            Purpose::ExportTurntable => {
                self.export.path = path.display().to_string();
                return;
            }
        };
        match result {
            Ok(()) if !matches!(purpose, Purpose::OpenVolume | Purpose::OpenFolder) => {
                let verb = if purpose == Purpose::LoadTf {
                    "Loaded"
                } else {
                    "Saved"
                };
                self.notice = Some(format!("{verb} {}", short_name(&path)));
            }
            Ok(()) => {}
            Err(e) => self.error = Some(e),
        }
    }

    fn poll_loading(&mut self) {
        let Some(result) = self.loading.as_ref().and_then(LoadJob::poll) else {
            return;
        };
        let source = self.loading.take().map(|j| j.source().clone());
        match result {
            Ok(loaded) => self.install(loaded, source.as_ref()),
            Err(e) => {
                let keep = if self.volume.is_some() {
                    "; still showing the previous volume"
                } else {
                    ""
                };
                self.error = Some(format!("Cannot open {e}{keep}"));
                if self.volume.is_none() && source != Some(Source::Demo) {
                    // Nothing on screen yet (a bad FILE argument): show the
                    // demo, and keep the error on screen.
                    self.start_loading(Source::Demo);
                }
            }
        }
    }

    /// Puts a freshly loaded volume on screen, fitting TF, iso value and camera.
    fn install(&mut self, loaded: Loaded, source: Option<&Source>) {
        let Loaded {
            scene,
            info,
            histogram,
            gradient_histogram,
            timeline,
        } = loaded;
        let sample_type = info.sample_type;
        let start_frame = self.start.as_ref().and_then(|s| s.frame);
        let s = &mut self.settings;
        match self.start.take() {
            Some(StartOptions { tf: Some(tf), .. }) => {
                s.tf = tf;
                s.tf_preset = None;
            }
            Some(StartOptions {
                tf_preset: Some(name),
                ..
            }) => s.tf_preset = Some(name),
            _ if source == Some(&Source::Demo) => {
                s.tf_preset = Some(crate::demo::DEMO_TF.to_string());
            }
            _ => {}
        }
        // Presets depend on the sample type (ramp spans the type's range).
        if let Some(tf) = s
            .tf_preset
            .as_deref()
            .and_then(|n| TransferFunction::preset_for_data(n, sample_type, info.value_range))
        {
            s.tf = tf;
        }
        if !tf_shows_anything(&s.tf, info.value_range) {
            let name = default_preset(&info);
            if let Some(tf) = TransferFunction::preset_for_data(name, sample_type, info.value_range)
            {
                s.tf = tf;
                s.tf_preset = Some(name.into());
            }
        }
        let (lo, hi) = info.value_range;
        if !(lo..=hi).contains(&s.iso_value) {
            s.iso_value = 0.5 * (lo + hi);
        }
        self.notice = Some(format!(
            "Opened {} in {:.0} ms",
            info.name,
            info.load_time.as_secs_f64() * 1e3
        ));
        if let Some(p) = info.path.clone() {
            self.remember_dir(&p);
        }
        self.camera = OrbitCamera::framing(&scene.grid().bounds(), self.canvas_aspect);
        // Frame costs learned on the previous volume say nothing of this one.
        self.progressive.reset();
        self.timeline = timeline;
        if let Some(k) = start_frame {
            match &mut self.timeline {
                Some(t) if k < t.frames() => t.go_to(k),
                Some(t) => {
                    self.error = Some(format!(
                        "--frame {k}: {} has frames 0 to {}",
                        info.name,
                        t.frames() - 1
                    ))
                }
                None if k > 0 => {
                    self.error = Some(format!("--frame {k}: {} is not a sequence", info.name))
                }
                None => {}
            }
        }
        self.volume = Some(Volume {
            scene,
            info,
            histogram,
            gradient_histogram,
        });
    }

    fn poll_frames(&mut self, ctx: &egui::Context) {
        match self.link.poll() {
            Some(Ok(f)) => {
                self.progressive.arrived(
                    f.id,
                    f.level,
                    [f.camera.width, f.camera.height],
                    f.frame.stats.time,
                );
                let size = [f.frame.width as usize, f.frame.height as usize];
                let image = egui::ColorImage::from_rgb(size, &f.frame.rgb);
                match &mut self.shown {
                    Some(s) => {
                        s.texture.set(image, TextureOptions::LINEAR);
                        s.frame = f;
                    }
                    None => {
                        let texture =
                            ctx.load_texture("volume-frame", image, TextureOptions::LINEAR);
                        self.shown = Some(ShownFrame { texture, frame: f });
                    }
                }
                self.frames_received += 1;
                self.render_error = None;
            }
            Some(Err(e)) => {
                self.progressive.failed(e.id);
                self.render_error = Some(e.message);
            }
            None => {}
        }
    }
}

/// The last component of `path` (a full path has no spaces to wrap at, and
/// would widen the panel).
pub(super) fn short_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// The preset for a volume whose current TF shows nothing: by the modality
/// the file declares, else `ramp` for 8-bit data (`vol_app render`'s
/// default) and the data-fitted `mr-default` for wider types, where a ramp
/// over the whole type range would be nearly transparent.
fn default_preset(info: &VolumeInfo) -> &'static str {
    match info.file.as_ref().and_then(|f| f.modality.as_deref()) {
        Some("CT") => "ct-bone",
        Some("MR") => "mr-default",
        _ if matches!(info.sample_type, SampleType::U8 | SampleType::I8) => "ramp",
        _ => "mr-default",
    }
}

/// True when some value in `range` has a non-zero opacity under `tf`.
fn tf_shows_anything(tf: &TransferFunction, (lo, hi): (f32, f32)) -> bool {
    let probes = (0..=256).map(|k| lo + (hi - lo) * k as f32 / 256.0);
    let points = tf
        .points
        .iter()
        .map(|p| p.value)
        .filter(|v| (lo..=hi).contains(v));
    probes.chain(points).any(|v| tf.evaluate(v).w > 0.0)
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        self.settings.save(storage);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tf_outside_the_data_range_shows_nothing() {
        let shapes = TransferFunction::preset("shapes", SampleType::U8).unwrap();
        assert!(tf_shows_anything(&shapes, (0.0, 255.0)));
        assert!(tf_shows_anything(&shapes, (90.0, 90.0)));
        assert!(!tf_shows_anything(&shapes, (0.0, 80.0)));
        assert!(!tf_shows_anything(&shapes, (120.0, 255.0)));
    }
}

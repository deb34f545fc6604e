//! "Export turntable…": the library's [`turntable::render`] on a thread of
//! its own, starting from the camera on screen with the TF and settings on
//! screen, writing a GIF or a directory of PNGs; a progress bar and a
//! Cancel button while it runs. The viewer's own renderer keeps going
//! meanwhile (the two share the cores).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;

use egui::Ui;

use super::app::ViewerApp;
use super::dialogs::Purpose;
use crate::turntable::{self, Outcome, Output, TurnAxis, Turntable};

/// The export window's fields and the job that runs.
pub struct Export {
    /// The window is open.
    pub open: bool,
    /// Frames in a full turn.
    pub frames: u32,
    /// Axis of the turn.
    pub axis: TurnAxis,
    /// Square image side in pixels.
    pub size: u32,
    /// GIF frames per second.
    pub fps: f32,
    /// A `.gif` file or a directory (ending in `/`).
    pub path: String,
    job: Option<Job>,
}

impl Default for Export {
    fn default() -> Self {
        Export {
            open: false,
            frames: 36,
            axis: TurnAxis::Y,
            size: 256,
            fps: 25.0,
            path: "turntable.gif".into(),
            job: None,
        }
    }
}

struct Job {
    done: Arc<AtomicU32>,
    frames: u32,
    cancel: Arc<AtomicBool>,
    thread: JoinHandle<Result<Outcome, String>>,
    path: PathBuf,
}

impl ViewerApp {
    /// The toolbar's button that opens the export window.
    pub(super) fn turntable_button(&mut self, ui: &mut Ui) {
        let running = self.export.job.is_some();
        let label = if running {
            "Exporting turntable…"
        } else {
            "Export turntable…"
        };
        if ui
            .add_enabled(self.volume.is_some(), egui::Button::new(label))
            .on_hover_text("Render frames of the camera orbiting the volume into a GIF or a folder")
            .clicked()
        {
            self.export.open = true;
        }
    }

    /// The export window's fields, to set them as the window would.
    pub fn export_settings_mut(&mut self) -> &mut Export {
        &mut self.export
    }

    /// True while a turntable export runs.
    pub fn is_exporting(&self) -> bool {
        self.export.job.is_some()
    }

    /// The export window (while open) and the end of a finished job.
    pub(super) fn export_window(&mut self, ui: &mut Ui) {
        self.finish_export();
        if !self.export.open {
            return;
        }
        let mut open = true;
        egui::Window::new("Export turntable")
            .open(&mut open)
            .resizable(false)
            .collapsible(false)
            .show(ui.ctx(), |ui| self.export_form(ui));
        self.export.open = open;
    }

    fn export_form(&mut self, ui: &mut Ui) {
        let running = self.export.job.is_some();
        ui.add_enabled_ui(!running, |ui| {
            let e = &mut self.export;
            egui::Grid::new("turntable").num_columns(2).show(ui, |ui| {
                ui.label("Frames");
                ui.add(egui::DragValue::new(&mut e.frames).range(1..=3600));
                ui.end_row();
                ui.label("Axis");
                ui.horizontal(|ui| {
                    for (a, l) in [(TurnAxis::X, "x"), (TurnAxis::Y, "y"), (TurnAxis::Z, "z")] {
                        ui.selectable_value(&mut e.axis, a, l);
                    }
                });
                ui.end_row();
                ui.label("Size (px)");
                ui.add(egui::DragValue::new(&mut e.size).range(16..=4096));
                ui.end_row();
                ui.label("GIF fps");
                ui.add(egui::DragValue::new(&mut e.fps).range(1.0..=50.0));
                ui.end_row();
            });
            let l = ui.label("File (.gif) or folder (ending in /):");
            ui.horizontal(|ui| {
                ui.text_edit_singleline(&mut self.export.path)
                    .labelled_by(l.id);
                if ui
                    .add_enabled(!self.dialogs.is_open(), egui::Button::new("Choose…"))
                    .clicked()
                {
                    self.show_dialog(Purpose::ExportTurntable);
                }
            });
        });
        match &self.export.job {
            Some(job) => {
                let done = job.done.load(Ordering::Relaxed);
                ui.add(
                    egui::ProgressBar::new(done as f32 / job.frames as f32)
                        .text(format!("frame {done} of {}", job.frames)),
                );
                if ui.button("Cancel").clicked() {
                    job.cancel.store(true, Ordering::Relaxed);
                }
            }
            None => {
                if ui.button("Export").clicked()
                    && let Err(e) = self.start_export()
                {
                    self.error = Some(e);
                }
            }
        }
    }

    /// Starts the export job with the view on screen.
    pub fn start_export(&mut self) -> Result<(), String> {
        let e = &self.export;
        let out = Output::from_path(&PathBuf::from(e.path.trim()), e.fps)?;
        let view = self
            .wanted_view([e.size, e.size])
            .ok_or("no volume to export")?;
        if view.options.mode == raycaster::integrator::RenderMode::Metaballs {
            return Err(
                "the turntable export renders volumes: choose a mode other than Metaballs".into(),
            );
        }
        let camera = self.camera.camera(e.size, e.size);
        let (frames, axis) = (e.frames.max(1), e.axis);
        let mut renderer = view
            .renderer
            .renderer(view.threads)
            .map_err(|e| e.to_string())?;
        let done = Arc::new(AtomicU32::new(0));
        let cancel = Arc::new(AtomicBool::new(false));
        let (done_in, cancel_in, wake) = (done.clone(), cancel.clone(), self.ctx.clone());
        let path = match &out {
            Output::Frames(p) | Output::Gif { path: p, .. } => p.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("vol_app-turntable".into())
            .spawn(move || {
                let job = Turntable {
                    center: view.scene.grid().bounds().center(),
                    scene: &view.scene,
                    camera,
                    axis,
                    frames,
                    tf: &view.tf,
                    options: &view.options,
                };
                let result =
                    turntable::render(&job, renderer.as_mut(), &out, &cancel_in, |k, _| {
                        done_in.store(k, Ordering::Relaxed);
                        wake.request_repaint();
                    });
                wake.request_repaint();
                result
            })
            .map_err(|e| format!("cannot start the export: {e}"))?;
        self.export.job = Some(Job {
            done,
            frames,
            cancel,
            thread,
            path,
        });
        Ok(())
    }

    /// Reports a finished export job.
    fn finish_export(&mut self) {
        if !self
            .export
            .job
            .as_ref()
            .is_some_and(|j| j.thread.is_finished())
        {
            return;
        }
        let Some(job) = self.export.job.take() else {
            return;
        };
        let name = super::app::short_name(&job.path);
        match job.thread.join() {
            Ok(Ok(Outcome::Done)) => {
                self.notice = Some(format!(
                    "Exported a {}-frame turntable to {name}",
                    job.frames
                ))
            }
            Ok(Ok(Outcome::Cancelled)) => self.notice = Some("Turntable export cancelled".into()),
            Ok(Err(e)) => self.error = Some(format!("Turntable export failed: {e}")),
            Err(_) => self.error = Some("Turntable export failed (its thread panicked)".into()),
        }
    }
}

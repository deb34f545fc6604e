//! The canvas: the rendered frame scaled to fit, mouse control of the
//! camera, the render request that follows from the view, and the status
//! line under it.

use std::time::{Duration, Instant};

use egui::{Color32, PointerButton, Rect, Sense, Ui};
use glam::Vec2;
use raycaster::prelude::*;

use super::app::ViewerApp;
use super::progressive::{Level, Stage};
use super::render_link::RenderRequest;
use super::state::ResolutionChoice;

/// How long after the last wheel event the camera counts as still moving.
const SCROLL_SETTLE: Duration = Duration::from_millis(250);

impl ViewerApp {
    /// The render canvas: the frame, mouse control of the camera, overlays.
    pub(super) fn canvas(&mut self, ui: &mut Ui) {
        if let Some(e) = self.error.clone() {
            ui.horizontal(|ui| {
                if ui.button("Dismiss").clicked() {
                    self.error = None;
                }
                let text = egui::RichText::new(e).color(Color32::from_rgb(255, 110, 100));
                ui.add(egui::Label::new(text).wrap());
            });
        }
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        response
            .widget_info(|| egui::WidgetInfo::labeled(egui::Role::Canvas, true, "Volume canvas"));
        // A reduced frame is drawn stretched to its full size (the texture's
        // bilinear filter upsamples it).
        let image_rect = self.shown.as_ref().map_or(rect, |s| {
            fit(rect, s.frame.camera.width, s.frame.camera.height)
        });
        let interacting = self.camera_input(ui, &response, image_rect.height());
        self.canvas_aspect = rect.aspect_ratio();
        let ppp = ui.ctx().pixels_per_point();
        let px = [
            (rect.width() * ppp).round() as u32,
            (rect.height() * ppp).round() as u32,
        ];
        self.request_next_frame(px, interacting);
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::BLACK);
        if let Some(s) = &self.shown {
            let uv = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            painter.image(s.texture.id(), image_rect, uv, Color32::WHITE);
        }
        self.draw_cursor_3d(&painter, image_rect);
        let overlay = |text: String| {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                text,
                egui::FontId::proportional(18.0),
                Color32::from_gray(220),
            );
        };
        if ui.input(|i| !i.raw.hovered_files.is_empty()) {
            overlay("Drop to open".into());
        } else if self.shown.is_none() {
            overlay(
                if self.loading.is_some() {
                    "Loading…"
                } else {
                    "No volume"
                }
                .into(),
            );
        }
    }

    /// Orbit (left drag), pan (right or middle drag), zoom (wheel), reset
    /// (double click). Returns true while the camera is moving.
    fn camera_input(&mut self, ui: &Ui, response: &egui::Response, view_height: f32) -> bool {
        let d = response.drag_delta();
        let delta = Vec2::new(d.x, d.y);
        if response.dragged_by(PointerButton::Primary) {
            self.camera.orbit(delta);
        } else if response.dragged_by(PointerButton::Secondary)
            || response.dragged_by(PointerButton::Middle)
        {
            self.camera.pan(delta, view_height);
        }
        if response.double_clicked() {
            self.camera.reset();
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom(scroll);
                self.last_scroll = Some(Instant::now());
            }
        }
        let scrolling = self
            .last_scroll
            .is_some_and(|t| t.elapsed() < SCROLL_SETTLE);
        if scrolling {
            ui.ctx().request_repaint_after(SCROLL_SETTLE);
        }
        response.dragged() || scrolling || self.controls_moving
    }

    /// Sends the next frame of the progressive refinement, if one is due
    /// (see [`progressive`](super::progressive)): a preview when the view
    /// changed, else the next refinement level once the camera is still.
    fn request_next_frame(&mut self, canvas_px: [u32; 2], interacting: bool) {
        let Some(view) = self.wanted_view(canvas_px) else {
            return;
        };
        let changed = self.last_view.as_ref() != Some(&view);
        let full = [view.camera.width, view.camera.height];
        self.last_view = Some(view.clone());
        if !self.settings.progressive {
            // Every frame at full quality, one request per change.
            self.progressive.settle();
            if changed {
                self.link.request(view.clone());
                self.last_request = Some(view);
            }
            return;
        }
        let Some(planned) = self.progressive.next(changed, interacting, full) else {
            return;
        };
        // Previews are jittered like the still frames (when jitter is on):
        // the same view at the same level then gives the same image at
        // every stage.
        let request = RenderRequest {
            level: planned.level,
            preview: planned.stage == Stage::Preview,
            ..view
        };
        let id = self.link.request(request.clone());
        self.progressive.sent(id);
        self.last_request = Some(request);
    }

    /// The full-quality request for what should be on screen for a canvas
    /// of `canvas_px` pixels.
    pub(super) fn wanted_view(&self, canvas_px: [u32; 2]) -> Option<RenderRequest> {
        let volume = self.volume.as_ref()?;
        let s = &self.settings;
        if canvas_px[0] < 8 || canvas_px[1] < 8 {
            return None;
        }
        let [w, h] = match s.resolution {
            ResolutionChoice::Canvas => canvas_px,
            ResolutionChoice::Fixed => [s.fixed_size; 2],
        };
        let (w, h) = (w.clamp(16, 4096), h.clamp(16, 4096));
        Some(RenderRequest {
            scene: volume.scene.clone(),
            camera: self.camera.camera(w, h),
            tf: s.tf.clone(),
            options: RenderOptions {
                mode: s.mode,
                step: Some(s.full_step(volume.scene.grid())),
                ert: s.ert,
                ess: s.ess,
                shading: s.shading,
                iso_value: s.iso_value,
                lights: s.light_directions(),
                shadows: s.shadows,
                reflection: s.reflection,
                iso_normals: s.iso_normals,
                clip: s.clip.clip(&volume.scene.grid().bounds()),
                gradient_opacity: s.clip.gradient_opacity(),
                jitter: s.clip.jitter,
                ..RenderOptions::default()
            },
            renderer: s.renderer,
            threads: if s.renderer == RendererKind::Serial {
                1
            } else {
                s.threads
            },
            level: Level::FULL,
            preview: false,
            metaballs: s
                .metaballs
                .params(volume.scene.grid(), volume.scene.value_range()),
        })
    }

    /// The status line: the frame's refinement level, time, samples,
    /// renderer, size, step.
    pub(super) fn status_line(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            if let Some(f) = self.shown.as_ref().map(|s| &s.frame) {
                let st = &f.frame.stats;
                let stage = match (f.level == Level::FULL, f.preview) {
                    (true, _) => "full quality".to_string(),
                    (false, true) => format!("preview {}", f.level.label()),
                    (false, false) => format!("refining {}", f.level.label()),
                };
                let work = match &f.metaballs {
                    Some(b) => format!("{} balls", si(b.balls as f64)),
                    None => format!(
                        "{} samples · step {}",
                        si(st.samples as f64),
                        raycaster::units::value(f.step)
                    ),
                };
                ui.monospace(format!(
                    "{stage} · {:.1} ms · {work} · {} rays · {} ×{} · {}×{}",
                    st.time.as_secs_f64() * 1e3,
                    si(st.rays as f64),
                    f.renderer,
                    f.threads,
                    f.frame.width,
                    f.frame.height,
                ));
            } else {
                ui.monospace("no frame yet");
            }
            // A still label, not an animated spinner: a spinner repaints the
            // window continuously, and with software OpenGL (no GPU, where
            // this viewer is meant to run) every repaint takes CPU time
            // from the frame being rendered.
            if self.is_rendering() {
                ui.weak("rendering…");
            }
            if let Some(e) = &self.render_error {
                ui.colored_label(Color32::from_rgb(255, 110, 100), e);
            }
        });
    }
}

/// The largest rectangle of the image's aspect centred in `rect`.
fn fit(rect: Rect, width: u32, height: u32) -> Rect {
    let aspect = width as f32 / height.max(1) as f32;
    let size = if rect.width() / rect.height().max(1e-3) > aspect {
        egui::vec2(rect.height() * aspect, rect.height())
    } else {
        egui::vec2(rect.width(), rect.width() / aspect)
    };
    Rect::from_center_size(rect.center(), size)
}

/// `12.3 M`-style numbers.
pub(super) fn si(v: f64) -> String {
    match v {
        v if v >= 1e9 => format!("{:.2} G", v / 1e9),
        v if v >= 1e6 => format!("{:.1} M", v / 1e6),
        v if v >= 1e3 => format!("{:.1} k", v / 1e3),
        v => format!("{v:.0}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_keeps_the_aspect_and_centres() {
        let r = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(200.0, 100.0));
        let f = fit(r, 700, 700);
        assert_eq!(f.size(), egui::vec2(100.0, 100.0));
        assert_eq!(f.center(), r.center());
        let f = fit(r, 400, 100);
        assert_eq!(f.size(), egui::vec2(200.0, 50.0));
    }

    #[test]
    fn big_numbers_get_si_prefixes() {
        assert_eq!(si(12_345_678.0), "12.3 M");
        assert_eq!(si(950.0), "950");
    }
}

//! The timeline of a sequence (a `.vseq`, a 4-D NIfTI/NRRD, a directory of
//! frame files): play/pause, loop, speed, step ±1 (keys N and M), scrub.
//!
//! A [`Timeline`] holds the library's [`Playback`], which decodes the next
//! frames on a thread of its own. Each UI frame [`Timeline::poll`] hands
//! over the next frame's scene when it is due (by the speed), decoded
//! (`try_get`: the UI never waits) and the frame before it has been
//! rendered; the app swaps it into the volume on screen, so camera, TF,
//! mode and every setting stay as they are. While playing, frames count as
//! motion (previews within the time budget, see
//! [`progressive`](super::progressive)); paused, the frame refines.

use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{Color32, Key, Modifiers, Ui};
use raycaster::prelude::*;
use raycaster::sequence::{Playback, PlaybackFrame};

use super::app::ViewerApp;

/// How often the UI looks again for a frame that is still decoding (the
/// decoder does not wake the UI).
const DECODE_POLL: Duration = Duration::from_millis(10);

/// The range of the speed control, in frames per second.
pub const FPS_RANGE: std::ops::RangeInclusive<f32> = 0.5..=60.0;

/// A sequence being played (see the module documentation).
pub struct Timeline {
    playback: Playback,
    /// The frame on screen.
    current: Arc<PlaybackFrame>,
    /// A frame asked for (step, scrub, the next while playing) that is not
    /// decoded yet.
    wanted: Option<u32>,
    playing: bool,
    /// When the next frame is due while playing.
    due: Instant,
    /// The frame that could not be decoded last, and why (stepping goes on
    /// from it).
    failed: Option<(u32, String)>,
}

impl std::fmt::Debug for Timeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Timeline")
            .field("frames", &self.frames())
            .field("current", &self.current.index)
            .field("wanted", &self.wanted)
            .field("playing", &self.playing)
            .finish()
    }
}

impl Timeline {
    /// A paused timeline showing `first`, decoded by `playback`.
    pub fn new(playback: Playback, first: Arc<PlaybackFrame>) -> Self {
        Timeline {
            playback,
            current: first,
            wanted: None,
            playing: false,
            due: Instant::now(),
            failed: None,
        }
    }

    /// The number of frames.
    pub fn frames(&self) -> u32 {
        self.playback.sequence().frames()
    }

    /// The value range of every frame, when the sequence knows it (a
    /// packed one does).
    pub fn value_range(&self) -> Option<(f32, f32)> {
        let packed = self.playback.sequence().packed()?;
        Some(packed.value_range())
    }

    /// The frame on screen, with its decode and build times.
    pub fn current(&self) -> &PlaybackFrame {
        &self.current
    }

    /// True while playing.
    pub fn is_playing(&self) -> bool {
        self.playing
    }

    /// The last decoding error, if any.
    pub fn error(&self) -> Option<&str> {
        self.failed.as_ref().map(|(_, e)| e.as_str())
    }

    /// The frame on its way to the screen, else the one that failed last,
    /// else the one on screen.
    fn position(&self) -> u32 {
        let failed = self.failed.as_ref().map(|f| f.0);
        self.wanted.or(failed).unwrap_or(self.current.index)
    }

    /// Asks for frame `k` (clamped to the sequence); it goes on screen when
    /// decoded.
    pub fn go_to(&mut self, k: u32) {
        let k = k.min(self.frames().saturating_sub(1));
        self.wanted = (k != self.current.index).then_some(k);
        self.failed = None;
    }

    /// Steps `delta` frames (wrapping around when `looping`).
    pub fn step(&mut self, delta: i64, looping: bool) {
        let n = i64::from(self.frames());
        let k = i64::from(self.position()) + delta;
        let k = if looping {
            k.rem_euclid(n)
        } else {
            k.clamp(0, n - 1)
        };
        self.go_to(k as u32);
    }

    /// Starts or pauses; playing from the last frame without looping starts
    /// over.
    pub fn play(&mut self, on: bool, looping: bool, fps: f32) {
        if on && !looping && self.position() + 1 >= self.frames() {
            self.go_to(0);
        }
        self.playing = on;
        self.due = Instant::now() + period(fps);
    }

    /// The scene to put on screen now, if a frame is due and decoded;
    /// `rendered` says the frame on screen has been drawn (playing waits
    /// for it, so that no frame is skipped). Asks `ctx` for a repaint when
    /// it must look again.
    pub fn poll(
        &mut self,
        ctx: &egui::Context,
        fps: f32,
        looping: bool,
        rendered: bool,
    ) -> Option<Arc<Scene>> {
        let now = Instant::now();
        if self.playing && self.wanted.is_none() {
            if !rendered {
                return None; // the frame's arrival repaints the UI
            }
            if now < self.due {
                ctx.request_repaint_after(self.due - now);
                return None;
            }
            let next = self.current.index + 1;
            if next < self.frames() {
                self.wanted = Some(next);
            } else if looping {
                self.wanted = Some(0);
            } else {
                self.playing = false;
                return None;
            }
        }
        let k = self.wanted?;
        // `None` while frame `k` is still decoding.
        match self.playback.try_get(k)? {
            Ok(frame) => {
                self.wanted = None;
                self.failed = None;
                self.due = (self.due + period(fps)).max(now);
                self.current = frame;
                Some(self.current.scene.clone())
            }
            Err(e) => {
                self.wanted = None;
                self.playing = false;
                self.failed = Some((k, format!("Frame {}: {e}", k + 1)));
                None
            }
        }
    }

    /// Asks for a repaint while a wanted frame is still decoding.
    fn keep_polling(&self, ctx: &egui::Context) {
        if self.wanted.is_some() {
            ctx.request_repaint_after(DECODE_POLL);
        }
    }
}

/// The time between frames at `fps`.
fn period(fps: f32) -> Duration {
    let fps = if fps.is_finite() {
        fps.clamp(*FPS_RANGE.start(), *FPS_RANGE.end())
    } else {
        10.0
    };
    Duration::from_secs_f32(1.0 / fps)
}

impl ViewerApp {
    /// Puts the sequence's next frame on screen when it is time (the same
    /// path as a newly loaded volume: the scene of the volume on screen
    /// changes, nothing else).
    pub(super) fn poll_timeline(&mut self) {
        let rendered = !self.link.is_busy();
        let (Some(t), Some(v)) = (&mut self.timeline, &mut self.volume) else {
            return;
        };
        let s = &self.settings;
        if let Some(scene) = t.poll(&self.ctx, s.play_fps, s.play_loop, rendered) {
            v.scene = scene;
        }
        t.keep_polling(&self.ctx);
    }

    /// The timeline bar under the canvas, and the N / M / Space keys.
    pub(super) fn timeline_bar(&mut self, ui: &mut Ui) {
        let Some(t) = &mut self.timeline else { return };
        let s = &mut self.settings;
        let n = t.frames();
        if !ui.ctx().egui_wants_keyboard_input() {
            if ui.input_mut(|i| i.consume_key(Modifiers::NONE, Key::N)) {
                t.step(-1, s.play_loop);
            }
            if ui.input_mut(|i| i.consume_key(Modifiers::NONE, Key::M)) {
                t.step(1, s.play_loop);
            }
            // Space plays and pauses, unless a focused widget (a button)
            // would take it as a click.
            let unfocused = ui.ctx().memory(|m| m.focused().is_none());
            if unfocused && ui.input_mut(|i| i.consume_key(Modifiers::NONE, Key::Space)) {
                t.play(!t.playing, s.play_loop, s.play_fps);
            }
        }
        ui.horizontal(|ui| {
            if ui
                .button("−1")
                .on_hover_text("Previous frame (N)")
                .clicked()
            {
                t.step(-1, s.play_loop);
            }
            let label = if t.playing { "Pause" } else { "Play" };
            // As wide either way, so that the slider does not shift.
            let play = egui::Button::new(label).min_size(egui::vec2(52.0, 0.0));
            if ui.add(play).on_hover_text("Play / pause (Space)").clicked() {
                t.play(!t.playing, s.play_loop, s.play_fps);
            }
            if ui.button("+1").on_hover_text("Next frame (M)").clicked() {
                t.step(1, s.play_loop);
            }
            ui.checkbox(&mut s.play_loop, "Loop");
            let fps = egui::DragValue::new(&mut s.play_fps)
                .range(FPS_RANGE)
                .speed(0.1)
                .max_decimals(1)
                .suffix(" fps");
            ui.add(fps)
                .on_hover_text("Playback speed, frames per second");
            let mut k = t.position() + 1;
            let text = format!("{k}/{n}");
            ui.spacing_mut().slider_width = (ui.available_width() - 90.0).max(60.0);
            let slider = egui::Slider::new(&mut k, 1..=n.max(1))
                .show_value(false)
                .text(text);
            let r = ui.add(slider);
            if r.changed() {
                t.go_to(k - 1);
            }
            self.controls_moving |= r.dragged() || t.playing;
        });
        ui.horizontal(|ui| {
            let f = &t.current;
            let ms = |d: Duration| d.as_secs_f64() * 1e3;
            ui.label(format!("Frame {}/{n}", f.index + 1))
                .on_hover_text(t.playback.sequence().frame_name(f.index));
            let render = self.shown.as_ref().map_or("–".into(), |s| {
                format!("{:.1}", ms(s.frame.frame.stats.time))
            });
            ui.monospace(format!(
                "decode {:.1} ms · build {:.1} ms · render {render} ms",
                ms(f.decode),
                ms(f.build)
            ));
            if let Some(e) = t.error() {
                ui.colored_label(Color32::from_rgb(255, 110, 100), e);
            }
        });
    }
}

//! The left panel: file, volume information, transfer function, rendering
//! options and camera, one collapsible section each.

use egui::{CollapsingHeader, Ui};
use raycaster::integrator::{IsoNormals, RenderMode};
use raycaster::metaballs::Kernel;
use raycaster::render::RendererKind;
use raycaster::storage::StorageKind;
use raycaster::transfer::PRESET_NAMES;
use raycaster::units::{bytes, significant, value as format_value};

use super::app::ViewerApp;
use super::dialogs::Purpose;
use super::loading::{GradientHistogram, Source, VolumeInfo};
use super::state::{
    BALL_RADIUS_SCALE_RANGE, BALL_STRIDE_RANGE, ClipSettings, FIELD_THRESHOLD_RANGE, LightAngles,
    MAX_LIGHTS, MAX_VIEWER_PLANES, MODES, PlaneSetting, ResolutionChoice, STEP_FACTOR_RANGE,
    Settings, max_threads, mode_label,
};

impl ViewerApp {
    /// All sections of the left panel.
    pub(super) fn left_panel(&mut self, ui: &mut Ui) {
        self.controls_moving = false;
        ui.add_space(4.0);
        self.file_section(ui);
        section(ui, "Volume", |ui| self.volume_section(ui));
        section(ui, "Transfer function", |ui| self.tf_section(ui));
        section(ui, "Rendering", |ui| self.render_section(ui));
        section(ui, "Camera", |ui| self.camera_section(ui));
        section(ui, "Clipping", |ui| self.clip_section(ui));
    }

    fn file_section(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            if ui
                .add_enabled(!self.dialogs.is_open(), egui::Button::new("Open…"))
                .on_hover_text("Open a volume file (Ctrl+O), or drop one on the window")
                .clicked()
            {
                self.show_dialog(Purpose::OpenVolume);
            }
            if ui
                .add_enabled(!self.dialogs.is_open(), egui::Button::new("Folder…"))
                .on_hover_text(
                    "Open a folder: a DICOM series (its slices), a sequence (one file per frame) or the one scan in it",
                )
                .clicked()
            {
                self.show_dialog(Purpose::OpenFolder);
            }
            if ui.button("Demo volume").clicked() {
                self.open_demo();
            }
        });
        let l = ui.label("Path:");
        ui.horizontal(|ui| {
            let edit = egui::TextEdit::singleline(&mut self.path_input)
                .hint_text("volume file, sequence or folder");
            let size = egui::vec2(ui.available_width() - 60.0, ui.spacing().interact_size.y);
            let edit = ui.add_sized(size, edit).labelled_by(l.id);
            let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            if (ui.button("Load").clicked() || enter) && !self.path_input.trim().is_empty() {
                let path = std::path::PathBuf::from(self.path_input.trim());
                self.open(&path);
            }
        });
        ui.checkbox(&mut self.settings.load_in_ram, "Read files into RAM")
            .on_hover_text(
                "Otherwise files are memory-mapped: instant, and larger than RAM is fine",
            );
        if let Some(job) = &self.loading {
            let (phase, fraction) = job.progress();
            let name = match job.source() {
                Source::File(p, ..) => super::app::short_name(p),
                Source::Demo => "the demo volume".into(),
            };
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!(
                    "Loading: {} ({:.1} s)",
                    phase.label(),
                    job.elapsed().as_secs_f32()
                ));
            });
            ui.add(egui::Label::new(name).truncate());
            if let Some(f) = fraction {
                ui.add(egui::ProgressBar::new(f).show_percentage());
            }
        }
        if let Some(n) = &self.notice {
            ui.add(egui::Label::new(egui::RichText::new(n).weak()).wrap());
        }
    }

    fn volume_section(&mut self, ui: &mut Ui) {
        let Some(v) = &self.volume else {
            ui.weak("No volume yet.");
            return;
        };
        info_grid(ui, &v.info);
    }

    fn tf_section(&mut self, ui: &mut Ui) {
        let current = self
            .settings
            .tf_preset
            .clone()
            .unwrap_or_else(|| "custom".into());
        let mut chosen = None;
        egui::ComboBox::from_label("Preset")
            .selected_text(&current)
            .show_ui(ui, |ui| {
                for name in PRESET_NAMES {
                    if ui.selectable_label(current == name, name).clicked() {
                        chosen = Some(name);
                    }
                }
            });
        if let Some(name) = chosen {
            self.set_tf_preset(name);
        }
        let histogram = self.volume.as_ref().map(|v| &v.histogram);
        if self.tf_editor.show(ui, &mut self.settings.tf, histogram) {
            self.settings.tf_preset = None;
        }
        self.controls_moving |= self.tf_editor.is_dragging();
        self.gradient_opacity_controls(ui);
        ui.horizontal(|ui| {
            let enabled = !self.dialogs.is_open();
            if ui
                .add_enabled(enabled, egui::Button::new("Load JSON…"))
                .clicked()
            {
                self.show_dialog(Purpose::LoadTf);
            }
            if ui
                .add_enabled(enabled, egui::Button::new("Save JSON…"))
                .clicked()
            {
                self.show_dialog(Purpose::SaveTf);
            }
        });
    }

    /// Gradient opacity: a checkbox, the volume's gradient-magnitude
    /// histogram with the opacity weight drawn over it, and the g0/g1
    /// sliders on the histogram's scale.
    fn gradient_opacity_controls(&mut self, ui: &mut Ui) {
        let histogram = self.volume.as_ref().map(|v| &v.gradient_histogram);
        let c = &mut self.settings.clip;
        ui.checkbox(&mut c.gradient_opacity, "Gradient opacity (DVR)")
            .on_hover_text(
                "Opacity × clamp((|∇f| − g0)/(g1 − g0), 0, 1): shows boundaries, hides \
                 homogeneous regions (|∇f| in data units per world unit)",
            );
        if c.gradient_opacity {
            // The sliders reach the histogram's end, or further when a
            // setting already does.
            let gmax = histogram.map_or(255.0, |h| h.hi).max(c.g1);
            if let Some(h) = histogram {
                gradient_plot(ui, h, gmax, c.g0, c.g1);
            }
            let a = ui.add(egui::Slider::new(&mut c.g0, 0.0..=gmax).text("g0: hidden below"));
            let b = ui.add(egui::Slider::new(&mut c.g1, 0.0..=gmax).text("g1: full from"));
            if c.g1 <= c.g0 {
                // Keep g0 < g1: the slider not being dragged gives way.
                if b.dragged() {
                    c.g0 = (c.g1 - 1e-3 * gmax).max(0.0);
                }
                c.g1 = c.g1.max(c.g0 + 1e-3 * gmax);
            }
            self.controls_moving |= a.dragged() || b.dragged();
        }
    }

    /// Jitter, the crop box (six sliders, fractions of the volume's box)
    /// and up to three clip planes (normal angles and offset).
    fn clip_section(&mut self, ui: &mut Ui) {
        let c = &mut self.settings.clip;
        ui.checkbox(&mut c.jitter, "Jitter")
            .on_hover_text("Trades wood-grain banding at coarse steps for fine noise");
        ui.label("Crop box (fraction of the volume):");
        let mut moving = false;
        for (a, name) in ["x", "y", "z"].into_iter().enumerate() {
            let (lo, hi) = c.crop.split_at_mut(3);
            let r0 = ui.add(egui::Slider::new(&mut lo[a], 0.0..=1.0).text(format!("{name} min")));
            let r1 = ui.add(egui::Slider::new(&mut hi[a], 0.0..=1.0).text(format!("{name} max")));
            if lo[a] > hi[a] {
                if r0.dragged() {
                    hi[a] = lo[a];
                } else {
                    lo[a] = hi[a];
                }
            }
            moving |= r0.dragged() || r1.dragged();
        }
        if ui.button("Reset crop box").clicked() {
            c.crop = ClipSettings::default().crop;
        }
        let mut remove = None;
        for (n, p) in c.planes.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                ui.label(format!("Plane {}", n + 1));
                if ui.small_button("Remove").clicked() {
                    remove = Some(n);
                }
            });
            let az =
                egui::Slider::new(&mut p.normal.azimuth, -180.0..=180.0).text("Normal azimuth °");
            let el =
                egui::Slider::new(&mut p.normal.elevation, -90.0..=90.0).text("Normal elevation °");
            let off = egui::Slider::new(&mut p.offset, -1.0..=1.0).text("Offset");
            for r in [ui.add(az), ui.add(el), ui.add(off)] {
                moving |= r.dragged();
            }
        }
        if let Some(n) = remove {
            c.planes.remove(n);
        }
        if c.planes.len() < MAX_VIEWER_PLANES && ui.button("Add clip plane").clicked() {
            c.planes.push(PlaneSetting {
                normal: LightAngles::default(),
                offset: 0.3,
            });
        }
        self.controls_moving |= moving;
    }

    fn render_section(&mut self, ui: &mut Ui) {
        let s = &mut self.settings;
        // Wrapped: six modes in one row would widen the panel.
        ui.horizontal_wrapped(|ui| {
            ui.label("Mode:");
            for m in MODES {
                ui.radio_value(&mut s.mode, m, mode_label(m));
            }
        });
        if s.mode == RenderMode::Iso {
            let (lo, hi) = self
                .volume
                .as_ref()
                .map_or((0.0, 255.0), |v| v.info.value_range);
            let iso = egui::Slider::new(&mut s.iso_value, lo..=hi.max(lo + 1e-3)).text("Iso value");
            self.controls_moving |= ui.add(iso).dragged();
            self.controls_moving |= lights_editor(ui, s, true);
        }
        if s.mode == RenderMode::Metaballs {
            let balls = self.shown.as_ref().and_then(|f| f.frame.metaballs);
            self.controls_moving |= metaballs_editor(ui, s, balls);
            self.controls_moving |= lights_editor(ui, s, false);
        }
        ui.checkbox(&mut s.shading, "Shading (Phong)");
        ui.horizontal(|ui| {
            egui::ComboBox::from_label("Renderer")
                .selected_text(s.renderer.name())
                .show_ui(ui, |ui| {
                    for r in RendererKind::ALL {
                        ui.selectable_value(&mut s.renderer, r, r.name());
                    }
                });
        });
        ui.add_enabled(
            s.renderer != RendererKind::Serial,
            egui::Slider::new(&mut s.threads, 1..=max_threads()).text("Threads"),
        );
        ui.checkbox(&mut s.ert, "Early ray termination (ERT)");
        ui.checkbox(&mut s.ess, "Empty-space skipping (ESS)");
        let step = egui::Slider::new(&mut s.step_factor, STEP_FACTOR_RANGE)
            .logarithmic(true)
            .text("Step × smallest spacing");
        let step = ui.add(step).on_hover_text(
            "Sampling step of full-quality frames, in units of the smallest voxel spacing \
             (default 0.5, as `vol_app render`)",
        );
        self.controls_moving |= step.dragged();
        ui.checkbox(&mut s.progressive, "Progressive refinement")
            .on_hover_text(
                "While the view changes: reduced size and a coarser step, chosen to render \
                 fast; once still: refined ¼ → ½ → full resolution. Off: every frame at full \
                 quality",
            );
        ui.horizontal(|ui| {
            ui.label("Resolution:");
            ui.radio_value(&mut s.resolution, ResolutionChoice::Canvas, "Canvas");
            ui.radio_value(
                &mut s.resolution,
                ResolutionChoice::Fixed,
                format!("Fixed {0}×{0}", s.fixed_size),
            );
        });
        if s.resolution == ResolutionChoice::Fixed {
            ui.add(egui::Slider::new(&mut s.fixed_size, 64..=2048).text("Fixed size"));
        }
    }

    fn camera_section(&mut self, ui: &mut Ui) {
        let c = &mut self.camera;
        let (mut az, mut el, mut dist) = (c.azimuth, c.elevation, c.distance);
        let a = ui.add(egui::Slider::new(&mut az, -180.0..=180.0).text("Azimuth °"));
        let e = ui.add(egui::Slider::new(&mut el, -89.0..=89.0).text("Elevation °"));
        let d = ui.add(
            egui::Slider::new(&mut dist, c.min_distance()..=c.max_distance())
                .logarithmic(true)
                .text("Distance"),
        );
        if a.changed() || e.changed() {
            c.set_angles(az, el);
        }
        if d.changed() {
            c.set_distance(dist);
        }
        self.controls_moving |= a.dragged() || e.dragged() || d.dragged();
        ui.horizontal(|ui| {
            if ui
                .button("Reset camera")
                .on_hover_text("Also: double-click the canvas")
                .clicked()
            {
                self.camera.reset();
            }
            let can_save = self.shown.is_some() && !self.dialogs.is_open();
            if ui
                .add_enabled(can_save, egui::Button::new("Save frame as PNG…"))
                .clicked()
            {
                self.show_dialog(Purpose::SavePng);
            }
        });
        ui.weak("Left drag: orbit · right drag: pan · wheel: zoom · double-click: reset");
    }
}

/// The Metaballs mode's controls and the balls of the frame on screen.
/// Returns true while a slider is dragged.
fn metaballs_editor(
    ui: &mut Ui,
    s: &mut Settings,
    shown: Option<super::metaball_link::MetaballInfo>,
) -> bool {
    let m = &mut s.metaballs;
    let mut moving = false;
    moving |= ui
        .add(egui::Slider::new(&mut m.threshold, 0.0..=1.0).text("Ball threshold"))
        .on_hover_text(
            "A voxel gives a ball when its value is above this fraction of the volume's \
             value range (--ball-threshold)",
        )
        .dragged();
    moving |= ui
        .add(egui::Slider::new(&mut m.stride, BALL_STRIDE_RANGE).text("Stride"))
        .on_hover_text("Every N-th voxel along each axis (--ball-stride)")
        .dragged();
    moving |= ui
        .add(
            egui::Slider::new(&mut m.radius_scale, BALL_RADIUS_SCALE_RANGE)
                .logarithmic(true)
                .text("Radius ×"),
        )
        .on_hover_text(
            "Ball radius as a multiple of 1.5 × stride × the largest spacing (--ball-radius)",
        )
        .dragged();
    moving |= ui
        .add(
            egui::Slider::new(&mut m.field_threshold, FIELD_THRESHOLD_RANGE)
                .text("Field threshold"),
        )
        .on_hover_text("The surface is where the summed kernels equal this (--field-threshold)")
        .dragged();
    ui.horizontal(|ui| {
        ui.label("Kernel:");
        for k in [Kernel::Wyvill, Kernel::Murakami] {
            ui.radio_value(&mut m.kernel, k, k.name());
        }
    });
    match shown {
        Some(b) if b.build_ms > 0.0 => {
            ui.label(format!("{} balls (made in {:.0} ms)", b.balls, b.build_ms))
        }
        Some(b) => ui.label(format!("{} balls", b.balls)),
        None => ui.weak("balls: not made yet"),
    };
    moving
}

/// The directional lights (none: the headlight) and shadows of the iso and
/// Metaballs modes, and iso mode's normals (`iso`). Returns true while a
/// light's slider is dragged.
fn lights_editor(ui: &mut Ui, s: &mut Settings, iso: bool) -> bool {
    ui.checkbox(&mut s.shadows, "Shadows")
        .on_hover_text("Cast a shadow ray towards each light from every surface hit");
    if iso {
        ui.add(egui::Slider::new(&mut s.reflection, 0.0..=1.0).text("Reflection"))
            .on_hover_text(
                "One mirror bounce: the share of each hit's colour that the ray \
                 reflected about the normal sees (0 = off)",
            );
    }
    let mut analytic = s.iso_normals == IsoNormals::Analytic;
    if iso
        && ui
            .checkbox(&mut analytic, "Faceted normals")
            .on_hover_text(
                "Normals from the exact derivative of each cell's interpolant (faceted) \
             instead of the interpolated central differences (smooth)",
            )
            .changed()
    {
        s.iso_normals = if analytic {
            IsoNormals::Analytic
        } else {
            IsoNormals::Gradient
        };
    }
    ui.horizontal(|ui| {
        ui.label("Lights:");
        if s.lights.is_empty() {
            ui.weak("Headlight")
                .on_hover_text("No lights added: lit from the camera");
        }
        let add = ui.add_enabled(s.lights.len() < MAX_LIGHTS, egui::Button::new("Add light"));
        if add
            .on_hover_text(format!("Up to {MAX_LIGHTS} directional lights"))
            .clicked()
        {
            s.lights.push(LightAngles::default());
        }
    });
    let (mut remove, mut moving) = (None, false);
    for (i, l) in s.lights.iter_mut().enumerate() {
        let n = i + 1;
        ui.horizontal(|ui| {
            ui.label(format!("Light {n}"));
            if ui.small_button("Remove").clicked() {
                remove = Some(i);
            }
        });
        let az =
            egui::Slider::new(&mut l.azimuth, -180.0..=180.0).text(format!("Light {n} azimuth °"));
        let el = egui::Slider::new(&mut l.elevation, -90.0..=90.0)
            .text(format!("Light {n} elevation °"));
        let (az, el) = (ui.add(az), ui.add(el));
        moving |= az.dragged() || el.dragged();
    }
    if let Some(i) = remove {
        s.lights.remove(i);
    }
    moving
}

/// The gradient-magnitude histogram over `0..=gmax` (log-scaled counts,
/// as the value histogram behind the TF curve), with the gradient opacity
/// weight `w(|∇f|)` of `g0`, `g1` drawn over it.
fn gradient_plot(ui: &mut Ui, h: &GradientHistogram, gmax: f32, g0: f32, g1: f32) {
    let size = egui::vec2(ui.available_width(), 44.0);
    let (rect, response) = ui.allocate_exact_size(size, egui::Sense::hover());
    response.widget_info(|| {
        egui::WidgetInfo::labeled(egui::Role::Canvas, true, "Gradient-magnitude histogram")
    });
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 3.0, egui::Color32::from_gray(24));
    let x = |g: f32| rect.left() + (g / gmax).clamp(0.0, 1.0) * rect.width();
    let max = h.counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    let w = h.hi / h.counts.len() as f32;
    for (i, &n) in h.counts.iter().enumerate().filter(|(_, n)| **n > 0) {
        let frac = (1.0 + n as f32).ln() / (1.0 + max).ln();
        let (x0, x1) = (x(i as f32 * w), x((i + 1) as f32 * w));
        painter.rect_filled(
            egui::Rect::from_min_max(
                egui::pos2(x0, rect.bottom() - frac * rect.height()),
                egui::pos2(x1.max(x0 + 1.0), rect.bottom()),
            ),
            0.0,
            egui::Color32::from_gray(85),
        );
    }
    let y = |weight: f32| rect.bottom() - weight * (rect.height() - 2.0);
    let ramp = vec![
        egui::pos2(rect.left(), y(0.0)),
        egui::pos2(x(g0), y(0.0)),
        egui::pos2(x(g1), y(1.0)),
        egui::pos2(rect.right(), y(1.0)),
    ];
    painter.line(
        ramp,
        egui::Stroke::new(1.5, egui::Color32::from_rgb(250, 200, 60)),
    );
    response.on_hover_text(format!(
        "|∇f| of sampled voxels, 0 to {:.4}; the line is the opacity weight",
        gmax
    ));
}

/// A collapsible section, open by default.
fn section(ui: &mut Ui, title: &str, body: impl FnOnce(&mut Ui)) {
    ui.separator();
    CollapsingHeader::new(title)
        .default_open(true)
        .show(ui, body);
}

/// The volume's facts as a two-column grid.
fn info_grid(ui: &mut Ui, info: &VolumeInfo) {
    let mut rows = vec![
        // A long file name is shortened rather than widening the panel.
        ("Name", ellipsize(&info.name, 32)),
        (
            "Dimensions",
            format!("{} × {} × {}", info.dims.x, info.dims.y, info.dims.z),
        ),
        (
            "Spacing",
            info.spacing
                .to_array()
                .map(|c| significant(c, 6))
                .join(" × "),
        ),
        ("Type", info.sample_type.name().to_string()),
        (
            "Values",
            format!(
                "{} … {}",
                format_value(info.value_range.0),
                format_value(info.value_range.1)
            ),
        ),
        (
            "File size",
            info.file_size().map_or("in memory".into(), bytes),
        ),
        ("Layout", info.layout.to_string()),
        (
            "Storage",
            match info.storage {
                StorageKind::Mapped => "memory-mapped".into(),
                StorageKind::Ram => "in RAM".into(),
            },
        ),
        (
            "Load time",
            format!("{:.0} ms", info.load_time.as_secs_f64() * 1e3),
        ),
    ];
    if let Some(file) = &info.file {
        rows.insert(1, ("Format", file.format.name().to_string()));
        let order = file
            .byte_order
            .map(|e| format!(", {}-endian", e.name()))
            .unwrap_or_default();
        rows.push((
            "Stored as",
            format!("{}{order}, {}", file.stored_type, file.encoding),
        ));
        if let Some(r) = file.rescale {
            rows.push(("Rescale", format!("value = {r}")));
        }
        if let Some(o) = &file.orientation {
            rows.push(("Orientation", ellipsize(o, 40)));
        }
        for n in &file.notes {
            rows.push(("Note", ellipsize(n, 40)));
        }
    }
    egui::Grid::new("volume-info")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            for (k, v) in rows {
                ui.label(k);
                ui.label(v);
                ui.end_row();
            }
        });
}

/// `text` cut in the middle to at most `max` characters.
fn ellipsize(text: &str, max: usize) -> String {
    let chars: Vec<char> = text.chars().collect();
    if chars.len() <= max {
        return text.to_string();
    }
    let head = (max - 1) / 2;
    let tail = max - 1 - head;
    let mut s: String = chars[..head].iter().collect();
    s.push('…');
    s.extend(&chars[chars.len() - tail..]);
    s
}

#[cfg(test)]
mod tests {
    #[test]
    fn long_names_are_cut_in_the_middle() {
        assert_eq!(super::ellipsize("head.vol", 10), "head.vol");
        let s = super::ellipsize("a_very_long_volume_name.vol", 11);
        assert_eq!(s, "a_ver…e.vol");
        assert_eq!(s.chars().count(), 11);
    }
}

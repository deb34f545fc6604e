//! Slice views: axial, coronal and sagittal slices through a cursor point,
//! beside or instead of the 3D image, with window/level and a readout of
//! the position and value under the mouse.
//!
//! The slices come from the library's [`slice_image`] (one pixel per voxel
//! of the plane, so a pixel is `spacing[u] × spacing[v]` and each view keeps
//! the aspect of the slice's physical extent). They are cut on short-lived
//! threads: a slice of a memory-mapped file may have to fault its pages in
//! from disk, which the UI must not wait for. Each view shows its newest
//! slice and asks for the next one when the cursor has moved along its
//! normal, one request in flight per view.
//!
//! Controls in a slice: left click or drag moves the cursor, right drag
//! sets window (horizontal) and level (vertical). The 3D view shows the
//! cursor as a small cross of the three axes (see `ViewerApp::draw_cursor_3d`).

use std::sync::Arc;

use crossbeam_channel::{Receiver, Sender};
use egui::{Color32, PointerButton, Pos2, Rect, Sense, Stroke, TextureHandle, TextureOptions, Ui};
use glam::Vec3;
use raycaster::volume::Grid;
use raycaster::volume::slice::{SliceAxis, SliceImage, sampled_quantiles, slice_image, value_at};

use super::app::ViewerApp;

/// What the central area shows (`vol_app --layout`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Layout {
    /// The 3D view only.
    #[default]
    #[value(name = "3d")]
    View3d,
    /// The three slices only.
    Slices,
    /// 2×2: the 3D view and the three slices.
    #[value(name = "2x2")]
    Grid,
}

impl Layout {
    /// The choices, with their labels.
    pub const ALL: [(Layout, &'static str); 3] = [
        (Layout::View3d, "3D"),
        (Layout::Slices, "Slices"),
        (Layout::Grid, "2×2"),
    ];
}

/// A window of values shown from black to white: `level ± width/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowLevel {
    /// Width of the window (data units, > 0).
    pub width: f32,
    /// Its centre.
    pub level: f32,
}

impl WindowLevel {
    /// The grey (0..=255) of value `v`.
    pub fn grey(self, v: f32) -> u8 {
        let lo = self.level - 0.5 * self.width;
        (((v - lo) / self.width).clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// The standard CT windows (Hounsfield units).
pub const CT_PRESETS: [(&str, WindowLevel); 4] = [
    (
        "Brain",
        WindowLevel {
            width: 80.0,
            level: 40.0,
        },
    ),
    (
        "Soft tissue",
        WindowLevel {
            width: 400.0,
            level: 40.0,
        },
    ),
    (
        "Lung",
        WindowLevel {
            width: 1500.0,
            level: -600.0,
        },
    ),
    (
        "Bone",
        WindowLevel {
            width: 1800.0,
            level: 400.0,
        },
    ),
];

/// The label of the window from the volume's 1st and 99th percentiles.
pub const AUTO: &str = "Auto (1–99 %)";

/// Voxels sampled for the auto window.
const AUTO_SAMPLES: u64 = 250_000;

/// The position and value under the mouse in a slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hover {
    /// The slice.
    pub axis: SliceAxis,
    /// World position (the slice's plane).
    pub world: Vec3,
    /// The trilinearly interpolated value there.
    pub value: Option<f32>,
}

/// One slice view: the newest slice, its texture, the request in flight.
#[derive(Default)]
struct View {
    image: Option<Arc<SliceImage>>,
    /// The scene the image was cut from (its address: a new frame of a
    /// sequence is a new scene).
    image_scene: usize,
    texture: Option<TextureHandle>,
    /// The window the texture was made with.
    texture_window: Option<WindowLevel>,
    in_flight: bool,
}

enum Msg {
    Slice {
        view: usize,
        scene: usize,
        image: SliceImage,
    },
    Auto {
        scene: usize,
        window: WindowLevel,
    },
}

/// The slice views' state.
pub struct SliceViews {
    /// Layout of the central area.
    pub layout: Layout,
    /// The cursor (world position) the slices go through.
    pub cursor: Vec3,
    /// The window shown.
    pub window: WindowLevel,
    /// The preset or [`AUTO`] the window came from; `None` once dragged.
    pub window_name: Option<&'static str>,
    /// What is under the mouse, while it is over a slice.
    pub hover: Option<Hover>,
    /// The auto window of the volume, once computed.
    auto: Option<WindowLevel>,
    /// The scene the auto window was asked for.
    auto_scene: usize,
    /// The volume the cursor and window were set for (a new grid or file
    /// resets them; a new frame of the same sequence does not).
    volume_key: Option<(Grid, String)>,
    views: [View; 3],
    tx: Sender<Msg>,
    rx: Receiver<Msg>,
}

impl Default for SliceViews {
    fn default() -> Self {
        let (tx, rx) = crossbeam_channel::unbounded();
        SliceViews {
            layout: Layout::View3d,
            cursor: Vec3::ZERO,
            window: WindowLevel {
                width: 255.0,
                level: 127.5,
            },
            window_name: None,
            hover: None,
            auto: None,
            auto_scene: 0,
            volume_key: None,
            views: Default::default(),
            tx,
            rx,
        }
    }
}

impl SliceViews {
    /// The slice on view `axis`, once cut.
    pub fn image(&self, axis: SliceAxis) -> Option<&SliceImage> {
        self.views[index(axis)].image.as_deref()
    }
}

fn index(axis: SliceAxis) -> usize {
    match axis {
        SliceAxis::Axial => 0,
        SliceAxis::Coronal => 1,
        SliceAxis::Sagittal => 2,
    }
}

/// Colours of the cursor lines: the line of constant x (seen in the axial
/// and coronal slices) is red like the sagittal view's frame, etc.
fn axis_colour(axis: usize) -> Color32 {
    [
        Color32::from_rgb(230, 80, 80),
        Color32::from_rgb(90, 200, 90),
        Color32::from_rgb(90, 140, 240),
    ][axis]
}

impl ViewerApp {
    /// The slice views (layout, cursor, window, readout).
    pub fn slices(&self) -> &SliceViews {
        &self.slices
    }

    /// The slice views, to change them as the toolbar would.
    pub fn slices_mut(&mut self) -> &mut SliceViews {
        &mut self.slices
    }

    /// The central area: the toolbar, then the 3D view and the slices in
    /// the chosen layout.
    pub(super) fn central(&mut self, ui: &mut Ui) {
        self.central_toolbar(ui);
        self.update_slices();
        let rect = ui.available_rect_before_wrap();
        let cell = |i: f32, j: f32, cols: f32, rows: f32| {
            let size = egui::vec2(rect.width() / cols, rect.height() / rows);
            Rect::from_min_size(rect.min + egui::vec2(i * size.x, j * size.y), size).shrink(1.0)
        };
        match self.slices.layout {
            Layout::View3d => return self.canvas(ui),
            Layout::Slices => {
                let wide = rect.width() >= rect.height();
                for (k, axis) in SliceAxis::ALL.into_iter().enumerate() {
                    let r = if wide {
                        cell(k as f32, 0.0, 3.0, 1.0)
                    } else {
                        cell(0.0, k as f32, 1.0, 3.0)
                    };
                    self.slice_view(ui, r, axis);
                }
            }
            Layout::Grid => {
                let mut view =
                    ui.new_child(egui::UiBuilder::new().max_rect(cell(0.0, 0.0, 2.0, 2.0)));
                self.canvas(&mut view);
                for (axis, (i, j)) in
                    SliceAxis::ALL
                        .into_iter()
                        .zip([(1.0, 0.0), (0.0, 1.0), (1.0, 1.0)])
                {
                    self.slice_view(ui, cell(i, j, 2.0, 2.0), axis);
                }
            }
        }
        ui.allocate_rect(rect, Sense::hover());
    }

    /// Layout switch, window/level controls, turntable export.
    fn central_toolbar(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            ui.label("View:");
            for (layout, label) in Layout::ALL {
                ui.selectable_value(&mut self.slices.layout, layout, label);
            }
            if self.slices.layout != Layout::View3d {
                ui.separator();
                self.window_controls(ui);
            }
            ui.separator();
            self.turntable_button(ui);
        });
    }

    fn window_controls(&mut self, ui: &mut Ui) {
        let s = &mut self.slices;
        let shown = s.window_name.unwrap_or("Custom");
        egui::ComboBox::from_label("Window")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                let auto = s.auto;
                if ui
                    .add_enabled(
                        auto.is_some(),
                        egui::Button::selectable(shown == AUTO, AUTO),
                    )
                    .clicked()
                    && let Some(w) = auto
                {
                    s.window = w;
                    s.window_name = Some(AUTO);
                }
                for (name, w) in CT_PRESETS {
                    let label = format!("CT {name} (W{} L{})", w.width, w.level);
                    if ui.selectable_label(shown == name, label).clicked() {
                        s.window = w;
                        s.window_name = Some(name);
                    }
                }
            });
        let w = ui.add(
            egui::DragValue::new(&mut s.window.width)
                .prefix("W ")
                .range(1e-3..=1e9),
        );
        let l = ui.add(egui::DragValue::new(&mut s.window.level).prefix("L "));
        if w.changed() || l.changed() {
            s.window_name = None;
        }
    }

    /// Takes in finished slices and auto windows, resets the cursor and the
    /// window for a new volume, and asks for the slices the cursor needs.
    fn update_slices(&mut self) {
        let Some(volume) = &self.volume else {
            return;
        };
        let scene = volume.scene.clone();
        let scene_id = Arc::as_ptr(&scene) as usize;
        let key = (*scene.grid(), volume.info.name.clone());
        let s = &mut self.slices;
        if s.volume_key.as_ref() != Some(&key) {
            s.volume_key = Some(key);
            s.cursor = scene.grid().bounds().center();
            s.auto = None;
            s.auto_scene = scene_id;
            s.hover = None;
            for v in &mut s.views {
                v.image = None;
            }
            let ct = volume
                .info
                .file
                .as_ref()
                .and_then(|f| f.modality.as_deref())
                == Some("CT");
            // CT opens on the soft-tissue window; everything else on the
            // auto window once it is known (the value range until then).
            let (lo, hi) = volume.info.value_range;
            (s.window, s.window_name) = if ct {
                (CT_PRESETS[1].1, Some(CT_PRESETS[1].0))
            } else {
                (
                    WindowLevel {
                        width: (hi - lo).max(1e-3),
                        level: 0.5 * (lo + hi),
                    },
                    Some(AUTO),
                )
            };
            let (tx, wake, scene) = (s.tx.clone(), self.ctx.clone(), scene.clone());
            std::thread::spawn(move || {
                let q = sampled_quantiles(scene.volume(), &[0.01, 0.99], AUTO_SAMPLES);
                let window = WindowLevel {
                    width: (q[1] - q[0]).max(1e-3),
                    level: 0.5 * (q[0] + q[1]),
                };
                let _ = tx.send(Msg::Auto {
                    scene: Arc::as_ptr(&scene) as usize,
                    window,
                });
                wake.request_repaint();
            });
        }
        while let Ok(msg) = s.rx.try_recv() {
            match msg {
                Msg::Slice { view, scene, image } => {
                    let v = &mut s.views[view];
                    // A slice of the previous frame of a sequence is worth
                    // showing until the next arrives; one of another grid
                    // is not.
                    let (u, w) = image.axis.in_plane();
                    let dims = volume.scene.grid().dims;
                    if (image.width, image.height) != (dims[u], dims[w]) {
                        v.in_flight = false;
                        continue;
                    }
                    v.in_flight = false;
                    v.image = Some(Arc::new(image));
                    v.image_scene = scene;
                    v.texture_window = None;
                }
                Msg::Auto { scene, window } => {
                    // An auto window of another volume is stale.
                    if scene == s.auto_scene {
                        s.auto = Some(window);
                        if s.window_name == Some(AUTO) {
                            s.window = window;
                        }
                    }
                }
            }
        }
        if s.layout == Layout::View3d {
            return;
        }
        for axis in SliceAxis::ALL {
            let n = axis.normal();
            let want = s.cursor[n];
            let v = &mut s.views[index(axis)];
            let current = v.image.as_ref().is_some_and(|i| {
                v.image_scene == scene_id && slice_position(&scene, axis, want) == i.position
            });
            if current || v.in_flight {
                continue;
            }
            v.in_flight = true;
            let (tx, wake, scene) = (s.tx.clone(), self.ctx.clone(), scene.clone());
            std::thread::spawn(move || {
                let image = slice_image(scene.volume(), axis, want);
                let _ = tx.send(Msg::Slice {
                    view: index(axis),
                    scene: Arc::as_ptr(&scene) as usize,
                    image,
                });
                wake.request_repaint();
            });
        }
    }

    /// One slice view in `rect`: the image at its physical aspect, the
    /// cursor lines, the label, mouse control and the readout.
    fn slice_view(&mut self, ui: &mut Ui, rect: Rect, axis: SliceAxis) {
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::BLACK);
        let (Some(volume), Some(image)) =
            (&self.volume, self.slices.views[index(axis)].image.clone())
        else {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "…",
                egui::FontId::proportional(18.0),
                Color32::GRAY,
            );
            return;
        };
        let grid = *volume.scene.grid();
        let scene = volume.scene.clone();
        let (u, v) = axis.in_plane();
        let extent = egui::vec2(
            image.width as f32 * image.pixel_size[0],
            image.height as f32 * image.pixel_size[1],
        );
        let shown = fit(rect.shrink(2.0), extent);
        let mut cell = ui.new_child(egui::UiBuilder::new().max_rect(rect));
        let response = cell.allocate_rect(shown, Sense::click_and_drag());
        let label = format!("{} slice", axis.label());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Canvas, true, &label));

        // Texture, remade when the slice or the window changed.
        let window = self.slices.window;
        let view = &mut self.slices.views[index(axis)];
        if view.texture_window != Some(window) || view.texture.is_none() {
            let grey: Vec<u8> = image.values.iter().map(|&x| window.grey(x)).collect();
            let size = [image.width as usize, image.height as usize];
            let picture = egui::ColorImage::from_gray(size, &grey);
            match &mut view.texture {
                Some(t) => t.set(picture, TextureOptions::NEAREST),
                None => {
                    view.texture = Some(ui.ctx().load_texture(
                        label.clone(),
                        picture,
                        TextureOptions::NEAREST,
                    ))
                }
            }
            view.texture_window = Some(window);
        }
        if let Some(t) = &view.texture {
            // Row 0 is the lowest coordinate: flip so that `v` points up.
            let uv = Rect::from_min_max(egui::pos2(0.0, 1.0), egui::pos2(1.0, 0.0));
            painter.image(t.id(), shown, uv, Color32::WHITE);
        }

        let cursor = self.slices.cursor;
        // World ↔ screen: pixel k covers [k, k + 1) of the image, its voxel
        // sits at its centre.
        let to_world = |p: Pos2| {
            let fu = (p.x - shown.left()) / shown.width() * image.width as f32 - 0.5;
            let fv = (shown.bottom() - p.y) / shown.height() * image.height as f32 - 0.5;
            let mut w = cursor;
            w[u] = grid.origin[u] + fu.clamp(0.0, (grid.dims[u] - 1) as f32) * grid.spacing[u];
            w[v] = grid.origin[v] + fv.clamp(0.0, (grid.dims[v] - 1) as f32) * grid.spacing[v];
            w[axis.normal()] = image.position;
            w
        };
        let to_screen = |w: Vec3| {
            let fu = (w[u] - grid.origin[u]) / grid.spacing[u] + 0.5;
            let fv = (w[v] - grid.origin[v]) / grid.spacing[v] + 0.5;
            egui::pos2(
                shown.left() + fu / image.width as f32 * shown.width(),
                shown.bottom() - fv / image.height as f32 * shown.height(),
            )
        };

        // Mouse: left moves the cursor, right drag sets window/level.
        if let Some(p) = response.interact_pointer_pos()
            && (response.clicked_by(PointerButton::Primary)
                || response.dragged_by(PointerButton::Primary))
        {
            // The cursor keeps its own through-plane coordinate: the image
            // shown may still be the slice at the cursor's previous position
            // while the new one is extracted, and a click must not move the
            // cursor back to it.
            let mut w = to_world(p);
            w[axis.normal()] = cursor[axis.normal()];
            self.slices.cursor = w;
        }
        if response.dragged_by(PointerButton::Secondary) {
            let d = response.drag_delta();
            let (lo, hi) = volume.info.value_range;
            let per_point = (hi - lo).max(1e-3) / 400.0;
            let s = &mut self.slices;
            s.window.width = (s.window.width + d.x * per_point).max(per_point);
            s.window.level -= d.y * per_point;
            s.window_name = None;
        }
        match response.hover_pos() {
            Some(p) => {
                let world = to_world(p);
                self.slices.hover = Some(Hover {
                    axis,
                    world,
                    value: value_at(scene.volume(), world),
                });
            }
            None if self.slices.hover.is_some_and(|h| h.axis == axis) => self.slices.hover = None,
            None => {}
        }

        // Cursor lines: the other two axes' planes through the cursor.
        let c = to_screen(self.slices.cursor);
        let stroke = |a: usize| Stroke::new(1.0, axis_colour(a));
        painter.line_segment(
            [
                egui::pos2(c.x, shown.top()),
                egui::pos2(c.x, shown.bottom()),
            ],
            stroke(u),
        );
        painter.line_segment(
            [
                egui::pos2(shown.left(), c.y),
                egui::pos2(shown.right(), c.y),
            ],
            stroke(v),
        );
        painter.rect_stroke(rect, 0.0, stroke(axis.normal()), egui::StrokeKind::Inside);

        let small = egui::FontId::proportional(13.0);
        let names = ["x", "y", "z"];
        painter.text(
            rect.left_top() + egui::vec2(6.0, 4.0),
            egui::Align2::LEFT_TOP,
            format!(
                "{} · {} = {:.1}",
                axis.label(),
                names[axis.normal()],
                image.position
            ),
            small.clone(),
            Color32::from_gray(220),
        );
        if let Some(h) = self.slices.hover.filter(|h| h.axis == axis) {
            // A label rather than painted text: screen readers (and the UI
            // tests) can read it.
            let at = Rect::from_min_max(
                rect.left_bottom() + egui::vec2(6.0, -22.0),
                rect.right_bottom() - egui::vec2(6.0, 2.0),
            );
            let text = egui::RichText::new(readout(&h))
                .font(small)
                .color(Color32::from_gray(230));
            cell.put(at, egui::Label::new(text).truncate());
        }
    }

    /// The cursor in the 3D view: three short lines along the world axes,
    /// projected through the camera of the frame on screen (`image_rect`
    /// is where that frame is drawn). Only while slices are shown.
    pub(super) fn draw_cursor_3d(&self, painter: &egui::Painter, image_rect: Rect) {
        let (Some(shown), Some(volume)) = (&self.shown, &self.volume) else {
            return;
        };
        if self.slices.layout == Layout::View3d {
            return;
        }
        let arm = 0.08 * volume.scene.grid().extent().length();
        for (a, [p, q]) in cursor_cross(&shown.frame.camera, self.slices.cursor, arm, image_rect) {
            painter.line_segment([p, q], Stroke::new(2.0, axis_colour(a)));
        }
    }
}

/// The cursor's cross in the 3D view: for each world axis (0 = x, 1 = y,
/// 2 = z) the segment `cursor ± arm·axis` projected through `camera` into
/// `image_rect` (where the camera's image is drawn); a segment with an end
/// behind the camera is left out.
pub fn cursor_cross(
    camera: &raycaster::camera::Camera,
    cursor: Vec3,
    arm: f32,
    image_rect: Rect,
) -> Vec<(usize, [Pos2; 2])> {
    let Some(frame) = camera.frame() else {
        return Vec::new();
    };
    let to_screen = |p: Vec3| {
        frame.project(p).map(|(i, j)| {
            egui::pos2(
                image_rect.left() + i / camera.width as f32 * image_rect.width(),
                image_rect.top() + j / camera.height as f32 * image_rect.height(),
            )
        })
    };
    [Vec3::X, Vec3::Y, Vec3::Z]
        .into_iter()
        .enumerate()
        .filter_map(|(a, dir)| {
            Some((
                a,
                [
                    to_screen(cursor - dir * arm)?,
                    to_screen(cursor + dir * arm)?,
                ],
            ))
        })
        .collect()
}

/// The world position the slice at `want` along `axis` lies at (clamped as
/// [`slice_image`] clamps it), to tell whether a slice is current.
fn slice_position(scene: &raycaster::scene::Scene, axis: SliceAxis, want: f32) -> f32 {
    let g = scene.grid();
    let n = axis.normal();
    let t = ((want - g.origin[n]) / g.spacing[n]).clamp(0.0, (g.dims[n] - 1) as f32);
    let t = if t.is_nan() { 0.0 } else { t };
    g.origin[n] + t * g.spacing[n]
}

/// `x 12.0 y -3.5 z 40.0 mm · value 123`.
pub fn readout(h: &Hover) -> String {
    let value = h.value.map_or_else(
        || "outside".to_string(),
        |v| format!("value {}", raycaster::units::significant(v, 4)),
    );
    format!(
        "x {:.1} y {:.1} z {:.1} mm · {value}",
        h.world.x, h.world.y, h.world.z
    )
}

/// The largest rectangle of `extent`'s aspect centred in `rect`.
fn fit(rect: Rect, extent: egui::Vec2) -> Rect {
    let aspect = extent.x / extent.y.max(1e-6);
    let size = if rect.width() / rect.height().max(1e-3) > aspect {
        egui::vec2(rect.height() * aspect, rect.height())
    } else {
        egui::vec2(rect.width(), rect.width() / aspect)
    };
    Rect::from_center_size(rect.center(), size)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_maps_level_to_mid_grey() {
        let w = WindowLevel {
            width: 80.0,
            level: 40.0,
        };
        assert_eq!(w.grey(0.0), 0);
        assert_eq!(w.grey(40.0), 128);
        assert_eq!(w.grey(80.0), 255);
        assert_eq!(w.grey(-1000.0), 0);
    }

    #[test]
    fn the_cursor_cross_is_projected_through_the_camera() {
        use raycaster::camera::Camera;
        // From +z looking at the origin, up +y: x is to the right and y up
        // on screen, z points at the viewer (a dot).
        let camera = Camera::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 200, 100);
        let rect = Rect::from_min_size(egui::pos2(50.0, 20.0), egui::vec2(400.0, 200.0));
        let cross = cursor_cross(&camera, Vec3::ZERO, 1.0, rect);
        assert_eq!(cross.len(), 3);
        let centre = rect.center();
        let [l, r] = cross[0].1;
        assert!(l.x < centre.x && r.x > centre.x && (l.y - centre.y).abs() < 1e-3);
        let [d, u] = cross[1].1;
        assert!(d.y > centre.y && u.y < centre.y && (d.x - centre.x).abs() < 1e-3);
        let [b, f] = cross[2].1;
        assert!(b.distance(centre) < 1e-3 && f.distance(centre) < 1e-3);
        // Off centre: x = 1 at depth 10 is (1/10)/(tan 22.5°·aspect 2) of
        // the half width right of the middle (SPEC §3).
        let cross = cursor_cross(&camera, Vec3::new(1.0, 0.0, 0.0), 0.5, rect);
        let mid = cross[1].1[0].lerp(cross[1].1[1], 0.5);
        let h = (22.5f32).to_radians().tan();
        let want = centre.x + 1.0 / (10.0 * h * 2.0) * 0.5 * rect.width();
        assert!((mid.x - want).abs() < 0.01, "{} vs {want}", mid.x);
        // Behind the camera: nothing.
        assert!(cursor_cross(&camera, Vec3::new(0.0, 0.0, 20.0), 1.0, rect).is_empty());
    }

    #[test]
    fn slices_keep_their_physical_aspect() {
        let r = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(300.0, 300.0));
        // 100 × 50 voxels of 1 × 3 mm: 100 mm wide, 150 mm high.
        let f = fit(r, egui::vec2(100.0, 150.0));
        assert_eq!(f.size(), egui::vec2(200.0, 300.0));
    }
}

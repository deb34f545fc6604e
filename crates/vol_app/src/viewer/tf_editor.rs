//! The transfer-function editor: control points drawn as an opacity curve
//! over the volume's histogram, with a strip of the TF's colours beneath.
//!
//! Drag a point to change its value (x) and opacity (y); double-click empty
//! space to add a point; right-click a point to remove it; click a point to
//! edit its colour and exact numbers below the curve. The opacity axis is
//! square-root scaled so that the faint opacities typical of volume
//! rendering (0.01–0.1) stay easy to grab.

use egui::{Color32, PointerButton, Pos2, Rect, Sense, Stroke, Ui, vec2};
use raycaster::transfer::{Interpolation, TfPoint, TransferFunction};

use super::loading::Histogram;

/// Height of the curve area in points.
const PLOT_HEIGHT: f32 = 150.0;
/// Height of the colour strip under the curve.
const STRIP_HEIGHT: f32 = 12.0;
/// How close (points) the pointer must be to grab a control point.
const GRAB_RADIUS: f32 = 9.0;

/// Editor state that lives between frames.
#[derive(Debug, Default)]
pub struct TfEditor {
    selected: Option<usize>,
    dragging: Option<usize>,
    on_screen: Vec<Pos2>,
}

/// The mapping between values/opacities and the plot's points.
struct Axes {
    curve: Rect,
    strip: Rect,
    lo: f32,
    hi: f32,
}

impl Axes {
    fn x(&self, v: f32) -> f32 {
        self.curve.left() + (v - self.lo) / (self.hi - self.lo) * self.curve.width()
    }
    fn value(&self, x: f32) -> f32 {
        self.lo + (x - self.curve.left()) / self.curve.width() * (self.hi - self.lo)
    }
    fn y(&self, opacity: f32) -> f32 {
        self.curve.bottom() - opacity.clamp(0.0, 1.0).sqrt() * self.curve.height()
    }
    fn opacity(&self, y: f32) -> f32 {
        ((self.curve.bottom() - y) / self.curve.height())
            .clamp(0.0, 1.0)
            .powi(2)
    }
    fn point(&self, p: &TfPoint) -> Pos2 {
        Pos2::new(self.x(p.value), self.y(p.opacity))
    }
}

/// The value range the editor shows: the data's and the TF's together.
fn shown_range(tf: &TransferFunction, histogram: Option<&Histogram>) -> (f32, f32) {
    let (mut lo, mut hi) = tf.value_span();
    if let Some(h) = histogram {
        lo = lo.min(h.range.0);
        hi = hi.max(h.range.1);
    }
    if hi - lo < 1e-6 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo, hi)
    }
}

/// `[r, g, b]` in 0..1 as a colour.
pub fn color32(c: [f32; 3]) -> Color32 {
    let u = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    Color32::from_rgb(u(c[0]), u(c[1]), u(c[2]))
}

impl TfEditor {
    /// Where the control points were drawn in the last frame (UI points).
    pub fn point_positions(&self) -> &[Pos2] {
        &self.on_screen
    }

    /// True while a control point is being dragged.
    pub fn is_dragging(&self) -> bool {
        self.dragging.is_some()
    }

    /// Shows the editor; returns true when `tf` changed.
    pub fn show(
        &mut self,
        ui: &mut Ui,
        tf: &mut TransferFunction,
        histogram: Option<&Histogram>,
    ) -> bool {
        let n = tf.points.len();
        self.selected = self.selected.filter(|&i| i < n);
        self.dragging = self.dragging.filter(|&i| i < n);
        let width = ui.available_width().max(120.0);
        let (rect, response) = ui.allocate_exact_size(
            vec2(width, PLOT_HEIGHT + STRIP_HEIGHT + 4.0),
            Sense::click_and_drag(),
        );
        response.widget_info(|| {
            egui::WidgetInfo::labeled(egui::Role::Canvas, true, "Transfer function curve")
        });
        let (lo, hi) = shown_range(tf, histogram);
        let inner = rect.shrink2(vec2(6.0, 4.0));
        let axes = Axes {
            curve: Rect::from_min_max(
                inner.min,
                Pos2::new(inner.right(), inner.bottom() - STRIP_HEIGHT),
            ),
            strip: Rect::from_min_max(
                Pos2::new(inner.left(), inner.bottom() - STRIP_HEIGHT + 2.0),
                inner.max,
            ),
            lo,
            hi,
        };
        let hit = |tf: &TransferFunction, p: Option<Pos2>| hit(tf, &axes, p);
        let mut changed = false;
        if response.drag_started_by(PointerButton::Primary) {
            self.dragging = hit(tf, ui.input(|i| i.pointer.press_origin()));
            if self.dragging.is_some() {
                self.selected = self.dragging;
            }
        }
        if let (Some(i), Some(p)) = (self.dragging, response.interact_pointer_pos())
            && response.dragged_by(PointerButton::Primary)
        {
            changed |= move_point(tf, i, axes.value(p.x), axes.opacity(p.y));
        }
        if response.drag_stopped() {
            self.dragging = None;
        }
        let pointer = response.interact_pointer_pos();
        if response.clicked() {
            self.selected = hit(tf, pointer);
        }
        if response.double_clicked()
            && hit(tf, pointer).is_none()
            && let Some(p) = pointer
        {
            self.selected = Some(insert_point(tf, axes.value(p.x), axes.opacity(p.y)));
            changed = true;
        }
        if response.secondary_clicked()
            && let Some(i) = hit(tf, pointer)
            && tf.points.len() > 1
        {
            tf.points.remove(i);
            self.selected = None;
            changed = true;
        }
        paint(ui, rect, &axes, tf, histogram, self.selected);
        self.on_screen = tf.points.iter().map(|p| axes.point(p)).collect();
        changed |= self.point_details(ui, tf);
        ui.horizontal(|ui| {
            ui.label("Interpolation:");
            for (mode, name) in [
                (Interpolation::Linear, "linear"),
                (Interpolation::Step, "step"),
            ] {
                changed |= ui.radio_value(&mut tf.interpolation, mode, name).changed();
            }
        });
        changed
    }

    /// The selected point's numbers and colour, or a usage hint.
    fn point_details(&mut self, ui: &mut Ui, tf: &mut TransferFunction) -> bool {
        let Some(i) = self.selected else {
            ui.weak("Drag a point to move it, double-click to add one, right-click to remove it; click a point to edit it.");
            return false;
        };
        let n = tf.points.len();
        let lo = if i > 0 {
            tf.points[i - 1].value
        } else {
            f32::MIN
        };
        let hi = if i + 1 < n {
            tf.points[i + 1].value
        } else {
            f32::MAX
        };
        let span = (tf.value_span().1 - tf.value_span().0).abs().max(1.0);
        let mut changed = false;
        let mut remove = false;
        ui.horizontal_wrapped(|ui| {
            let p = &mut tf.points[i];
            ui.label(format!("Point {} of {n}:", i + 1));
            let l = ui.label("value");
            changed |= ui
                .add(
                    egui::DragValue::new(&mut p.value)
                        .range(lo..=hi)
                        .speed(span / 500.0),
                )
                .labelled_by(l.id)
                .changed();
            let l = ui.label("opacity");
            changed |= ui
                .add(
                    egui::DragValue::new(&mut p.opacity)
                        .range(0.0..=1.0)
                        .speed(0.002)
                        .max_decimals(3),
                )
                .labelled_by(l.id)
                .changed();
            let mut rgb = color32(p.color).to_srgba_unmultiplied();
            let mut srgb = [rgb[0], rgb[1], rgb[2]];
            if egui::color_picker::color_edit_button_srgb(ui, &mut srgb)
                .on_hover_text("Point colour")
                .changed()
            {
                rgb[..3].copy_from_slice(&srgb);
                p.color = [0, 1, 2].map(|k| rgb[k] as f32 / 255.0);
                changed = true;
            }
            remove = ui.add_enabled(n > 1, egui::Button::new("Remove")).clicked();
        });
        if remove {
            tf.points.remove(i);
            self.selected = None;
            changed = true;
        }
        changed
    }
}

/// The control point within grabbing distance of `p`, the nearest if several.
fn hit(tf: &TransferFunction, axes: &Axes, p: Option<Pos2>) -> Option<usize> {
    let p = p?;
    tf.points
        .iter()
        .enumerate()
        .map(|(i, q)| (i, axes.point(q).distance(p)))
        .filter(|&(_, d)| d <= GRAB_RADIUS)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// Moves point `i` to `value` (kept between its neighbours) and `opacity`.
fn move_point(tf: &mut TransferFunction, i: usize, value: f32, opacity: f32) -> bool {
    let lo = if i > 0 {
        tf.points[i - 1].value
    } else {
        f32::MIN
    };
    let hi = tf.points.get(i + 1).map_or(f32::MAX, |p| p.value);
    let p = &mut tf.points[i];
    let (v, a) = (value.clamp(lo, hi), opacity.clamp(0.0, 1.0));
    let changed = p.value != v || p.opacity != a;
    p.value = v;
    p.opacity = a;
    changed
}

/// Inserts a point at `value` with the TF's current colour there; returns its
/// index.
fn insert_point(tf: &mut TransferFunction, value: f32, opacity: f32) -> usize {
    let c = tf.evaluate(value);
    let i = tf.points.partition_point(|p| p.value <= value);
    tf.points.insert(
        i,
        TfPoint {
            value,
            color: [c.x, c.y, c.z].map(|v| v.clamp(0.0, 1.0)),
            opacity: opacity.clamp(0.0, 1.0),
        },
    );
    i
}

fn paint(
    ui: &Ui,
    rect: Rect,
    axes: &Axes,
    tf: &TransferFunction,
    histogram: Option<&Histogram>,
    selected: Option<usize>,
) {
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 3.0, Color32::from_gray(24));
    // Histogram, log-scaled counts.
    if let Some(h) = histogram {
        let max = h.counts.iter().copied().max().unwrap_or(0).max(1) as f32;
        let w = (h.hi - h.lo) / h.counts.len() as f32;
        for (i, &c) in h.counts.iter().enumerate().filter(|(_, c)| **c > 0) {
            let v0 = h.lo + i as f32 * w;
            let frac = (1.0 + c as f32).ln() / (1.0 + max).ln();
            let top = axes.curve.bottom() - frac * axes.curve.height();
            let x0 = axes.x(v0);
            let x1 = axes.x(v0 + w).max(x0 + 1.0);
            painter.rect_filled(
                Rect::from_min_max(Pos2::new(x0, top), Pos2::new(x1, axes.curve.bottom())),
                0.0,
                Color32::from_gray(85),
            );
        }
    }
    // The colour strip and the opacity curve, one column per point of width.
    let mut curve = Vec::new();
    let mut x = axes.curve.left();
    while x <= axes.curve.right() {
        let c = tf.evaluate(axes.value(x));
        let shade = 0.25 + 0.75 * c.w.clamp(0.0, 1.0).sqrt();
        painter.rect_filled(
            Rect::from_min_max(
                Pos2::new(x, axes.strip.top()),
                Pos2::new(x + 1.0, axes.strip.bottom()),
            ),
            0.0,
            color32([c.x * shade, c.y * shade, c.z * shade]),
        );
        curve.push(Pos2::new(x, axes.y(c.w)));
        x += 1.0;
    }
    painter.line(curve, Stroke::new(1.5, Color32::from_gray(230)));
    for (i, p) in tf.points.iter().enumerate() {
        let stroke = if selected == Some(i) {
            Stroke::new(2.5, Color32::YELLOW)
        } else {
            Stroke::new(1.0, Color32::WHITE)
        };
        painter.circle(axes.point(p), 5.0, color32(p.color), stroke);
    }
    let font = egui::FontId::proportional(11.0);
    let weak = Color32::from_gray(160);
    let top = rect.top() + 2.0;
    painter.text(
        Pos2::new(rect.left() + 4.0, top),
        egui::Align2::LEFT_TOP,
        raycaster::units::value(axes.lo),
        font.clone(),
        weak,
    );
    painter.text(
        Pos2::new(rect.right() - 4.0, top),
        egui::Align2::RIGHT_TOP,
        raycaster::units::value(axes.hi),
        font,
        weak,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use raycaster::sample::SampleType;

    fn shapes() -> TransferFunction {
        TransferFunction::preset("shapes", SampleType::U8).unwrap()
    }

    #[test]
    fn moving_a_point_keeps_the_points_sorted_and_in_range() {
        let mut tf = shapes();
        assert!(move_point(&mut tf, 1, 1000.0, 3.0));
        assert_eq!(tf.points[1].value, tf.points[2].value);
        assert_eq!(tf.points[1].opacity, 1.0);
        assert!(move_point(&mut tf, 1, -5.0, -1.0));
        assert_eq!(tf.points[1].value, tf.points[0].value);
        assert_eq!(tf.points[1].opacity, 0.0);
        assert!(!move_point(&mut tf, 1, -5.0, -1.0));
        assert!(TransferFunction::from_json(&tf.to_json()).is_ok());
    }

    #[test]
    fn inserted_points_take_the_colour_under_them_and_keep_order() {
        let mut tf = shapes();
        let i = insert_point(&mut tf, 97.0, 0.5);
        assert_eq!(i, 2);
        assert_eq!(tf.points[i].color, shapes().points[1].color);
        assert!(tf.points.windows(2).all(|w| w[0].value <= w[1].value));
        let i = insert_point(&mut tf, -10.0, 0.1);
        assert_eq!(i, 0);
    }

    #[test]
    fn the_axes_invert() {
        let axes = Axes {
            curve: Rect::from_min_max(Pos2::new(10.0, 0.0), Pos2::new(210.0, 100.0)),
            strip: Rect::NOTHING,
            lo: -50.0,
            hi: 150.0,
        };
        for v in [-50.0, 0.0, 37.5, 150.0] {
            assert!((axes.value(axes.x(v)) - v).abs() < 1e-3);
        }
        for a in [0.0, 0.02, 0.3, 1.0] {
            assert!((axes.opacity(axes.y(a)) - a).abs() < 1e-5);
        }
        assert!(
            axes.y(0.02) < axes.y(0.0) - 10.0,
            "faint opacities are visible"
        );
    }
}

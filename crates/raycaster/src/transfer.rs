//! Transfer functions: map a sample value to colour and opacity (the opacity
//! is for one world unit of path length).
//!
//! A [`TransferFunction`] is the user's description (control points, JSON
//! files, named presets). Renderers never evaluate it per sample: they use a
//! [`TfLut`], a table built for one sampling step that already holds the
//! step-corrected opacity `α = 1 − (1 − a)^s` and the colour premultiplied by
//! it, and that answers "is anything in this value range visible?" in O(1) for
//! empty-space skipping.

use std::path::Path;

use crate::simd::{Isa, LANES};
use glam::{Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::sample::SampleType;

/// How RGBA varies between control points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Linear between neighbouring points, clamped to the end points outside.
    #[default]
    Linear,
    /// The RGBA of the last point whose value is <= v; transparent below the first.
    Step,
}

/// One control point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TfPoint {
    /// Sample value (data units).
    pub value: f32,
    /// Colour, each channel in 0..=1.
    pub color: [f32; 3],
    /// Opacity per world unit of path length, 0..=1.
    pub opacity: f32,
}

/// A transfer function: sorted control points and an interpolation rule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransferFunction {
    /// How to interpolate between points.
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Control points sorted by value.
    pub points: Vec<TfPoint>,
}

/// Names of the built-in presets.
pub const PRESET_NAMES: [&str; 6] = [
    "shapes",
    "skull",
    "ramp",
    "ct-bone",
    "ct-soft",
    "mr-default",
];

fn rgb255(r: u8, g: u8, b: u8) -> [f32; 3] {
    [r as f32 / 255.0, g as f32 / 255.0, b as f32 / 255.0]
}

fn pt(value: f32, color: [f32; 3], opacity: f32) -> TfPoint {
    TfPoint {
        value,
        color,
        opacity,
    }
}

impl TransferFunction {
    /// A validated transfer function.
    pub fn new(interpolation: Interpolation, points: Vec<TfPoint>) -> Result<Self> {
        let tf = TransferFunction {
            interpolation,
            points,
        };
        tf.validate().map_err(|message| Error::TransferFunction {
            path: Default::default(),
            message,
        })?;
        Ok(tf)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        if self.points.is_empty() {
            return Err("transfer function has no points".into());
        }
        for (i, p) in self.points.iter().enumerate() {
            if !p.value.is_finite() {
                return Err(format!("point {i}: value {} is not finite", p.value));
            }
            if !(0.0..=1.0).contains(&p.opacity) {
                return Err(format!("point {i}: opacity {} outside 0..1", p.opacity));
            }
            if p.color.iter().any(|c| !(0.0..=1.0).contains(c)) {
                return Err(format!("point {i}: colour {:?} outside 0..1", p.color));
            }
            if i > 0 && p.value < self.points[i - 1].value {
                return Err(format!(
                    "points are not sorted by value ({} after {})",
                    p.value,
                    self.points[i - 1].value
                ));
            }
        }
        Ok(())
    }

    /// Reads a TF from a JSON file.
    pub fn from_json_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_json(&text).map_err(|e| match e {
            Error::TransferFunction { message, .. } => Error::TransferFunction {
                path: path.to_path_buf(),
                message,
            },
            other => other,
        })
    }

    /// Parses a TF from JSON text.
    pub fn from_json(text: &str) -> Result<Self> {
        let tf: TransferFunction =
            serde_json::from_str(text).map_err(|e| Error::TransferFunction {
                path: Default::default(),
                message: format!("invalid transfer function JSON: {e}"),
            })?;
        tf.validate().map_err(|message| Error::TransferFunction {
            path: Default::default(),
            message,
        })?;
        Ok(tf)
    }

    /// The TF as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// A named preset for data of `sample_type` (the `ramp` preset spans the
    /// type's range), or `None` for an unknown name. See [`PRESET_NAMES`].
    /// `mr-default` assumes a typical brightest value for the type; use
    /// [`TransferFunction::preset_for_data`] when the data is at hand.
    pub fn preset(name: &str, sample_type: SampleType) -> Option<Self> {
        Self::preset_for_data(name, sample_type, (0.0, mr_scale(sample_type)))
    }

    /// A named preset fitted to data of `sample_type` whose values span
    /// `value_range`. Only `mr-default` uses the range: MR intensities have
    /// no physical unit, so its control points sit at fixed fractions of the
    /// brightest value (tuned on the FLAIR, MNI152 and DICOM MRI data in
    /// ../shared/data). The CT presets are in Hounsfield units and `ramp`
    /// spans the type (white, transparent at 0, opaque at the type's maximum).
    pub fn preset_for_data(
        name: &str,
        sample_type: SampleType,
        value_range: (f32, f32),
    ) -> Option<Self> {
        let bright = if value_range.1.is_finite() && value_range.1 > value_range.0.max(0.0) {
            value_range.1
        } else {
            mr_scale(sample_type)
        };
        use Interpolation::*;
        let (interpolation, points) = match name {
            "shapes" => (
                Step,
                vec![
                    // Just above the bounds: red for 85 < v <= 95, blue for
                    // 95 < v <= 100, green for 100 < v < 115, so shapes of
                    // exactly 95 and 100 take the colour below the bound.
                    pt(85.001, rgb255(255, 30, 60), 0.02),
                    pt(95.001, rgb255(10, 60, 180), 0.3),
                    pt(100.001, rgb255(90, 210, 20), 0.6),
                    pt(115.0, [0.0; 3], 0.0),
                ],
            ),
            "skull" => (
                Step,
                vec![
                    pt(40.0, rgb255(227, 218, 201), 1.0),
                    pt(240.0, [0.0; 3], 0.0),
                ],
            ),
            "ramp" => (
                Linear,
                vec![
                    pt(0.0, [1.0; 3], 0.0),
                    pt(sample_type.max_value(), [1.0; 3], 1.0),
                ],
            ),
            // Hounsfield units: soft tissue transparent, bone from ~200 HU.
            "ct-bone" => (
                Linear,
                vec![
                    pt(150.0, rgb255(200, 120, 90), 0.0),
                    pt(250.0, rgb255(230, 200, 160), 0.3),
                    pt(700.0, rgb255(245, 235, 215), 0.9),
                    pt(2000.0, [1.0, 1.0, 0.97], 1.0),
                ],
            ),
            // Skin faint, fat clear, muscle and organs a thin red veil,
            // contrast-filled vessels brighter, bone white (tuned on a
            // contrast chest CT and a head CT, see README "Formats").
            "ct-soft" => (
                Linear,
                vec![
                    pt(-700.0, rgb255(200, 140, 115), 0.0),
                    pt(-400.0, rgb255(220, 160, 130), 0.01),
                    pt(-150.0, rgb255(220, 160, 130), 0.0),
                    pt(20.0, rgb255(190, 60, 50), 0.0),
                    pt(60.0, rgb255(200, 70, 55), 0.03),
                    pt(150.0, rgb255(225, 120, 90), 0.08),
                    pt(300.0, rgb255(240, 220, 190), 0.5),
                    pt(1000.0, [1.0, 1.0, 0.95], 0.9),
                ],
            ),
            // MR intensities are unitless: fractions of the brightest value;
            // the lowest 8% (noise floor, air) stays transparent.
            "mr-default" => (
                Linear,
                vec![
                    pt(0.0, [0.0; 3], 0.0),
                    pt(0.08 * bright, rgb255(120, 90, 80), 0.0),
                    pt(0.25 * bright, rgb255(220, 170, 140), 0.15),
                    pt(0.6 * bright, rgb255(250, 235, 220), 0.5),
                    pt(bright, [1.0; 3], 0.8),
                ],
            ),
            _ => return None,
        };
        Some(TransferFunction {
            interpolation,
            points,
        })
    }

    /// Colour and opacity (per world unit) at value `v`, exactly: linear
    /// interpolates between neighbouring points and clamps outside them;
    /// step takes the last point whose value is <= `v` (transparent below
    /// the first).
    pub fn evaluate(&self, v: f32) -> Vec4 {
        let p = &self.points;
        let rgba = |q: &TfPoint| Vec4::new(q.color[0], q.color[1], q.color[2], q.opacity);
        match self.interpolation {
            Interpolation::Step => match p.iter().rposition(|q| q.value <= v) {
                Some(i) => rgba(&p[i]),
                None => Vec4::ZERO,
            },
            Interpolation::Linear => {
                let first = &p[0];
                let last = &p[p.len() - 1];
                if v <= first.value {
                    return rgba(first);
                }
                if v >= last.value {
                    return rgba(last);
                }
                let i = p.iter().rposition(|q| q.value <= v).unwrap_or(0);
                let (a, b) = (&p[i], &p[i + 1]);
                let w = if b.value > a.value {
                    (v - a.value) / (b.value - a.value)
                } else {
                    1.0
                };
                rgba(a).lerp(rgba(b), w)
            }
        }
    }

    /// The smallest and largest point values.
    pub fn value_span(&self) -> (f32, f32) {
        (
            self.points[0].value,
            self.points[self.points.len() - 1].value,
        )
    }
}

/// The value that `mr-default` treats as bright.
fn mr_scale(t: SampleType) -> f32 {
    match t {
        SampleType::U8 | SampleType::I8 => t.max_value(),
        SampleType::F32 => 1.0,
        _ => 1000.0,
    }
}

/// A transfer function tabulated for one sampling step.
///
/// Entry `e` holds `(α·r, α·g, α·b, α)` with `α = 1 − (1 − a)^step`. The table
/// covers the span of the TF's points at `scale` entries per value unit (a
/// power of two, so points at integers or simple fractions fall exactly on
/// entry boundaries); one extra entry at each end holds what the TF gives
/// below the first and above the last point. A step TF's interval with one
/// control point strictly inside it is split at that point (values above it
/// take the next entry); any other interval with a control point inside it (a
/// kink the table cannot represent) is flagged, and values falling there are
/// evaluated exactly, so lookups equal [`TransferFunction::evaluate`]
/// whatever the points.
#[derive(Debug, Clone)]
pub struct TfLut {
    entries: Vec<Vec4>,
    /// Per interval: evaluate exactly instead of from the table.
    exact: Vec<bool>,
    /// Per interval of a step TF: the one point inside it (+∞ when none):
    /// values at or above it take the next entry, which is that point's.
    split: Vec<f32>,
    /// Per interval: 0 when every value in it is transparent by the table,
    /// non-zero otherwise (and for exact intervals), for
    /// [`TfLut::visible_lanes`].
    keys: Vec<f32>,
    /// Prefix counts of intervals that hold a visible value, for [`TfLut::any_visible`].
    visible_prefix: Vec<u32>,
    /// Per interval, for its values below and at or above `split`: the
    /// number of the stretch of values that all look up the same entry
    /// ([`NOT_CONSTANT`] where the lookup varies), numbered in value order,
    /// for [`TfLut::constant_over`].
    pieces: Vec<[u32; 2]>,
    tf: TransferFunction,
    lo: f32,
    scale: f32,
    /// `entries.len() − 2`: the largest position.
    max_position: f32,
    linear: bool,
    step: f32,
}

/// [`TfLut::pieces`] of values whose lookup varies within the interval.
const NOT_CONSTANT: u32 = u32::MAX;

/// Entries per table, roughly; the scale is the largest power of two that
/// keeps the table this small (16 per unit for u8 data).
const LUT_TARGET: f32 = 4096.0;

impl TfLut {
    /// Tabulates `tf` for sampling step `step` (world units).
    pub fn new(tf: &TransferFunction, step: f32) -> Self {
        let (lo, hi) = tf.value_span();
        let span = (hi - lo).max(1e-6);
        let scale = (LUT_TARGET / span).log2().floor().clamp(-20.0, 20.0).exp2();
        let n = ((span * scale).ceil() as usize).max(1);
        let linear = tf.interpolation == Interpolation::Linear;
        let correct = |c: Vec4| correct(c, step);
        // Node j (j >= 1) sits at value lo + (j − 1)/scale; node 0 stands for
        // "below lo" and the last node for "above hi".
        let node = |j: usize| lo + (j as f32 - 1.0) / scale;
        let mut entries = Vec::with_capacity(n + 3);
        entries.push(correct(if linear { tf.evaluate(lo) } else { Vec4::ZERO }));
        for i in 0..=n {
            entries.push(correct(tf.evaluate(node(i + 1))));
        }
        entries.push(correct(tf.evaluate(hi)));
        // Interval j covers [node j, node j+1) (step) or [node j, node j+1]
        // (linear, interpolated between the two nodes). A linear TF may jump
        // at a point (two points with one value), so a point on an
        // interval's right end also makes it exact.
        let intervals = entries.len() - 1;
        let mut exact = vec![false; intervals];
        let mut split = vec![f32::INFINITY; intervals];
        let mut visible = vec![false; intervals];
        for j in 0..intervals {
            let (a, b) = (node(j), node(j + 1));
            let inner: Vec<&TfPoint> = if j == 0 || j + 1 >= intervals {
                Vec::new()
            } else {
                tf.points
                    .iter()
                    .filter(|p| p.value > a && (p.value < b || (linear && p.value <= b)))
                    .collect()
            };
            // One step inside an interval splits it in two table entries:
            // the TF is constant from that point to the next node.
            // (Unless another point sits on that node.)
            let point_on_end = tf.points.iter().any(|p| p.value == b);
            match inner.as_slice() {
                [p] if !linear && !point_on_end => split[j] = p.value,
                [] => {}
                _ => exact[j] = true,
            }
            visible[j] = entries[j].w > 0.0
                || (linear && entries[j + 1].w > 0.0)
                || inner.iter().any(|p| p.opacity > 0.0);
        }
        let keys = (0..intervals)
            .map(|j| match (exact[j], linear || split[j].is_finite()) {
                (true, _) => -1.0,
                (false, true) => entries[j].w.max(entries[j + 1].w),
                (false, false) => entries[j].w,
            })
            .collect();
        let mut visible_prefix = Vec::with_capacity(intervals + 1);
        let mut count = 0u32;
        visible_prefix.push(0);
        for &v in &visible {
            count += v as u32;
            visible_prefix.push(count);
        }
        // Stretches of values with one lookup: an interval continues the
        // stretch before it when its entry is the same; an exact interval
        // or a linear one between two different entries varies.
        let mut pieces = Vec::with_capacity(intervals);
        let (mut id, mut current) = (0u32, None::<Vec4>);
        let mut piece = |e: Option<Vec4>| match e {
            Some(e) if current == Some(e) => id,
            Some(e) => {
                id += 1;
                current = Some(e);
                id
            }
            None => {
                current = None;
                NOT_CONSTANT
            }
        };
        for j in 0..intervals {
            let varies = exact[j] || (linear && entries[j] != entries[j + 1]);
            let below = piece((!varies).then_some(entries[j]));
            let above = if split[j].is_finite() {
                piece(Some(entries[j + 1]))
            } else {
                below
            };
            pieces.push([below, above]);
        }
        let entries_len = entries.len();
        TfLut {
            entries,
            exact,
            split,
            keys,
            visible_prefix,
            pieces,
            tf: tf.clone(),
            lo,
            scale,
            max_position: (entries_len - 2) as f32,
            linear,
            step,
        }
    }

    /// The sampling step this table was made for.
    pub fn step(&self) -> f32 {
        self.step
    }

    /// Position of value `v` in node units (node 0 = below the span).
    #[inline(always)]
    fn position(&self, v: f32) -> f32 {
        // max/min rather than clamp: NaN becomes 0 (see `index`).
        ((v - self.lo) * self.scale + 1.0)
            .max(0.0)
            .min(self.max_position)
    }

    /// The entry index of a position from [`TfLut::position`].
    #[inline(always)]
    fn index(x: f32) -> usize {
        // SAFETY: `position` returns a value in [0, entries.len() − 2] (NaN
        // mapped to 0), and tables are far shorter than 2^31 entries, so
        // the truncation is representable. (Through `i32`, which a vector
        // instruction converts; `u32` takes the compiler several.)
        unsafe { x.to_int_unchecked::<i32>() as u32 as usize }
    }

    /// Premultiplied, step-corrected `(α·r, α·g, α·b, α)` at value `v`.
    #[inline(always)]
    pub fn lookup(&self, v: f32) -> Vec4 {
        self.lookup_at(self.position(v), v)
    }

    /// The table positions of the values `v`, computed lane-wise (the part
    /// of [`TfLut::lookup`] that vectorises), and a mask with bit `l` set
    /// when `v[l]` may have a non-zero opacity: lanes whose bit is clear
    /// look up as transparent. [`TfLut::lookup_at`] finishes the lookups.
    #[inline(always)]
    pub fn visible_lanes<I: Isa>(&self, isa: I, v: &[f32; LANES]) -> ([f32; LANES], u32) {
        let mut x = [0.0; LANES];
        let mut i = [0u32; LANES];
        for l in 0..LANES {
            x[l] = self.position(v[l]);
            i[l] = Self::index(x[l]) as u32;
        }
        let key = isa.gather(&self.keys, &i);
        let mut visible = [0u32; LANES];
        for l in 0..LANES {
            visible[l] = (key[l] != 0.0) as u32;
        }
        (x, isa.nonzero_mask(&visible))
    }

    /// [`TfLut::lookup`] of value `v` at its table position `x` (from
    /// [`TfLut::visible_lanes`]).
    #[inline(always)]
    pub fn lookup_at(&self, x: f32, v: f32) -> Vec4 {
        let i = Self::index(x);
        if self.exact[i] {
            return self.exact_lookup(v);
        }
        if self.linear {
            let f = x - i as f32;
            let a = self.entries[i];
            let b = self.entries[i + 1];
            a + (b - a) * f
        } else {
            self.entries[i + (v >= self.split[i]) as usize]
        }
    }

    #[cold]
    fn exact_lookup(&self, v: f32) -> Vec4 {
        correct(self.tf.evaluate(v), self.step)
    }

    /// True when some value in `[vmin, vmax]` has a non-zero opacity under
    /// this table: the test behind empty-space skipping, consistent with
    /// [`TfLut::lookup`] by construction.
    #[inline]
    pub fn any_visible(&self, vmin: f32, vmax: f32) -> bool {
        let a = Self::index(self.position(vmin));
        let b = Self::index(self.position(vmax));
        // Whether interval `j` holds a visible value, counting only the
        // parts of a split interval below / above its point the range
        // reaches.
        let part = |j: usize, lower: bool, upper: bool| {
            if self.split[j].is_finite() {
                (lower && self.entries[j].w > 0.0) || (upper && self.entries[j + 1].w > 0.0)
            } else {
                self.visible_prefix[j + 1] > self.visible_prefix[j]
            }
        };
        if a == b {
            return part(a, vmin < self.split[a], vmax >= self.split[a]);
        }
        part(a, vmin < self.split[a], true)
            || part(b, true, vmax >= self.split[b])
            || self.visible_prefix[b] > self.visible_prefix[a + 1]
    }

    /// True when every value in `[vmin, vmax]` looks up the same entry (so
    /// [`TfLut::lookup`] of `vmin` is the lookup of any sample a cell of that
    /// value range gives): unshaded, such a cell is composited without
    /// sampling it.
    #[inline]
    pub fn constant_over(&self, vmin: f32, vmax: f32) -> bool {
        let piece = |v: f32| {
            let j = Self::index(self.position(v));
            self.pieces[j][(v >= self.split[j]) as usize]
        };
        let a = piece(vmin);
        a != NOT_CONSTANT && a == piece(vmax)
    }

    /// Colour (not premultiplied) and step-corrected opacity at `v`.
    pub fn color(&self, v: f32) -> (Vec3, f32) {
        let e = self.lookup(v);
        if e.w > 0.0 {
            (e.truncate() / e.w, e.w)
        } else {
            (Vec3::ZERO, 0.0)
        }
    }
}

/// Opacity correction for step `step` and premultiplication.
fn correct(c: Vec4, step: f32) -> Vec4 {
    let a = 1.0 - (1.0 - c.w.clamp(0.0, 1.0)).powf(step);
    Vec4::new(c.x * a, c.y * a, c.z * a, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes [`TfLut::visible_lanes`] leaves out look up as transparent,
    /// its positions are `lookup`'s, and the AVX2 copy gives the same mask.
    #[test]
    fn visible_lanes_never_drop_a_visible_value() {
        use crate::simd::{LANES, Portable};
        let mut rng = fastrand::Rng::with_seed(3);
        for name in PRESET_NAMES {
            for step in [0.1, 0.5, 2.0] {
                let tf = TransferFunction::preset(name, SampleType::I16).unwrap();
                let lut = TfLut::new(&tf, step);
                let (lo, hi) = tf.value_span();
                for _ in 0..500 {
                    let v: [f32; LANES] = std::array::from_fn(|_| {
                        // Mostly inside the span, near its points, some outside.
                        let p = tf.points[rng.usize(..tf.points.len())].value;
                        match rng.u8(..4) {
                            0 => lo - 10.0 + rng.f32() * (hi - lo + 20.0),
                            1 => p + (rng.f32() - 0.5) * 0.01,
                            2 => p,
                            _ => lo + rng.f32() * (hi - lo),
                        }
                    });
                    let (x, mask) = lut.visible_lanes(Portable, &v);
                    for l in 0..LANES {
                        assert_eq!(lut.lookup_at(x[l], v[l]), lut.lookup(v[l]));
                        if mask & (1 << l) == 0 {
                            assert_eq!(lut.lookup(v[l]).w, 0.0, "{name} at {}", v[l]);
                        }
                    }
                    #[cfg(target_arch = "x86_64")]
                    if let Some(avx2) = crate::simd::Avx2::detect() {
                        assert_eq!(lut.visible_lanes(avx2, &v).1, mask);
                    }
                }
            }
        }
    }

    /// A range `constant_over` accepts looks up one entry throughout
    /// (checked at its ends and many values between, near the TF's points
    /// above all), and ranges inside one step of a step TF are accepted.
    #[test]
    fn constant_ranges_look_up_one_entry() {
        let mut rng = fastrand::Rng::with_seed(8);
        let (mut accepted, mut refused) = (0, 0);
        for name in PRESET_NAMES {
            for sample_type in [SampleType::U8, SampleType::I16, SampleType::F32] {
                let tf = TransferFunction::preset(name, sample_type).unwrap();
                let lut = TfLut::new(&tf, 0.5);
                let (lo, hi) = tf.value_span();
                let near = |rng: &mut fastrand::Rng| {
                    let p = tf.points[rng.usize(..tf.points.len())].value;
                    p + (rng.f32() - 0.5) * (hi - lo) * 0.05
                };
                for _ in 0..2000 {
                    let (a, b) = match rng.u8(..3) {
                        0 => (near(&mut rng), near(&mut rng)),
                        1 => {
                            let a = near(&mut rng);
                            (a, a + rng.f32() * (hi - lo) * 1e-3)
                        }
                        _ => (
                            lo - 10.0 + rng.f32() * (hi - lo + 20.0),
                            lo - 10.0 + rng.f32() * (hi - lo + 20.0),
                        ),
                    };
                    let (a, b) = (a.min(b), a.max(b));
                    if !lut.constant_over(a, b) {
                        refused += 1;
                        continue;
                    }
                    accepted += 1;
                    let e = lut.lookup(a);
                    for k in 0..=64 {
                        let v = a + (b - a) * k as f32 / 64.0;
                        assert_eq!(lut.lookup(v.min(b)), e, "{name}: [{a}, {b}] at {v}");
                    }
                    for p in &tf.points {
                        for v in [p.value, p.value.next_down(), p.value.next_up()] {
                            if (a..=b).contains(&v) {
                                assert_eq!(lut.lookup(v), e, "{name}: [{a}, {b}] at {v}");
                            }
                        }
                    }
                }
            }
        }
        assert!(accepted > 1000 && refused > 1000, "{accepted} / {refused}");
        // The benchmark's shapes of 92..=95 are red, those of 96..=100 blue.
        let shapes = TfLut::new(
            &TransferFunction::preset("shapes", SampleType::U8).unwrap(),
            0.2,
        );
        assert!(shapes.constant_over(92.0, 95.0) && shapes.constant_over(96.0, 100.0));
        assert!(!shapes.constant_over(95.0, 96.0) && !shapes.constant_over(0.0, 95.0));
    }

    #[test]
    fn presets_exist_and_validate() {
        for name in PRESET_NAMES {
            let tf = TransferFunction::preset(name, SampleType::U8).unwrap();
            tf.validate().unwrap();
        }
        assert!(TransferFunction::preset("nope", SampleType::U8).is_none());
    }

    #[test]
    fn step_evaluation_follows_the_spec() {
        let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
        assert_eq!(tf.evaluate(85.0).w, 0.0);
        assert_eq!(tf.evaluate(85.01).w, 0.02);
        // The generator's shapes of exactly 95 and 100 are red and blue.
        assert_eq!(tf.evaluate(95.0).w, 0.02);
        assert_eq!(tf.evaluate(95.01).w, 0.3);
        assert_eq!(tf.evaluate(100.0).w, 0.3);
        assert_eq!(tf.evaluate(100.01).w, 0.6);
        assert_eq!(tf.evaluate(114.99).w, 0.6);
        assert_eq!(tf.evaluate(115.0).w, 0.0);
    }

    #[test]
    fn linear_evaluation_interpolates_and_clamps() {
        let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
        assert!((tf.evaluate(127.5).w - 0.5).abs() < 1e-6);
        assert_eq!(tf.evaluate(-5.0).w, 0.0);
        assert_eq!(tf.evaluate(300.0).w, 1.0);
    }

    #[test]
    fn lut_matches_exact_evaluation_with_opacity_correction() {
        let mut rng = fastrand::Rng::with_seed(3);
        for name in ["shapes", "skull", "ramp"] {
            let tf = TransferFunction::preset(name, SampleType::U8).unwrap();
            for step in [0.1f32, 0.5, 1.0, 2.0] {
                let lut = TfLut::new(&tf, step);
                for _ in 0..2000 {
                    let v = rng.f32() * 300.0 - 20.0;
                    let e = tf.evaluate(v);
                    let a = 1.0 - (1.0 - e.w).powf(step);
                    let got = lut.lookup(v);
                    assert!(
                        (got.w - a).abs() < 2e-3,
                        "{name} step {step} v {v}: {} vs {a}",
                        got.w
                    );
                    assert!((got.x - e.x * a).abs() < 2e-3);
                }
            }
        }
    }

    #[test]
    fn visibility_agrees_with_lookup() {
        let mut rng = fastrand::Rng::with_seed(5);
        for name in ["shapes", "skull", "ramp"] {
            let tf = TransferFunction::preset(name, SampleType::U8).unwrap();
            let lut = TfLut::new(&tf, 0.5);
            for _ in 0..3000 {
                let a = rng.f32() * 280.0 - 10.0;
                let b = a + rng.f32() * 20.0;
                let any = (0..=400).any(|k| lut.lookup(a + (b - a) * k as f32 / 400.0).w > 0.0);
                if any {
                    assert!(
                        lut.any_visible(a, b),
                        "{name} [{a}, {b}] has visible values"
                    );
                }
            }
            // Values wholly below the shapes TF's first point are invisible.
        }
        let shapes = TfLut::new(
            &TransferFunction::preset("shapes", SampleType::U8).unwrap(),
            0.2,
        );
        assert!(!shapes.any_visible(0.0, 85.0));
        assert!(shapes.any_visible(0.0, 85.01));
        assert!(!shapes.any_visible(115.0, 255.0));
    }

    #[test]
    fn wide_and_odd_step_points_are_exact() {
        let p = |v: f32, a: f32| TfPoint {
            value: v,
            color: [v / 70000.0, 0.5, 0.5],
            opacity: a,
        };
        for (interp, pts) in [
            (
                Interpolation::Step,
                vec![p(1000.0, 0.2), p(1010.0, 0.9), p(60000.0, 0.0)],
            ),
            (
                Interpolation::Step,
                vec![p(10.3, 0.5), p(10.31, 0.0), p(20.0, 1.0)],
            ),
            (
                Interpolation::Linear,
                vec![p(0.0, 0.0), p(5000.5, 1.0), p(5001.0, 0.0), p(65535.0, 0.3)],
            ),
        ] {
            let tf = TransferFunction::new(interp, pts).unwrap();
            let lut = TfLut::new(&tf, 0.5);
            let mut rng = fastrand::Rng::with_seed(9);
            let (lo, hi) = tf.value_span();
            let mut probes: Vec<f32> = tf
                .points
                .iter()
                .flat_map(|p| [p.value, p.value - 0.01, p.value + 0.01])
                .collect();
            probes.extend((0..5000).map(|_| lo - 10.0 + rng.f32() * (hi - lo + 20.0)));
            for v in probes {
                let e = tf.evaluate(v);
                let a = 1.0 - (1.0 - e.w).powf(0.5);
                let got = lut.lookup(v);
                assert!(
                    (got.w - a).abs() < 2e-3,
                    "{interp:?} v {v}: {} vs {a}",
                    got.w
                );
                if got.w > 0.0 {
                    assert!(lut.any_visible(v, v), "{v} visible but not in any_visible");
                }
            }
        }
    }

    #[test]
    fn json_round_trip_and_errors() {
        let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
        assert_eq!(TransferFunction::from_json(&tf.to_json()).unwrap(), tf);
        let spec = r#"{ "interpolation": "linear",
          "points": [ { "value": 40, "color": [0.9, 0.85, 0.8], "opacity": 0.0 },
                      { "value": 80, "color": [0.9, 0.85, 0.8], "opacity": 0.8 } ] }"#;
        let tf = TransferFunction::from_json(spec).unwrap();
        assert!((tf.evaluate(60.0).w - 0.4).abs() < 1e-6);
        for bad in [
            "{",
            r#"{"points": []}"#,
            r#"{"points": [{"value": 5, "color": [1,1,1], "opacity": 2}]}"#,
            r#"{"points": [{"value": 5, "color": [1,1,1], "opacity": 1}, {"value": 1, "color": [1,1,1], "opacity": 1}]}"#,
        ] {
            assert!(TransferFunction::from_json(bad).is_err(), "{bad}");
        }
    }
}

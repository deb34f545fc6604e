//! The viewer's settings: everything the user chooses in the left panel, kept
//! between runs in eframe's storage (last directory, transfer function,
//! rendering options).
//!
//! The per-volume state (camera, histogram) is not persisted: it belongs to
//! the volume on screen.

use std::path::PathBuf;

use raycaster::integrator::RenderMode;
use raycaster::render::RendererKind;
use raycaster::transfer::TransferFunction;
use raycaster::volume::Grid;
use serde::{Deserialize, Serialize};

/// The key of the settings in eframe's storage.
pub const STORAGE_KEY: &str = "vol_app.viewer.settings";

/// The fine sampling step, in units of the smallest voxel spacing (0.2 is
/// the benchmark frame's step on unit-spaced data).
pub const FINE_STEP: f32 = 0.2;
/// The coarse sampling step, in units of the smallest voxel spacing.
pub const COARSE_STEP: f32 = 0.9;
/// Resolution factor of the preview frames rendered while the camera moves in
/// adaptive mode.
pub const PREVIEW_SCALE: f32 = 0.5;

/// The rendering modes, in menu order.
pub const MODES: [RenderMode; 4] = [
    RenderMode::Dvr,
    RenderMode::Mip,
    RenderMode::Avg,
    RenderMode::Iso,
];

/// A mode's label in the UI.
pub fn mode_label(mode: RenderMode) -> &'static str {
    match mode {
        RenderMode::Dvr => "DVR",
        RenderMode::Mip => "MIP",
        RenderMode::Avg => "X-ray",
        RenderMode::Iso => "Iso",
    }
}

/// How long the sampling step is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum StepChoice {
    /// Always [`FINE_STEP`].
    Fine,
    /// Always [`COARSE_STEP`].
    Coarse,
    /// Coarse (and at reduced resolution) while the camera moves, fine when
    /// it stops.
    #[default]
    Adaptive,
}

impl StepChoice {
    /// The step in world units for `grid`, and whether the frame is a preview.
    pub fn step(self, grid: &Grid, interacting: bool) -> (f32, bool) {
        let unit = grid.spacing.min_element();
        match self {
            StepChoice::Fine => (FINE_STEP * unit, false),
            StepChoice::Coarse => (COARSE_STEP * unit, false),
            StepChoice::Adaptive if interacting => (COARSE_STEP * unit, true),
            StepChoice::Adaptive => (FINE_STEP * unit, false),
        }
    }
}

/// The size of the rendered image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ResolutionChoice {
    /// One ray per physical pixel of the canvas.
    #[default]
    Canvas,
    /// A fixed square image ([`Settings::fixed_size`]), scaled to fit.
    Fixed,
}

/// Everything the user chooses, persisted between runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// Where the last file was opened from or saved to.
    pub last_dir: Option<PathBuf>,
    /// The transfer function being edited.
    pub tf: TransferFunction,
    /// The preset `tf` came from, while it is unmodified.
    pub tf_preset: Option<String>,
    /// Rendering mode.
    pub mode: RenderMode,
    /// Iso value (data units) for [`RenderMode::Iso`].
    pub iso_value: f32,
    /// Phong shading.
    pub shading: bool,
    /// Renderer.
    pub renderer: RendererKind,
    /// Render threads (clamped to the machine's cores).
    pub threads: usize,
    /// Early ray termination.
    pub ert: bool,
    /// Empty-space skipping.
    pub ess: bool,
    /// Sampling step.
    pub step: StepChoice,
    /// Image size.
    pub resolution: ResolutionChoice,
    /// Side of the fixed-size image.
    pub fixed_size: u32,
    /// Read files into RAM instead of memory-mapping them.
    pub load_in_ram: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            last_dir: None,
            tf: preset_or_ramp(crate::demo::DEMO_TF),
            tf_preset: Some(crate::demo::DEMO_TF.to_string()),
            mode: RenderMode::Dvr,
            iso_value: 100.0,
            shading: true,
            // The viewer's default so far; the library's (and `vol_app
            // render`'s) is the object renderer.
            renderer: RendererKind::Tiles,
            threads: max_threads(),
            ert: true,
            ess: true,
            step: StepChoice::Adaptive,
            resolution: ResolutionChoice::Canvas,
            fixed_size: 700,
            load_in_ram: false,
        }
    }
}

/// The machine's core count.
pub fn max_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

fn preset_or_ramp(name: &str) -> TransferFunction {
    use raycaster::sample::SampleType;
    TransferFunction::preset(name, SampleType::U8)
        .or_else(|| TransferFunction::preset("ramp", SampleType::U8))
        .unwrap_or(TransferFunction {
            interpolation: Default::default(),
            points: vec![raycaster::transfer::TfPoint {
                value: 0.0,
                color: [1.0; 3],
                opacity: 0.0,
            }],
        })
}

impl Settings {
    /// The settings stored by the last run, or the defaults; values that no
    /// longer make sense (an invalid TF, more threads than cores) are repaired.
    pub fn load(storage: Option<&dyn eframe::Storage>) -> Self {
        let stored: Option<Settings> = storage.and_then(|s| eframe::get_value(s, STORAGE_KEY));
        stored.map(Settings::repaired).unwrap_or_default()
    }

    /// Writes the settings to eframe's storage.
    pub fn save(&self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, STORAGE_KEY, self);
    }

    fn repaired(mut self) -> Self {
        let defaults = Settings::default();
        if TransferFunction::from_json(&self.tf.to_json()).is_err() {
            self.tf = defaults.tf;
            self.tf_preset = defaults.tf_preset;
        }
        self.threads = self.threads.clamp(1, max_threads());
        if !self.iso_value.is_finite() {
            self.iso_value = defaults.iso_value;
        }
        self.fixed_size = self.fixed_size.clamp(64, 4096);
        if self.last_dir.as_ref().is_some_and(|d| !d.is_dir()) {
            self.last_dir = None;
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{UVec3, Vec3};

    #[test]
    fn settings_round_trip_through_json() {
        let mut s = Settings {
            mode: RenderMode::Iso,
            ert: false,
            step: StepChoice::Coarse,
            ..Settings::default()
        };
        s.tf.points[0].opacity = 0.5;
        s.tf_preset = None;
        let text = serde_json::to_string(&s).unwrap();
        let back: Settings = serde_json::from_str(&text).unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn missing_and_bad_fields_fall_back_to_defaults() {
        let back: Settings = serde_json::from_str(r#"{"mode": "mip"}"#).unwrap();
        assert_eq!(back.mode, RenderMode::Mip);
        assert_eq!(back.tf, Settings::default().tf);
        let bad = Settings {
            threads: 10_000,
            fixed_size: 1,
            tf: TransferFunction {
                interpolation: Default::default(),
                points: vec![],
            },
            ..Settings::default()
        }
        .repaired();
        assert_eq!(bad.threads, max_threads());
        assert_eq!(bad.fixed_size, 64);
        assert_eq!(bad.tf, Settings::default().tf);
    }

    #[test]
    fn adaptive_step_is_coarse_only_while_interacting() {
        let grid = Grid::new(UVec3::splat(8), Vec3::new(2.0, 0.5, 1.0));
        assert_eq!(StepChoice::Fine.step(&grid, true), (0.1, false));
        assert_eq!(StepChoice::Coarse.step(&grid, false), (0.45, false));
        assert_eq!(StepChoice::Adaptive.step(&grid, true), (0.45, true));
        assert_eq!(StepChoice::Adaptive.step(&grid, false), (0.1, false));
    }
}

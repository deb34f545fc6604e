//! The viewer's settings: everything the user chooses in the left panel, kept
//! between runs in eframe's storage (last directory, transfer function,
//! rendering options).
//!
//! The per-volume state (camera, histogram) is not persisted: it belongs to
//! the volume on screen.

use std::path::PathBuf;

use glam::Vec3;
use raycaster::integrator::RenderMode;
use raycaster::render::RendererKind;
use raycaster::transfer::TransferFunction;
use raycaster::volume::Grid;
use serde::{Deserialize, Serialize};

/// The key of the settings in eframe's storage.
pub const STORAGE_KEY: &str = "vol_app.viewer.settings";

/// The default sampling step at full quality, in units of the smallest
/// voxel spacing: half of it, as `vol_app render` and the library default.
pub const DEFAULT_STEP_FACTOR: f32 = 0.5;
/// The range of the step slider, in units of the smallest voxel spacing.
pub const STEP_FACTOR_RANGE: std::ops::RangeInclusive<f32> = 0.05..=4.0;

/// The rendering modes, in menu order. Metaballs are rendered from balls
/// made of the volume, on a thread of their own
/// ([`metaball_link`](super::metaball_link)).
pub const MODES: [RenderMode; 6] = [
    RenderMode::Dvr,
    RenderMode::Mip,
    RenderMode::Minip,
    RenderMode::Avg,
    RenderMode::Iso,
    RenderMode::Metaballs,
];

/// A mode's label in the UI.
pub fn mode_label(mode: RenderMode) -> &'static str {
    match mode {
        RenderMode::Dvr => "DVR",
        RenderMode::Mip => "MIP",
        RenderMode::Minip => "MinIP",
        RenderMode::Avg => "X-ray",
        RenderMode::Iso => "Iso",
        RenderMode::Metaballs => "Metaballs",
    }
}

/// The most directional lights the panel offers.
pub const MAX_LIGHTS: usize = 4;

/// A directional light of [`RenderMode::Iso`], as two angles in degrees.
///
/// The convention is the orbit camera's (see
/// [`camera_control`](super::camera_control)): the direction towards the
/// light is `(cos el·sin az, sin el, cos el·cos az)`, i.e. the elevation is
/// the angle from the xz-plane towards +y, and the azimuth turns about +y
/// from +z towards +x. So azimuth 0, elevation 0 is the +z side (where
/// `vol_app render`'s default camera looks from), azimuth 90 is +x,
/// elevation 90 is straight above (+y), and a light at the camera's own
/// angles shines from where the camera stands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LightAngles {
    /// Azimuth in degrees, −180..180.
    pub azimuth: f32,
    /// Elevation in degrees, −90..90.
    pub elevation: f32,
}

impl Default for LightAngles {
    /// A new light: above, to the right of the camera's home view.
    fn default() -> Self {
        LightAngles {
            azimuth: 60.0,
            elevation: 45.0,
        }
    }
}

impl LightAngles {
    /// The unit world direction towards the light (see the type's docs).
    pub fn direction(self) -> Vec3 {
        let (az, el) = (self.azimuth.to_radians(), self.elevation.to_radians());
        Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos())
    }

    /// Finite angles within the sliders' ranges.
    fn repaired(self) -> Self {
        let fix = |v: f32, max: f32, default: f32| {
            if v.is_finite() {
                v.clamp(-max, max)
            } else {
                default
            }
        };
        let d = LightAngles::default();
        LightAngles {
            azimuth: fix(self.azimuth, 180.0, d.azimuth),
            elevation: fix(self.elevation, 90.0, d.elevation),
        }
    }
}

/// The most clip planes the panel offers.
pub const MAX_VIEWER_PLANES: usize = 3;

/// A clip plane of the viewer: samples on the side its normal points to are
/// removed. The normal is given by two angles (as a light's direction), the
/// offset as a fraction of half the volume's diagonal from its centre
/// (0: through the centre, ±1: off the volume).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct PlaneSetting {
    /// Direction of the normal.
    pub normal: LightAngles,
    /// Offset along the normal, −1..1.
    pub offset: f32,
}

/// Clipping and per-sample options of the viewer (SPEC §8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ClipSettings {
    /// Crop box in coordinates normalised to the volume's box: `min` x, y,
    /// z then `max` x, y, z, each 0..1.
    pub crop: [f32; 6],
    /// Clip planes.
    pub planes: Vec<PlaneSetting>,
    /// Gradient opacity on.
    pub gradient_opacity: bool,
    /// Gradient magnitude (data units per world unit) at and below which
    /// gradient opacity hides a sample.
    pub g0: f32,
    /// Gradient magnitude from which a sample keeps the TF's opacity.
    pub g1: f32,
    /// Jittered samples (in every frame: a view renders the same image at
    /// every stage of the progressive refinement).
    pub jitter: bool,
}

impl Default for ClipSettings {
    fn default() -> Self {
        ClipSettings {
            crop: [0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            planes: Vec::new(),
            gradient_opacity: false,
            g0: 0.0,
            g1: 10.0,
            jitter: true,
        }
    }
}

impl ClipSettings {
    /// The library's clip for a volume with world box `bounds`.
    pub fn clip(&self, bounds: &raycaster::geometry::Aabb) -> raycaster::clip::Clip {
        let size = bounds.max - bounds.min;
        let at = |u: [f32; 3]| bounds.min + Vec3::from_array(u) * size;
        let lo = at([self.crop[0], self.crop[1], self.crop[2]]);
        let hi = at([self.crop[3], self.crop[4], self.crop[5]]);
        let full = self.crop == ClipSettings::default().crop;
        let half_diagonal = 0.5 * size.length();
        raycaster::clip::Clip {
            clip_box: (!full).then_some((lo.min(hi), lo.max(hi))),
            planes: self
                .planes
                .iter()
                .map(|p| {
                    let n = p.normal.direction();
                    raycaster::clip::ClipPlane {
                        normal: n,
                        offset: n.dot(bounds.center()) + p.offset * half_diagonal,
                    }
                })
                .collect(),
        }
    }

    /// The library's gradient opacity (off, or with g0 < g1).
    pub fn gradient_opacity(&self) -> Option<raycaster::integrator::GradientOpacity> {
        (self.gradient_opacity && self.g0 < self.g1).then_some(
            raycaster::integrator::GradientOpacity {
                g0: self.g0,
                g1: self.g1,
            },
        )
    }

    fn repaired(mut self) -> Self {
        for (i, c) in self.crop.iter_mut().enumerate() {
            *c = if c.is_finite() {
                c.clamp(0.0, 1.0)
            } else {
                (i >= 3) as u8 as f32
            };
        }
        self.planes.truncate(MAX_VIEWER_PLANES);
        for p in &mut self.planes {
            p.normal = p.normal.repaired();
            p.offset = if p.offset.is_finite() {
                p.offset.clamp(-1.0, 1.0)
            } else {
                0.0
            };
        }
        if !(self.g0.is_finite() && self.g1.is_finite() && self.g0 >= 0.0 && self.g0 < self.g1) {
            let d = ClipSettings::default();
            (self.g0, self.g1) = (d.g0, d.g1);
        }
        self
    }
}

/// The Metaballs mode's settings, relative to the volume on screen (so they
/// carry over from one volume to the next).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MetaballSettings {
    /// A voxel gives a ball when its value exceeds this fraction of the way
    /// up the volume's value range (the seed's 0.3).
    pub threshold: f32,
    /// Every `stride`-th voxel per axis.
    pub stride: u32,
    /// Ball radius as a multiple of the default (1.5 × stride × the largest
    /// spacing, so that neighbours overlap).
    pub radius_scale: f32,
    /// The kernel.
    pub kernel: raycaster::metaballs::Kernel,
    /// The surface is where the summed field equals this.
    pub field_threshold: f32,
}

impl Default for MetaballSettings {
    fn default() -> Self {
        MetaballSettings {
            threshold: 0.3,
            stride: 2,
            radius_scale: 1.0,
            kernel: raycaster::metaballs::Kernel::Wyvill,
            field_threshold: 0.5,
        }
    }
}

/// The ranges of the Metaballs sliders.
pub const BALL_STRIDE_RANGE: std::ops::RangeInclusive<u32> = 1..=16;
/// See [`BALL_STRIDE_RANGE`].
pub const BALL_RADIUS_SCALE_RANGE: std::ops::RangeInclusive<f32> = 0.25..=4.0;
/// See [`BALL_STRIDE_RANGE`].
pub const FIELD_THRESHOLD_RANGE: std::ops::RangeInclusive<f32> = 0.05..=0.95;

impl MetaballSettings {
    /// The parameters for a volume on `grid` whose values span `range`.
    pub fn params(&self, grid: &Grid, range: (f32, f32)) -> super::metaball_link::MetaballParams {
        let (lo, hi) = range;
        super::metaball_link::MetaballParams {
            threshold: lo + self.threshold * (hi - lo),
            stride: self.stride,
            radius: self.radius_scale
                * raycaster::metaballs::Extraction::default_radius(grid.spacing, self.stride),
            kernel: self.kernel,
            field_threshold: self.field_threshold,
            max_balls: super::metaball_link::MAX_BALLS,
        }
    }

    fn repaired(self) -> Self {
        let d = MetaballSettings::default();
        let fix = |v: f32, r: std::ops::RangeInclusive<f32>, default: f32| {
            if v.is_finite() {
                v.clamp(*r.start(), *r.end())
            } else {
                default
            }
        };
        MetaballSettings {
            threshold: fix(self.threshold, 0.0..=1.0, d.threshold),
            stride: self
                .stride
                .clamp(*BALL_STRIDE_RANGE.start(), *BALL_STRIDE_RANGE.end()),
            radius_scale: fix(self.radius_scale, BALL_RADIUS_SCALE_RANGE, d.radius_scale),
            kernel: self.kernel,
            field_threshold: fix(
                self.field_threshold,
                FIELD_THRESHOLD_RANGE,
                d.field_threshold,
            ),
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
    /// Directional lights of [`RenderMode::Iso`]; empty: one headlight.
    pub lights: Vec<LightAngles>,
    /// Shadow rays towards each light in [`RenderMode::Iso`].
    pub shadows: bool,
    /// The share of each hit's colour seen in the mirror direction in
    /// [`RenderMode::Iso`] (`--reflection`; 0 = off).
    pub reflection: f32,
    /// How [`RenderMode::Iso`] finds its normals (`--normals`).
    pub iso_normals: raycaster::integrator::IsoNormals,
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
    /// Sampling step of full-quality frames, in units of the smallest voxel
    /// spacing.
    pub step_factor: f32,
    /// Progressive refinement: fast reduced previews while something
    /// changes, refined to full quality once still (see
    /// [`progressive`](super::progressive)); off renders every frame at full
    /// quality.
    pub progressive: bool,
    /// Image size.
    pub resolution: ResolutionChoice,
    /// Side of the fixed-size image.
    pub fixed_size: u32,
    /// Read files into RAM instead of memory-mapping them.
    pub load_in_ram: bool,
    /// A sequence's playback starts over after its last frame.
    pub play_loop: bool,
    /// Playback speed of a sequence, in frames per second.
    pub play_fps: f32,
    /// Crop box, clip planes, gradient opacity, jitter.
    pub clip: ClipSettings,
    /// The Metaballs mode.
    pub metaballs: MetaballSettings,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            last_dir: None,
            tf: preset_or_ramp(crate::demo::DEMO_TF),
            tf_preset: Some(crate::demo::DEMO_TF.to_string()),
            mode: RenderMode::Dvr,
            iso_value: 100.0,
            lights: Vec::new(),
            shadows: false,
            reflection: 0.0,
            iso_normals: Default::default(),
            shading: true,
            // The viewer's default so far; the library's (and `vol_app
            // render`'s) is the object renderer.
            renderer: RendererKind::Tiles,
            threads: max_threads(),
            ert: true,
            ess: true,
            step_factor: DEFAULT_STEP_FACTOR,
            progressive: true,
            resolution: ResolutionChoice::Canvas,
            fixed_size: 700,
            load_in_ram: false,
            play_loop: true,
            play_fps: 10.0,
            clip: ClipSettings::default(),
            metaballs: MetaballSettings::default(),
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
    /// The sampling step of full-quality frames of `grid`, in world units.
    pub fn full_step(&self, grid: &Grid) -> f32 {
        self.step_factor * grid.spacing.min_element()
    }

    /// The world directions of [`Settings::lights`], as
    /// [`RenderOptions::lights`](raycaster::render::RenderOptions::lights)
    /// wants them (empty: the headlight).
    pub fn light_directions(&self) -> Vec<Vec3> {
        self.lights.iter().map(|l| l.direction()).collect()
    }

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
        self.reflection = if self.reflection.is_finite() {
            self.reflection.clamp(0.0, 1.0)
        } else {
            defaults.reflection
        };
        self.lights.truncate(MAX_LIGHTS);
        for l in &mut self.lights {
            *l = l.repaired();
        }
        self.fixed_size = self.fixed_size.clamp(64, 4096);
        self.step_factor = if self.step_factor.is_finite() {
            self.step_factor
                .clamp(*STEP_FACTOR_RANGE.start(), *STEP_FACTOR_RANGE.end())
        } else {
            defaults.step_factor
        };
        let fps = super::timeline::FPS_RANGE;
        self.play_fps = if self.play_fps.is_finite() {
            self.play_fps.clamp(*fps.start(), *fps.end())
        } else {
            defaults.play_fps
        };
        self.clip = self.clip.repaired();
        self.metaballs = self.metaballs.repaired();
        if self.last_dir.as_ref().is_some_and(|d| !d.is_dir()) {
            self.last_dir = None;
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    #[test]
    fn settings_round_trip_through_json() {
        let mut s = Settings {
            mode: RenderMode::Iso,
            ert: false,
            step_factor: 0.25,
            progressive: false,
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
            step_factor: f32::NAN,
            play_fps: f32::INFINITY,
            tf: TransferFunction {
                interpolation: Default::default(),
                points: vec![],
            },
            ..Settings::default()
        }
        .repaired();
        assert_eq!(bad.threads, max_threads());
        assert_eq!(bad.fixed_size, 64);
        assert_eq!(bad.step_factor, DEFAULT_STEP_FACTOR);
        assert_eq!(bad.play_fps, 10.0);
        let far = Settings {
            step_factor: 100.0,
            ..Settings::default()
        }
        .repaired();
        assert_eq!(far.step_factor, *STEP_FACTOR_RANGE.end());
        assert_eq!(bad.tf, Settings::default().tf);
    }

    #[test]
    fn the_default_step_is_half_the_smallest_spacing_like_vol_app_render() {
        let grid = Grid::new(UVec3::splat(8), Vec3::new(2.0, 0.5, 1.0));
        let s = Settings::default();
        assert!(s.progressive);
        assert_eq!(s.full_step(&grid), 0.25);
        // The library's default step (what `vol_app render` uses without
        // --step) is the same.
        let library = raycaster::render::RenderOptions::default().step_for(&grid);
        assert_eq!(s.full_step(&grid), library);
        let fine = Settings {
            step_factor: 0.2,
            ..s
        };
        assert_eq!(fine.full_step(&grid), 0.1);
    }

    #[test]
    fn settings_of_an_older_version_keep_what_still_applies() {
        // An older viewer stored a step choice by name.
        let back: Settings = serde_json::from_str(r#"{"step": "adaptive", "ert": false}"#).unwrap();
        assert!(!back.ert);
        assert_eq!(back.step_factor, DEFAULT_STEP_FACTOR);
        assert!(back.progressive);
    }

    #[test]
    fn light_angles_turn_into_directions_like_the_orbit_camera() {
        let dir = |azimuth, elevation| LightAngles { azimuth, elevation }.direction();
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
        assert!(close(dir(0.0, 90.0), Vec3::Y));
        assert!(close(dir(123.0, -90.0), -Vec3::Y));
        assert!(close(dir(0.0, 0.0), Vec3::Z));
        assert!(close(dir(90.0, 0.0), Vec3::X));
        assert!(close(dir(-90.0, 0.0), -Vec3::X));
        assert!(close(dir(180.0, 0.0), -Vec3::Z));
        let h = 0.5f32.sqrt();
        assert!(close(dir(90.0, 45.0), Vec3::new(h, h, 0.0)));
        for (az, el) in [(37.0, 12.0), (-150.0, -60.0)] {
            assert!((dir(az, el).length() - 1.0).abs() < 1e-6);
        }
        // A light at the camera's angles shines from where the camera is.
        let mut cam = super::super::camera_control::OrbitCamera::framing(
            &Grid::new(UVec3::splat(8), Vec3::ONE).bounds(),
            1.0,
        );
        cam.set_angles(-70.0, 30.0);
        let c = cam.camera(64, 64);
        let towards_camera = (c.position - c.target).normalize();
        assert!(close(dir(-70.0, 30.0), towards_camera));
    }

    #[test]
    fn lights_and_shadows_default_to_a_headlight_and_are_repaired() {
        // Settings saved before lights existed load with the headlight.
        let old: Settings = serde_json::from_str(r#"{"mode": "iso", "iso_value": 50}"#).unwrap();
        assert!(old.lights.is_empty() && !old.shadows);
        assert!(old.light_directions().is_empty());
        let s = Settings {
            lights: vec![
                LightAngles::default(),
                LightAngles {
                    azimuth: -30.0,
                    elevation: 10.0,
                },
            ],
            shadows: true,
            ..Settings::default()
        };
        let back: Settings = serde_json::from_str(&serde_json::to_string(&s).unwrap()).unwrap();
        assert_eq!(back, s);
        let bad = LightAngles {
            azimuth: f32::NAN,
            elevation: 400.0,
        };
        let r = Settings {
            lights: vec![bad; MAX_LIGHTS + 2],
            reflection: 3.0,
            ..s
        }
        .repaired();
        assert_eq!(r.reflection, 1.0);
        assert_eq!(
            Settings {
                reflection: f32::NAN,
                ..Settings::default()
            }
            .repaired()
            .reflection,
            0.0
        );
        assert_eq!(r.lights.len(), MAX_LIGHTS);
        assert_eq!(r.lights[0].azimuth, LightAngles::default().azimuth);
        assert_eq!(r.lights[0].elevation, 90.0);
    }
}

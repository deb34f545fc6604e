//! Turntable movies: N frames of a camera orbiting the volume's centre
//! about a world axis, written as numbered PNGs into a directory or as one
//! animated GIF. `vol_app render --turntable N` and the viewer's "Export
//! turntable…" both run [`render`].
//!
//! Frame `k` is the start camera turned rigidly by `2π·k/N` about the axis
//! through the centre (right-handed: counter-clockwise seen from the axis's
//! positive end): position, look-at point and up vector all turn, so the
//! distance to the centre and the elevation above the axis's plane stay,
//! and frame 0 is the start camera itself.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use glam::{Quat, Vec3};
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, RgbaImage};
use raycaster::camera::Camera;
use raycaster::prelude::*;

/// The world axis a turntable turns about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TurnAxis {
    /// About +x.
    X,
    /// About +y (the default camera's up: the classic turntable).
    Y,
    /// About +z.
    Z,
}

impl TurnAxis {
    /// The unit vector of the axis.
    pub fn vector(self) -> Vec3 {
        match self {
            TurnAxis::X => Vec3::X,
            TurnAxis::Y => Vec3::Y,
            TurnAxis::Z => Vec3::Z,
        }
    }
}

/// `camera` turned by `angle` radians about the line through `center`
/// along `axis` (right-handed).
pub fn orbit(camera: &Camera, center: Vec3, axis: TurnAxis, angle: f32) -> Camera {
    let q = Quat::from_axis_angle(axis.vector(), angle);
    Camera {
        position: center + q * (camera.position - center),
        target: center + q * (camera.target - center),
        up: q * camera.up,
        ..*camera
    }
}

/// The camera of frame `k` of `frames`.
pub fn frame_camera(camera: &Camera, center: Vec3, axis: TurnAxis, k: u32, frames: u32) -> Camera {
    let angle = std::f64::consts::TAU * f64::from(k) / f64::from(frames.max(1));
    orbit(camera, center, axis, angle as f32)
}

/// Where the frames go.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// `frame_0000.png`, `frame_0001.png`, … in this directory (made when
    /// missing).
    Frames(PathBuf),
    /// One animated GIF, looping, `1/fps` s a frame (GIF counts delays in
    /// hundredths of a second, so the delay is rounded down to one).
    Gif {
        /// The file; it appears only when complete.
        path: PathBuf,
        /// Frames per second.
        fps: f32,
    },
}

impl Output {
    /// The output that `path` names: a `.gif` file, or a directory (one
    /// that exists, or a path ending in `/`). Anything else is an error
    /// naming `--out`.
    pub fn from_path(path: &Path, fps: f32) -> Result<Output, String> {
        let is_gif = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("gif"));
        let text = path.to_string_lossy();
        let is_dir =
            path.is_dir() || text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR);
        if is_gif && !path.is_dir() {
            if !(fps.is_finite() && (0.1..=100.0).contains(&fps)) {
                return Err(format!("--fps {fps} must be in 0.1..=100"));
            }
            Ok(Output::Gif {
                path: path.to_path_buf(),
                fps,
            })
        } else if is_dir {
            Ok(Output::Frames(path.to_path_buf()))
        } else {
            Err(format!(
                "--out {text}: a turntable is written to a directory (DIR/) or an animated GIF (FILE.gif)"
            ))
        }
    }
}

/// What to render.
pub struct Turntable<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Frame 0's camera.
    pub camera: Camera,
    /// The point the camera orbits (the volume's centre).
    pub center: Vec3,
    /// The axis.
    pub axis: TurnAxis,
    /// Frames in a full turn (at least 1).
    pub frames: u32,
    /// Transfer function.
    pub tf: &'a TransferFunction,
    /// Render options.
    pub options: &'a RenderOptions,
}

/// How a turntable ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// All frames written.
    Done,
    /// `cancel` was set; a GIF is not written, frames already in a
    /// directory stay.
    Cancelled,
}

/// Renders the turntable with `renderer` into `out`, calling `progress`
/// with (frames done, frames) after each frame and stopping between
/// frames once `cancel` is set.
pub fn render(
    job: &Turntable,
    renderer: &mut dyn Renderer,
    out: &Output,
    cancel: &AtomicBool,
    mut progress: impl FnMut(u32, u32),
) -> Result<Outcome, String> {
    if job.frames == 0 {
        return Err("--turntable 0: a turntable needs at least 1 frame".into());
    }
    let mut frame = |k: u32| {
        let camera = frame_camera(&job.camera, job.center, job.axis, k, job.frames);
        renderer
            .render(job.scene, &camera, job.tf, job.options)
            .map_err(|e| e.to_string())
    };
    match out {
        Output::Frames(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            for k in 0..job.frames {
                if cancel.load(Ordering::Relaxed) {
                    return Ok(Outcome::Cancelled);
                }
                frame(k)?
                    .save_png(&dir.join(frame_name(k)))
                    .map_err(|e| e.to_string())?;
                progress(k + 1, job.frames);
            }
            Ok(Outcome::Done)
        }
        Output::Gif { path, fps } => {
            // 1000/fps ms as a ratio, fps in thousandths.
            let delay =
                Delay::from_numer_denom_ms(1_000_000, (fps * 1000.0).round().max(1.0) as u32);
            // Render inside the atomic write, so a failed or cancelled
            // export leaves no partial file; errors travel as io errors and
            // come back as their message.
            let mut cancelled = false;
            let written = raycaster::format::atomic::write_atomically(path, |w| {
                gif_frames(w, delay, job.frames, &mut frame, cancel, &mut progress)
                    .map(|c| cancelled = c)
            });
            match written {
                Ok(()) => Ok(Outcome::Done),
                Err(_) if cancelled || cancel.load(Ordering::Relaxed) => Ok(Outcome::Cancelled),
                Err(e) => Err(e.to_string()),
            }
        }
    }
}

/// The file name of frame `k` in a directory of frames.
pub fn frame_name(k: u32) -> String {
    format!("frame_{k:04}.png")
}

/// Encodes the frames into `w`; returns an error when cancelled (so that
/// the atomic write drops the temporary file).
fn gif_frames(
    w: &mut impl Write,
    delay: Delay,
    frames: u32,
    frame: &mut impl FnMut(u32) -> Result<Frame, String>,
    cancel: &AtomicBool,
    progress: &mut impl FnMut(u32, u32),
) -> std::io::Result<bool> {
    // Speed 10 of 1..30: NeuQuant on every 10th pixel, a good palette per
    // frame at a fraction of speed 1's time.
    let mut encoder = GifEncoder::new_with_speed(w, 10);
    encoder
        .set_repeat(Repeat::Infinite)
        .map_err(std::io::Error::other)?;
    for k in 0..frames {
        if cancel.load(Ordering::Relaxed) {
            return Err(std::io::Error::other("cancelled"));
        }
        let f = frame(k).map_err(std::io::Error::other)?;
        let rgba: Vec<u8> = f
            .rgb
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect();
        let buffer = RgbaImage::from_raw(f.width, f.height, rgba)
            .ok_or_else(|| std::io::Error::other("frame buffer size mismatch"))?;
        encoder
            .encode_frame(image::Frame::from_parts(buffer, 0, 0, delay))
            .map_err(std::io::Error::other)?;
        progress(k + 1, frames);
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_turn_about_z_maps_x_to_y() {
        let c = Camera::look_at(Vec3::new(11.0, 1.0, 5.0), Vec3::new(1.0, 1.0, 5.0), 8, 8);
        let t = orbit(
            &c,
            Vec3::new(1.0, 1.0, 0.0),
            TurnAxis::Z,
            std::f32::consts::FRAC_PI_2,
        );
        assert!(t.position.abs_diff_eq(Vec3::new(1.0, 11.0, 5.0), 1e-5));
        assert!(t.target.abs_diff_eq(Vec3::new(1.0, 1.0, 5.0), 1e-5));
        assert!(t.up.abs_diff_eq(Vec3::new(-1.0, 0.0, 0.0), 1e-6));
        let f = frame_camera(&c, Vec3::ZERO, TurnAxis::Y, 0, 36);
        assert_eq!(f.position, c.position);
    }

    #[test]
    fn outputs_are_a_directory_or_a_gif() {
        assert!(matches!(
            Output::from_path(Path::new("movie.GIF"), 25.0),
            Ok(Output::Gif { .. })
        ));
        assert!(matches!(
            Output::from_path(Path::new("frames/"), 25.0),
            Ok(Output::Frames(_))
        ));
        let e = Output::from_path(Path::new("movie.png"), 25.0).unwrap_err();
        assert!(e.starts_with("--out movie.png"), "{e}");
        let e = Output::from_path(Path::new("a.gif"), 0.0).unwrap_err();
        assert!(e.starts_with("--fps"), "{e}");
    }
}

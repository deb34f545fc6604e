//! A rendered frame and its statistics.

use std::path::Path;
use std::time::Duration;

use crate::error::{Error, Result};

/// Counters of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameStats {
    /// Rays cast (pixels inside the volume's screen rectangle).
    pub rays: u64,
    /// Rays that met the volume's box.
    pub rays_in_volume: u64,
    /// Rays that ended with some opacity (in iso mode: hit the surface).
    pub covered: u64,
    /// Samples taken along rays (interpolations at `t_k`; gradient and iso
    /// refinement lookups are not counted).
    pub samples: u64,
    /// Wall-clock time of the frame.
    pub time: Duration,
}

/// An RGB8 image, row-major from the top-left pixel, and its statistics.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3·width·height` bytes.
    pub rgb: Vec<u8>,
    /// Counters.
    pub stats: FrameStats,
}

impl Frame {
    /// The RGB of pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Writes the frame as an RGB8 PNG.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        image::save_buffer_with_format(
            path,
            &self.rgb,
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io(path, io),
            other => Error::Image {
                path: path.to_path_buf(),
                message: other.to_string(),
            },
        })
    }
}

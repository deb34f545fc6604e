//! [`Film`]: the image a frame is assembled on, over its background.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{Vec3, Vec4};
use parking_lot::Mutex;

use crate::camera::PixelRect;

/// An RGB8 image being filled tile by tile; pixels no ray touches keep the
/// background.
#[derive(Debug)]
pub struct Film {
    width: u32,
    background: Vec3,
    background_rgb: [u8; 3],
    /// The pixels, written by the render threads tile by tile as each
    /// finishes one (see [`Film::put_tile`]).
    rgb: Mutex<Vec<u8>>,
    /// Rays that met the volume, and of those the ones that ended with
    /// some opacity, added tile by tile.
    counts: [AtomicU64; 2],
}

/// Per-tile counts of rays that met the volume and that ended with some
/// opacity (for iso, hit the surface), for [`Film::add_counts`].
#[derive(Debug, Clone, Copy, Default)]
pub struct RayCounts {
    /// Rays that met the volume's box.
    pub entered: u64,
    /// Of those, rays that ended with opacity > 0.
    pub covered: u64,
}

impl RayCounts {
    /// Counts one ray that met the volume and ended with colour `c`.
    #[inline(always)]
    pub fn add(&mut self, c: Vec4) {
        self.entered += 1;
        self.covered += (c.w > 0.0) as u64;
    }
}

impl Film {
    /// A `width`×`height` film filled with `background` (0..1 per channel).
    pub fn new(width: u32, height: u32, background: Vec3) -> Self {
        let background_rgb = to_bytes(background);
        let n = width as usize * height as usize;
        // A black film is zeroed memory, which the allocator gets from the
        // system already zero (no pass over the pixels, which every tile
        // then writes anyway); another background is copied in.
        let rgb = if background_rgb == [0; 3] {
            vec![0; 3 * n]
        } else {
            background_rgb.repeat(n)
        };
        Film {
            width,
            background,
            background_rgb,
            rgb: Mutex::new(rgb),
            counts: Default::default(),
        }
    }

    /// Adds a tile's ray counts (once per tile: no contention per pixel).
    pub fn add_counts(&self, c: RayCounts) {
        self.counts[0].fetch_add(c.entered, Ordering::Relaxed);
        self.counts[1].fetch_add(c.covered, Ordering::Relaxed);
    }

    /// The counts added so far.
    pub fn counts(&self) -> RayCounts {
        RayCounts {
            entered: self.counts[0].load(Ordering::Relaxed),
            covered: self.counts[1].load(Ordering::Relaxed),
        }
    }

    /// The background as bytes.
    pub fn background_rgb(&self) -> [u8; 3] {
        self.background_rgb
    }

    /// The bytes of a ray's premultiplied colour `c` composited over the
    /// background: `rgb = C + (1 − A)·background`.
    #[inline]
    pub fn composite(&self, c: Vec4) -> [u8; 3] {
        // A ray that gathered nothing (most rays of a sparse frame) shows
        // the background, whose bytes are known.
        if c == Vec4::ZERO {
            return self.background_rgb;
        }
        to_bytes(c.truncate() + (1.0 - c.w) * self.background)
    }

    /// Copies a tile's pixels (row-major RGB of `rect`) into place. Called
    /// by the thread that rendered the tile, as soon as it has: the tile's
    /// pixels are still in its cache, and the film's pages, which a black
    /// film leaves untouched until here, are first written (faulted in) by
    /// all the render threads during the frame instead of by one thread
    /// after it. The lock is held for one tile's copy.
    pub fn put_tile(&self, rect: &PixelRect, pixels: &[u8]) {
        let w = 3 * (rect.x1 - rect.x0) as usize;
        let mut rgb = self.rgb.lock();
        for (row, j) in (rect.y0..rect.y1).enumerate() {
            let o = 3 * (j as usize * self.width as usize + rect.x0 as usize);
            rgb[o..o + w].copy_from_slice(&pixels[row * w..row * w + w]);
        }
    }

    /// The finished image.
    pub fn into_rgb(self) -> Vec<u8> {
        self.rgb.into_inner()
    }
}

/// `round(255·clamp(x, 0, 1))` per channel (no gamma).
#[inline]
pub(crate) fn to_bytes(c: Vec3) -> [u8; 3] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z)]
}

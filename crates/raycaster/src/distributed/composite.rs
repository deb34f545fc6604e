//! Compositing: the parts' [`PartialImage`]s merged into the frame, in the
//! visibility order of their regions (sort-last compositing).
//!
//! Per pixel, front to back: DVR blends premultiplied colours with "over"
//! (`C += (1 − A)·C_i`, `A += (1 − A)·A_i`); MIP and MinIP keep the
//! extremum of the parts' extrema and only then look it up in the transfer
//! function; avg adds the parts' sums and counts before dividing; iso keeps
//! the nearest hit. The background is applied last, as SPEC §5 says
//! (`rgb = C + (1 − A)·background`, clamped, rounded).
//!
//! **Early ray termination across parts.** Each rank stops its own rays at
//! the ERT threshold, but cannot know that a part in front of it already
//! made a pixel opaque. The compositor restores the single-process rule
//! where it can: once the accumulated opacity reaches the threshold, later
//! parts are not blended (exactly where a single process would have
//! stopped, when the front part stopped the ray). Where the threshold is
//! crossed inside a later part, that part integrated its samples from
//! `A = 0` and stopped later than a single process would: the difference
//! is below `1 − threshold` of the pixel.

use glam::{Vec3, Vec4};

use super::render::PartialImage;
use crate::camera::PixelRect;
use crate::error::{Error, Result};
use crate::integrator::{AvgState, Fragment, MinipState, MipState, RenderMode};
use crate::render::film::to_bytes;
use crate::transfer::TransferFunction;

/// What the compositor needs of the frame's settings.
#[derive(Debug, Clone)]
pub struct Compositor {
    /// The mode the parts were rendered in.
    pub mode: RenderMode,
    /// The transfer function (MIP and MinIP look the extremum up in it).
    pub tf: TransferFunction,
    /// The ERT threshold (`None`: ERT off).
    pub ert: Option<f32>,
    /// Divisor of avg (the sample type's maximum).
    pub avg_norm: f32,
    /// Background colour, 0..1.
    pub background: Vec3,
}

impl Compositor {
    /// Merges `fragment` (of a part behind those merged so far) into `acc`.
    #[inline]
    pub fn merge(&self, acc: &mut Fragment, f: &Fragment) {
        match self.mode {
            RenderMode::Dvr => {
                if self.ert.is_none_or(|t| acc.rgba.w < t) {
                    acc.rgba += (1.0 - acc.rgba.w) * f.rgba;
                }
            }
            RenderMode::Mip | RenderMode::Minip => {
                if f.count > 0 {
                    acc.value = if acc.count == 0 {
                        f.value
                    } else if self.mode == RenderMode::Mip {
                        acc.value.max(f.value)
                    } else {
                        acc.value.min(f.value)
                    };
                    acc.count += f.count;
                }
            }
            RenderMode::Avg => {
                acc.value += f.value;
                acc.count += f.count;
            }
            RenderMode::Iso => {
                if f.count > 0 && (acc.count == 0 || f.value < acc.value) {
                    *acc = *f;
                }
            }
            RenderMode::Metaballs => {}
        }
    }

    /// The premultiplied pixel of a fully merged fragment.
    pub fn resolve(&self, f: &Fragment) -> Vec4 {
        match self.mode {
            RenderMode::Dvr | RenderMode::Iso => f.rgba,
            RenderMode::Mip if f.count > 0 => MipState::colour(&self.tf, f.value),
            RenderMode::Minip if f.count > 0 => MinipState::colour(&self.tf, f.value),
            RenderMode::Avg => AvgState::colour(f.value as f64, f.count as u64, self.avg_norm),
            _ => Vec4::ZERO,
        }
    }

    /// The RGB8 of a pixel no part covers (the background).
    pub fn empty_pixel(&self) -> [u8; 3] {
        self.pixel(&Fragment::default())
    }

    /// The RGB8 of a fully merged fragment, over the background.
    #[inline]
    pub fn pixel(&self, f: &Fragment) -> [u8; 3] {
        let c = self.resolve(f);
        to_bytes(c.truncate() + (1.0 - c.w) * self.background)
    }

    /// Merges `parts`, given front to back, over the pixels of `rect`
    /// (the parts may hold more or fewer pixels; those outside `rect` are
    /// ignored), starting from empty fragments: the same arithmetic, pixel
    /// by pixel, as [`Compositor::composite`] over the same parts.
    pub fn merge_over<'a>(
        &self,
        rect: PixelRect,
        width: u32,
        height: u32,
        parts: impl IntoIterator<Item = &'a PartialImage>,
    ) -> Result<PartialImage> {
        let mut acc = vec![Fragment::default(); rect.area() as usize];
        let rw = (rect.x1 - rect.x0) as usize;
        let mut samples = 0;
        for part in parts {
            if (part.width, part.height) != (width, height) {
                return Err(Error::option(
                    "partial image",
                    format!(
                        "{}x{} does not match {width}x{height}",
                        part.width, part.height
                    ),
                ));
            }
            samples += part.samples;
            let r = part.rect.intersect(&rect);
            let w = (r.x1 - r.x0) as usize;
            let pw = (part.rect.x1 - part.rect.x0) as usize;
            for j in r.y0..r.y1 {
                let src = (j - part.rect.y0) as usize * pw + (r.x0 - part.rect.x0) as usize;
                let dst = (j - rect.y0) as usize * rw + (r.x0 - rect.x0) as usize;
                for (a, f) in acc[dst..dst + w]
                    .iter_mut()
                    .zip(&part.fragments[src..src + w])
                {
                    self.merge(a, f);
                }
            }
        }
        Ok(PartialImage {
            width,
            height,
            rect,
            fragments: acc,
            samples,
            time: std::time::Duration::ZERO,
        })
    }

    /// The RGB8 of the pixels of `rect` (row-major) from the merged
    /// `image`; pixels of `rect` it does not hold are the background.
    pub fn resolve_rect(&self, image: &PartialImage, rect: PixelRect) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(rect.area() as usize * 3);
        let empty = self.empty_pixel();
        let held = image.rect.intersect(&rect);
        let iw = (image.rect.x1 - image.rect.x0) as usize;
        for y in rect.y0..rect.y1 {
            if held.is_empty() || y < held.y0 || y >= held.y1 {
                for _ in rect.x0..rect.x1 {
                    rgb.extend(empty);
                }
                continue;
            }
            for _ in rect.x0..held.x0 {
                rgb.extend(empty);
            }
            let at = (y - image.rect.y0) as usize * iw + (held.x0 - image.rect.x0) as usize;
            for f in &image.fragments[at..at + (held.x1 - held.x0) as usize] {
                rgb.extend(self.pixel(f));
            }
            for _ in held.x1..rect.x1 {
                rgb.extend(empty);
            }
        }
        rgb
    }

    /// The RGB8 frame from pieces `(rect, rgb over rect)` that do not
    /// overlap; pixels no piece covers are the background.
    pub fn assemble<'a>(
        &self,
        width: u32,
        height: u32,
        pieces: impl IntoIterator<Item = (PixelRect, &'a [u8])>,
    ) -> Result<Vec<u8>> {
        let mut rgb = self.empty_pixel().repeat(width as usize * height as usize);
        for (r, piece) in pieces {
            if r.is_empty() {
                continue;
            }
            if r.x1 > width || r.y1 > height || piece.len() as u64 != 3 * r.area() {
                return Err(Error::option(
                    "composited piece",
                    format!("{r:?} with {} bytes in {width}x{height}", piece.len()),
                ));
            }
            let w = 3 * (r.x1 - r.x0) as usize;
            for (row, y) in (r.y0..r.y1).enumerate() {
                let o = 3 * (y as usize * width as usize + r.x0 as usize);
                rgb[o..o + w].copy_from_slice(&piece[row * w..row * w + w]);
            }
        }
        Ok(rgb)
    }

    /// Composites `parts`, given front to back, into the RGB8 frame.
    pub fn composite<'a>(
        &self,
        parts: impl IntoIterator<Item = &'a PartialImage> + Clone,
    ) -> Result<(u32, u32, Vec<u8>)> {
        let Some(first) = parts.clone().into_iter().next() else {
            return Err(Error::option("ranks", "nothing to composite"));
        };
        let (width, height) = (first.width, first.height);
        let full = PixelRect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        };
        let merged = self.merge_over(full, width, height, parts)?;
        Ok((width, height, self.resolve_rect(&merged, full)))
    }
}

//! Rendering a part: the rays of the frame integrated over the samples one
//! region owns, with the existing integrators, into [`Fragment`]s.
//!
//! Each ray is first clipped to the **whole** volume's box, so the sample
//! positions `t_k = t_in + k·s` (SPEC §5, jitter and clipping included) are
//! the single-process ones; the region then keeps the range of `k` whose
//! positions it owns ([`Region::sample_range`]). The segment is moved into
//! the part's voxel space (the same world points; its origin shifted by
//! the part's first voxel) and integrated by the mode's [`Integrator`],
//! whose [`Integrator::fragment`] is the pixel's partial result, with no
//! background. Exact isosurfaces search the ray parameter interval the
//! region owns instead of its samples.
//!
//! The pixel loop is this module's own (rows on a rayon pool) because the
//! renderers of [`crate::render`] write finished RGB over a background;
//! the volume and the mode are dispatched once per frame as there, so the
//! hot loops stay monomorphised.

use std::time::{Duration, Instant};

use glam::UVec3;
use rayon::prelude::*;

use super::partition::Region;
use crate::camera::{Camera, PixelRect};
use crate::error::{Error, Result};
use crate::integrator::{
    Fragment, Integrator, IntegratorVisitor, RaySegment, RenderMode, Span, jitter,
};
use crate::render::plan::{FramePlan, PlanCache, RenderOptions};
use crate::scene::Scene;
use crate::transfer::TransferFunction;
use crate::volume::{Grid, Volume, VolumeVisitor};

/// One rank's part of the volume, ready to render.
#[derive(Debug)]
pub struct PartScene {
    /// The part's voxels (region plus ghost layer) and their macrocells.
    pub scene: Scene,
    /// The samples it owns.
    pub region: Region,
    /// The part's first voxel in the whole grid.
    pub offset: UVec3,
    /// The whole volume's grid.
    pub whole: Grid,
    /// The whole volume's value range (shading thresholds depend on it).
    pub value_range: (f32, f32),
}

impl PartScene {
    /// The ray `whole` (a segment of the whole volume) restricted to this
    /// part and moved into its voxel space; `None` when the part owns
    /// nothing of it.
    #[inline]
    fn localise(&self, whole: &RaySegment, iso: bool) -> Option<RaySegment> {
        let mut seg = *whole;
        seg.origin = whole.origin - self.offset.as_vec3();
        if iso {
            let (a, b) = self.region.interval(whole.origin, whole.dir);
            seg.t_in = whole.t_in.max(a);
            seg.t_out = whole.t_out.min(b);
            (seg.t_in <= seg.t_out && !whole.is_empty()).then_some(seg)
        } else {
            let (first, end) = self.region.sample_range(
                whole.origin,
                whole.dir,
                whole.t0,
                whole.inv_step,
                (whole.first, whole.count),
                |k| whole.pos(k),
            );
            seg.first = first;
            seg.count = end;
            (first < end).then_some(seg)
        }
    }
}

/// A part's image: one [`Fragment`] per pixel of the rectangle its box
/// covers on screen.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialImage {
    /// Image width (the whole frame's).
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// The pixels held.
    pub rect: PixelRect,
    /// Row-major over `rect`.
    pub fragments: Vec<Fragment>,
    /// Samples taken.
    pub samples: u64,
    /// Wall-clock time of the render.
    pub time: Duration,
}

impl PartialImage {
    /// The fragment of pixel `(x, y)` when the rectangle holds it.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Option<&Fragment> {
        self.rect.contains(x, y).then(|| {
            let w = (self.rect.x1 - self.rect.x0) as usize;
            &self.fragments[(y - self.rect.y0) as usize * w + (x - self.rect.x0) as usize]
        })
    }

    /// The part of the image inside `rect` (its rectangle is the
    /// intersection, possibly empty), to send to the rank that composites
    /// `rect`. Samples and time are not kept.
    pub fn crop(&self, rect: &PixelRect) -> PartialImage {
        let r = self.rect.intersect(rect);
        let w = (self.rect.x1 - self.rect.x0) as usize;
        let mut fragments = Vec::with_capacity(r.area() as usize);
        for y in r.y0..r.y1 {
            let o = (y - self.rect.y0) as usize * w + (r.x0 - self.rect.x0) as usize;
            fragments.extend_from_slice(&self.fragments[o..o + (r.x1 - r.x0) as usize]);
        }
        PartialImage {
            width: self.width,
            height: self.height,
            rect: r,
            fragments,
            samples: 0,
            time: Duration::ZERO,
        }
    }

    /// The length of [`PartialImage::encode`]'s output for an image of
    /// `rect`: what a receiver that knows the rectangle expects.
    pub fn encoded_len(rect: &PixelRect) -> usize {
        6 + rect.area() as usize * Fragment::FLOATS
    }

    /// The image as floats, to send: width, height, the rectangle, then
    /// [`Fragment::FLOATS`] per pixel (pixel coordinates are exact in f32
    /// below 2²⁴).
    pub fn encode(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(Self::encoded_len(&self.rect));
        self.encode_crop_into(&self.rect, &mut out);
        out
    }

    /// Appends the encoding of `self.crop(rect)` to `out` (without making
    /// the crop).
    pub fn encode_crop_into(&self, rect: &PixelRect, out: &mut Vec<f32>) {
        let r = self.rect.intersect(rect);
        out.reserve(Self::encoded_len(&r));
        out.extend([self.width, self.height, r.x0, r.y0, r.x1, r.y1].map(|v| v as f32));
        let w = (self.rect.x1 - self.rect.x0) as usize;
        for y in r.y0..r.y1 {
            let o = (y - self.rect.y0) as usize * w + (r.x0 - self.rect.x0) as usize;
            for f in &self.fragments[o..o + (r.x1 - r.x0) as usize] {
                f.write(out);
            }
        }
    }

    /// The image [`PartialImage::encode`] wrote (samples and time are not
    /// sent).
    pub fn decode(floats: &[f32]) -> Result<PartialImage> {
        let bad = |m: String| Error::option("partial image", m);
        if floats.len() < 6 {
            return Err(bad(format!(
                "{} floats, fewer than its header",
                floats.len()
            )));
        }
        let u = |i: usize| floats[i] as u32;
        let rect = PixelRect {
            x0: u(2),
            y0: u(3),
            x1: u(4),
            y1: u(5),
        };
        let (width, height) = (u(0), u(1));
        if rect.x0 > rect.x1 || rect.y0 > rect.y1 || rect.x1 > width || rect.y1 > height {
            return Err(bad(format!("rectangle {rect:?} outside {width}x{height}")));
        }
        let body = &floats[6..];
        if body.len() as u64 != rect.area() * Fragment::FLOATS as u64 {
            return Err(bad(format!(
                "{} floats for {} pixels",
                body.len(),
                rect.area()
            )));
        }
        Ok(PartialImage {
            width,
            height,
            rect,
            fragments: body
                .chunks_exact(Fragment::FLOATS)
                .map(Fragment::read)
                .collect(),
            samples: 0,
            time: Duration::ZERO,
        })
    }
}

/// Renders parts of a volume into [`PartialImage`]s on a thread pool.
pub struct PartRenderer {
    pool: rayon::ThreadPool,
    threads: usize,
    cache: PlanCache,
}

impl std::fmt::Debug for PartRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PartRenderer")
            .field("threads", &self.threads)
            .finish()
    }
}

impl PartRenderer {
    /// A renderer with `threads` workers (0 = one per core).
    pub fn new(threads: usize) -> Result<Self> {
        let (pool, threads) = crate::render::render_pool(threads, "part")?;
        Ok(PartRenderer {
            pool,
            threads,
            cache: PlanCache::default(),
        })
    }

    /// Worker threads.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Renders the samples `part` owns for `camera`, `tf` and `options`
    /// (the step defaults to the whole volume's). Shadow rays would cross
    /// other parts, so they are refused.
    pub fn render(
        &mut self,
        part: &PartScene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
    ) -> Result<PartialImage> {
        let start = Instant::now();
        if options.shadows && options.mode == RenderMode::Iso {
            return Err(Error::option(
                "shadows",
                "shadow rays cross other ranks' parts: not available with --distributed",
            ));
        }
        if options.reflection > 0.0 && options.mode == RenderMode::Iso {
            return Err(Error::option(
                "reflection",
                "reflection rays cross other ranks' parts: not available with --distributed",
            ));
        }
        let mut options = options.clone();
        options.step = Some(options.step_for(&part.whole));
        let plan = FramePlan::new(&mut self.cache, &part.scene, camera, tf, &options)?;
        let clip = options.clip.region(&part.whole);
        let rect = plan.rect;
        let mut fragments = vec![Fragment::default(); rect.area() as usize];

        struct WithVolume<'a> {
            job: Job<'a>,
            fragments: &'a mut [Fragment],
        }
        #[derive(Clone, Copy)]
        struct Job<'a> {
            part: &'a PartScene,
            plan: &'a FramePlan,
            tf: &'a TransferFunction,
            options: &'a RenderOptions,
            clip: Option<&'a crate::clip::ClipRegion>,
            pool: &'a rayon::ThreadPool,
        }
        impl VolumeVisitor for WithVolume<'_> {
            type Output = u64;
            fn visit<V: Volume>(self, volume: &V) -> u64 {
                struct WithMode<'a, 'v, V: Volume> {
                    job: Job<'a>,
                    volume: &'v V,
                    fragments: &'v mut [Fragment],
                }
                impl<V: Volume> IntegratorVisitor for WithMode<'_, '_, V> {
                    type Output = u64;
                    fn visit<I: Integrator>(self) -> u64 {
                        integrate::<V, I>(self.job, self.volume, self.fragments)
                    }
                }
                self.job.options.mode.visit(WithMode {
                    job: self.job,
                    volume,
                    fragments: self.fragments,
                })
            }
        }
        fn integrate<V: Volume, I: Integrator>(
            job: Job<'_>,
            volume: &V,
            fragments: &mut [Fragment],
        ) -> u64 {
            let Job {
                part,
                plan,
                tf,
                options,
                clip,
                pool,
            } = job;
            let ctx = plan.context_with_range(volume, &part.scene, tf, options, part.value_range);
            let rect = plan.rect;
            let width = (rect.x1 - rect.x0) as usize;
            let iso = options.mode == RenderMode::Iso;
            pool.install(|| {
                fragments
                    .par_chunks_mut(width.max(1))
                    .enumerate()
                    .map(|(row, out)| {
                        let j = rect.y0 + row as u32;
                        let mut samples = 0u64;
                        for (i, slot) in (rect.x0..rect.x1).zip(out.iter_mut()) {
                            let ray = plan.camera.ray(i, j);
                            let jit = plan.jitter.map_or(0.0, |seed| jitter(i, j, seed));
                            let Some(whole) =
                                RaySegment::with(&part.whole, &ray, plan.step, jit, clip)
                            else {
                                continue;
                            };
                            let Some(seg) = part.localise(&whole, iso) else {
                                continue;
                            };
                            let mut state = I::default();
                            samples += state.integrate(Span::whole(&ctx, &seg));
                            *slot = state.fragment(&ctx);
                        }
                        samples
                    })
                    .sum()
            })
        }

        let samples = part.scene.volume().visit(WithVolume {
            job: Job {
                part,
                plan: &plan,
                tf,
                options: &options,
                clip: clip.as_ref(),
                pool: &self.pool,
            },
            fragments: &mut fragments,
        });
        Ok(PartialImage {
            width: plan.width,
            height: plan.height,
            rect,
            fragments,
            samples,
            time: start.elapsed(),
        })
    }
}

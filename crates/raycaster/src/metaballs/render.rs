//! [`MetaballRenderer`]: a frame of metaballs. Per frame it builds the
//! tile candidate lists, then renders the tiles (one tile loop,
//! [`render_tile`]) in order on the calling thread or on a rayon pool;
//! every ray is computed the same way whichever thread takes its tile, so
//! every renderer gives the same image.

use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::balls::Balls;
use super::kernel::Kernel;
use super::ray::{self, RayParams, Scratch};
use super::shadow::{ShadowGrid, ShadowScratch};
use super::tiles::TileLists;
use crate::camera::{Camera, CameraFrame, PixelRect};
use crate::error::{Error, Result};
use crate::geometry::Ray;
use crate::integrator::Phong;
use crate::render::film::{Film, RayCounts};
use crate::render::{Frame, FrameStats, RendererKind};
use crate::simd::{self, Isa};
use crate::transfer::TransferFunction;

/// How metaballs are drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct MetaballOptions {
    /// The kernel.
    pub kernel: Kernel,
    /// The surface is `F = field_threshold` (> 0; default 0.5).
    pub field_threshold: f32,
    /// Phong shading (off: the blended colour, flat).
    pub shading: bool,
    /// Phong coefficients; `None`: [`Phong::default`].
    pub phong: Option<Phong>,
    /// Directional lights (world directions towards them, not zero); empty:
    /// one headlight. As in iso mode.
    pub lights: Vec<Vec3>,
    /// Background colour, 0..1.
    pub background: Vec3,
    /// Shadow rays from each hit towards each light (with shading): a
    /// light the surface hides adds nothing there. As in iso mode.
    pub shadows: bool,
}

impl Default for MetaballOptions {
    fn default() -> Self {
        MetaballOptions {
            kernel: Kernel::Wyvill,
            field_threshold: 0.5,
            shading: true,
            phong: None,
            lights: Vec::new(),
            background: Vec3::ZERO,
            shadows: false,
        }
    }
}

/// What a metaball frame cost beyond [`FrameStats`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MetaballStats {
    /// Building the tile candidate lists (part of the frame time).
    pub lists: Duration,
    /// Entries in all candidate lists.
    pub list_entries: u64,
    /// Balls in front of the camera.
    pub visible_balls: u64,
    /// Binning every ball into the shadow rays' grid (with shadows; part
    /// of the frame time; next to nothing while the balls and kernel stay
    /// the same: the grid is kept).
    pub shadow_grid: Duration,
}

/// Renders [`Balls`]: serially or on a thread pool (see the module docs).
pub struct MetaballRenderer {
    kind: RendererKind,
    pool: Option<rayon::ThreadPool>,
    threads: usize,
    /// The last shadow grid, by the [`Balls::id`] and kernel it was built
    /// for: while they do not change (a moving camera, new lights) it is
    /// reused.
    shadow_grid: Option<((u64, Kernel), Option<ShadowGrid>)>,
}

impl std::fmt::Debug for MetaballRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MetaballRenderer")
            .field("kind", &self.kind)
            .field("threads", &self.threads)
            .finish()
    }
}

/// Tile side in pixels, for the candidate lists and the tile loop alike.
pub const TILE: u32 = 16;

impl MetaballRenderer {
    /// A renderer scheduled like `kind`: `serial` renders the tiles in order
    /// on the calling thread; `tiles` and `object` render them on a pool of
    /// `threads` (0 = one per core). (There are no bricks to split a ray
    /// into: the object renderer's schedule is the tiled one here.)
    pub fn new(kind: RendererKind, threads: usize) -> Result<Self> {
        let (pool, threads) = match kind {
            RendererKind::Serial => (None, 1),
            RendererKind::Tiles | RendererKind::Object => {
                let (pool, threads) = crate::render::render_pool(threads, "metaballs")?;
                (Some(pool), threads)
            }
        };
        Ok(MetaballRenderer {
            kind,
            pool,
            threads,
            shadow_grid: None,
        })
    }

    /// The renderer's name (`serial`, `tiles`, `object`).
    pub fn name(&self) -> &'static str {
        self.kind.name()
    }

    /// Worker threads.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Renders `balls` seen by `camera`; colours from `tf` at the balls'
    /// values (white without a TF or without values).
    pub fn render(
        &mut self,
        balls: &Balls,
        camera: &Camera,
        tf: Option<&TransferFunction>,
        options: &MetaballOptions,
    ) -> Result<(Frame, MetaballStats)> {
        let start = Instant::now();
        let frame = camera.frame().ok_or_else(|| {
            Error::option(
                "camera",
                format!(
                    "degenerate (position {}, look-at {}, up {}, fov {}, size {}x{})",
                    camera.position,
                    camera.target,
                    camera.up,
                    camera.fov_y_deg,
                    camera.width,
                    camera.height
                ),
            )
        })?;
        let threshold = options.field_threshold;
        if !(threshold.is_finite() && threshold > 0.0) {
            return Err(Error::option(
                "field-threshold",
                format!("{threshold} must be finite and > 0"),
            ));
        }
        let mut lights = Vec::with_capacity(options.lights.len());
        for l in &options.lights {
            let unit = l.normalize_or_zero();
            if unit == Vec3::ZERO || !unit.is_finite() {
                return Err(Error::option(
                    "light",
                    format!("direction {l} must be finite and not zero"),
                ));
            }
            lights.push(unit);
        }
        let values = balls.has_values().then_some(tf).flatten();
        let lists = TileLists::build(balls, &frame, camera.width, camera.height, TILE, |i| {
            values.map_or(Vec3::ONE, |tf| {
                tf.evaluate(balls.as_slice()[i].value).truncate()
            })
        })?;
        let lists_time = start.elapsed();
        let (r_min, r_max) = balls
            .as_slice()
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), b| {
                (lo.min(b.radius as f64), hi.max(b.radius as f64))
            });
        let scale = r_max.max(f64::MIN_POSITIVE);
        let mut params = RayParams::new(
            &lists.balls,
            options.kernel,
            threshold as f64,
            scale,
            ROOT_TOLERANCE * r_min.min(r_max) / scale,
        );
        params.shading = options.shading.then(|| options.phong.unwrap_or_default());
        params.lights = &lights;
        // Shadow casters include the balls the camera does not see.
        let grid_start = Instant::now();
        let shadow_grid = if options.shadows && options.shading {
            let key = (balls.id(), options.kernel);
            if self.shadow_grid.as_ref().is_none_or(|(k, _)| *k != key) {
                let build = || ShadowGrid::build(balls, options.kernel);
                let grid = match &self.pool {
                    None => build(),
                    Some(pool) => pool.install(build),
                };
                self.shadow_grid = Some((key, grid));
            }
            self.shadow_grid
                .as_ref()
                .and_then(|(_, grid)| grid.as_ref())
        } else {
            None
        };
        let shadow_grid_time = grid_start.elapsed();
        let shadow_params = shadow_grid.map(|g| params.with_balls(&g.balls));
        let film = Film::new(camera.width, camera.height, options.background);
        let tiles: Vec<(u32, u32)> = (0..lists.rows)
            .flat_map(|ty| (0..lists.cols).map(move |tx| (tx, ty)))
            .filter(|&(tx, ty)| !lists.candidates(tx, ty).is_empty())
            .collect();
        let job = TileJob {
            frame: &frame,
            lists: &lists,
            params: &params,
            shadows: shadow_grid.zip(shadow_params.as_ref()),
            offset: SHADOW_OFFSET * r_min.min(r_max),
            film: &film,
        };
        let met: u64 = match &self.pool {
            None => tiles.iter().map(|&t| render_tile(&job, t)).sum(),
            Some(pool) => pool.install(|| {
                tiles
                    .par_iter()
                    .with_max_len(1)
                    .map(|&t| render_tile(&job, t))
                    .sum()
            }),
        };
        let rays: u64 = tiles
            .iter()
            .map(|&(tx, ty)| lists.rect(tx, ty).area())
            .sum();
        let counts = film.counts();
        let stats = MetaballStats {
            lists: lists_time,
            list_entries: lists.entries() as u64,
            visible_balls: lists.balls.len() as u64,
            shadow_grid: shadow_grid_time,
        };
        Ok((
            Frame {
                width: camera.width,
                height: camera.height,
                rgb: film.into_rgb(),
                stats: FrameStats {
                    rays,
                    rays_in_volume: counts.entered,
                    covered: counts.covered,
                    samples: met,
                    time: start.elapsed(),
                },
            },
            stats,
        ))
    }
}

/// Roots are refined to this fraction of the smallest radius (the contract
/// asks for 1e-3·R).
pub const ROOT_TOLERANCE: f64 = 1e-4;

/// Shadow rays start this fraction of the smallest radius off the surface
/// along its normal, well past the hit's tolerance, so that they do not
/// find the surface they leave.
const SHADOW_OFFSET: f64 = 2e-3;

/// How deep into a tile's candidate list (from its first `t_lo`, in
/// largest radii) [`ray::tighten_tile`] tightens it: on the benchmark
/// lattices a ray hits within a radius or two of its first ball (4 radii
/// measured 1 % slower at 8000 balls, 1 radius 3 % slower).
const TIGHTEN_DEPTH: f64 = 2.0;

/// What the tile loop reads.
struct TileJob<'a> {
    frame: &'a CameraFrame,
    lists: &'a TileLists,
    params: &'a RayParams<'a>,
    /// With shadows: all balls in a grid, and the shadow rays' parameters.
    shadows: Option<(&'a ShadowGrid, &'a RayParams<'a>)>,
    /// How far off the surface shadow rays start.
    offset: f64,
    film: &'a Film,
}

/// The tile loop: every pixel of tile `(tx, ty)`, put on the film (by the
/// thread that rendered it, as the volume renderers' tile loop does);
/// returns the ray-ball intersections taken. In
/// [`FrameStats`], `rays_in_volume` counts the rays that met a ball,
/// `covered` those that hit the surface and `samples` the intersections.
fn render_tile(job: &TileJob<'_>, (tx, ty): (u32, u32)) -> u64 {
    let rect: PixelRect = job.lists.rect(tx, ty);
    let cands = job.lists.candidates(tx, ty);
    let mut tile = Vec::new();
    // Perspective rays all start at the eye: the candidates are kept
    // relative to it.
    let eye = job.frame.position().as_dvec3();
    ray::tile_cands(job.params.balls, cands, eye, &mut tile);
    ray::tighten_tile(
        job.frame,
        &rect,
        &mut tile,
        eye,
        TIGHTEN_DEPTH * job.params.scale,
    );
    let (rgb, met, counts) = simd::dispatch(TileRays {
        job,
        rect,
        tile: &tile,
        eye,
    });
    job.film.add_counts(counts);
    job.film.put_tile(&rect, &rgb);
    met
}

/// The rays of one tile, compiled for the best instruction set of the CPU
/// (a [`simd::Kernel::WIDE`] loop), so that the candidates' tests against
/// a ray's line ([`ray::CandColumns`]) run in vector lanes.
struct TileRays<'a, 'b> {
    job: &'a TileJob<'b>,
    rect: PixelRect,
    tile: &'a [ray::Cand],
    eye: DVec3,
}

impl simd::Kernel for TileRays<'_, '_> {
    type Output = (Vec<u8>, u64, RayCounts);
    const WIDE: bool = true;

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) -> Self::Output {
        let TileRays {
            job,
            rect,
            tile,
            eye,
        } = self;
        let mut rgb = Vec::with_capacity(3 * rect.area() as usize);
        let mut met = 0;
        let mut counts = RayCounts::default();
        let mut scratch = Scratch::default();
        let mut shadow_scratch = ShadowScratch::default();
        let mut columns = ray::CandColumns::default();
        columns.fill(tile);
        for j in rect.y0..rect.y1 {
            for i in rect.x0..rect.x1 {
                let r = job.frame.ray(i, j);
                let res = ray::first_hit_columns(job.params, &r, tile, &columns, eye, &mut scratch);
                met += res.met as u64;
                let px = match res.t {
                    Some(t) => {
                        let c = ray::shade(job.params, &r, t, scratch.active(), |x, n, l| {
                            job.shadows.is_some_and(|(grid, params)| {
                                let origin = x + n.as_dvec3() * job.offset;
                                let shadow = Ray {
                                    origin: origin.as_vec3(),
                                    dir: l,
                                };
                                grid.blocked(params, &shadow, &mut shadow_scratch)
                            })
                        });
                        counts.add(c);
                        job.film.composite(c)
                    }
                    None => {
                        if res.met > 0 {
                            counts.add(glam::Vec4::ZERO);
                        }
                        job.film.background_rgb()
                    }
                };
                rgb.extend_from_slice(&px);
            }
        }
        (rgb, met, counts)
    }
}

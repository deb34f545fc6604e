//! The screen-parallel renderer: tiles of the covered screen rectangle
//! integrated on a thread pool, each ray whole on one thread.

use rayon::prelude::*;

use super::TiledRenderer;
use super::driver::{FrameJob, Schedule, render_tile};
use super::film::Film;
use crate::camera::PixelRect;
use crate::error::Result;
use crate::integrator::Integrator;
use crate::volume::Volume;

/// The tiled renderer's schedule: tiles on a rayon pool; work stealing
/// balances tiles of unequal cost.
pub struct TilePool {
    pool: rayon::ThreadPool,
    threads: usize,
    tile: u32,
}

impl std::fmt::Debug for TilePool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TilePool")
            .field("threads", &self.threads)
            .field("tile", &self.tile)
            .finish()
    }
}

impl TiledRenderer {
    /// Default tile side in pixels: on the benchmark frame 16- and 32-pixel
    /// tiles measured alike, 8 and 64 slower (see the README).
    pub const DEFAULT_TILE: u32 = 16;

    /// A renderer with `threads` workers (0 = one per core) and square tiles
    /// of `tile` pixels.
    pub fn new(threads: usize, tile: u32) -> Result<Self> {
        let (pool, threads) = super::render_pool(threads, "tile")?;
        Ok(TiledRenderer::with_schedule(TilePool {
            pool,
            threads,
            tile: tile.max(1),
        }))
    }
}

impl Schedule for TilePool {
    const NAME: &'static str = "tiles";

    fn threads(&self) -> usize {
        self.threads
    }

    fn run<V: Volume, I: Integrator>(&mut self, job: &FrameJob<'_, V>, film: &Film) -> Option<u64> {
        let tiles: Vec<PixelRect> = job.plan.rect.tiles(self.tile).collect();
        // Each tile goes on the film from the thread that rendered it; a
        // tile is only missing when the frame was cancelled.
        self.pool.install(|| {
            tiles
                .par_iter()
                .with_max_len(1)
                .map(|t| (!job.cancel.is_cancelled()).then(|| render_tile::<V, I>(job, film, t)))
                .sum()
        })
    }
}

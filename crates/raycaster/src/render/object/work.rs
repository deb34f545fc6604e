//! A frame's work: the visible bricks front to back and each tile's queue of
//! them.

use glam::UVec3;

use super::bricks::{BrickSet, Region};
use super::footprint::{footprint, intersect};
use crate::camera::{Camera, PixelRect, Projection};
use crate::geometry::Aabb;
use crate::render::plan::FramePlan;
use crate::volume::Grid;

/// One queued brick of a frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct QueuedBrick {
    pub region: Region,
    /// Pixels its rays may reach (inside the volume's screen rectangle).
    pub rect: PixelRect,
}

/// A frame's work: the queued bricks in front-to-back order and, per tile,
/// its queue of bricks (indices into `bricks`), in order.
#[derive(Debug)]
pub(super) struct FrameWork {
    pub bricks: Vec<QueuedBrick>,
    pub tiles: Vec<PixelRect>,
    /// Tile `t`'s queue is `queue[start[t]..start[t + 1]]`.
    start: Vec<u32>,
    queue: Vec<u32>,
}

impl FrameWork {
    pub fn build(
        set: &BrickSet,
        grid: &Grid,
        camera: &Camera,
        plan: &FramePlan,
        tile: u32,
    ) -> Self {
        let frame = &plan.camera;
        let rect = plan.rect;
        let tile = tile.max(1);
        let tiles: Vec<PixelRect> = rect.tiles(tile).collect();
        let tiles_x = (rect.x1 - rect.x0).div_ceil(tile);
        // Front-to-back keys.
        let eye = grid.world_to_voxel(camera.position);
        let eye_brick: [i64; 3] =
            std::array::from_fn(|a| set.brick_of(eye[a], set.count[a]) as i64);
        let sign: [i64; 3] = std::array::from_fn(|a| {
            let d = frame.forward[a];
            (d > 0.0) as i64 - (d < 0.0) as i64
        });
        let key = |b: UVec3| -> i64 {
            match camera.projection {
                Projection::Perspective => (0..3).map(|a| (b[a] as i64 - eye_brick[a]).abs()).sum(),
                Projection::Orthographic => (0..3).map(|a| sign[a] * b[a] as i64).sum(),
            }
        };
        // Every visible brick's screen footprint, on the current rayon pool
        // (every frame projects them all: 10⁵ bricks and more for the
        // largest volumes); the sort key is unique, so the order is fixed.
        use rayon::prelude::*;
        let mut order: Vec<(i64, u32, PixelRect)> = set
            .visible
            .par_iter()
            .enumerate()
            .with_min_len(1024)
            .filter_map(|(i, (b, bounds))| {
                let world = Aabb::new(
                    grid.voxel_to_world(bounds.min),
                    grid.voxel_to_world(bounds.max),
                );
                let fp = footprint(frame, camera, &world)?;
                let fp = intersect(&fp, &rect)?;
                Some((key(*b), i as u32, fp))
            })
            .collect();
        order.par_sort_unstable_by_key(|&(k, i, _)| (k, i));
        let bricks: Vec<QueuedBrick> = order
            .iter()
            .map(|&(_, i, fp)| QueuedBrick {
                region: set.region(set.visible[i as usize].0),
                rect: fp,
            })
            .collect();
        // Tile queues (compressed rows): count, prefix sums, fill in order.
        let tiles_of = |r: &PixelRect| {
            let tx = (r.x0 - rect.x0) / tile..=(r.x1 - 1 - rect.x0) / tile;
            let ty = (r.y0 - rect.y0) / tile..=(r.y1 - 1 - rect.y0) / tile;
            ty.flat_map(move |y| tx.clone().map(move |x| (y * tiles_x + x) as usize))
        };
        let mut start = vec![0u32; tiles.len() + 1];
        for b in &bricks {
            for t in tiles_of(&b.rect) {
                start[t + 1] += 1;
            }
        }
        for t in 0..tiles.len() {
            start[t + 1] += start[t];
        }
        let mut fill = start.clone();
        let mut queue = vec![0u32; start[tiles.len()] as usize];
        for (i, b) in bricks.iter().enumerate() {
            for t in tiles_of(&b.rect) {
                queue[fill[t] as usize] = i as u32;
                fill[t] += 1;
            }
        }
        FrameWork {
            bricks,
            tiles,
            start,
            queue,
        }
    }

    pub fn queue_of(&self, tile: u32) -> &[u32] {
        let t = tile as usize;
        &self.queue[self.start[t] as usize..self.start[t + 1] as usize]
    }
}

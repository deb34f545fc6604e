//! Per-tile candidate lists: which balls the rays of each screen tile may
//! meet, built for one frame in two passes from each ball's projected
//! bounding square ([`CameraFrame::sphere_rect`], exact under perspective).
//!
//! The first pass counts the balls per tile, a prefix sum turns the counts
//! into offsets, the second pass writes each ball into its tiles. Nothing
//! can overflow (each tile gets exactly the room it counted), and each
//! list comes out in one fixed order: the balls sorted by the frame's lower
//! bound on where a ray can enter them (`t_lo`), ties by index. A ray can
//! then stop taking candidates once their `t_lo` is past its hit.

use glam::{DVec3, Vec3};

use super::balls::Balls;
use crate::camera::{CameraFrame, PixelRect, Projection};
use crate::error::{Error, Result};
use crate::render::bins::Bins;

/// A ball as one frame sees it.
#[derive(Debug, Clone, Copy)]
pub struct FrameBall {
    /// Centre.
    pub center: DVec3,
    /// Radius squared.
    pub r2: f64,
    /// `1/radius²`.
    pub inv_r2: f64,
    /// No ray of the frame enters the ball before this `t`.
    pub t_lo: f64,
    /// Colour (the TF at the ball's value, or white).
    pub color: Vec3,
}

/// The balls of a frame sorted by `t_lo`, and per screen tile the indices
/// (into [`TileLists::balls`]) of those its rays may meet.
#[derive(Debug, Clone)]
pub struct TileLists {
    /// Tile side in pixels.
    pub tile: u32,
    /// Tiles per row.
    pub cols: u32,
    /// Tile rows.
    pub rows: u32,
    width: u32,
    height: u32,
    /// The frame's balls (those not wholly behind the eye), by `t_lo`.
    pub balls: Vec<FrameBall>,
    /// Per tile (row-major), its candidates.
    lists: Bins,
}

impl TileLists {
    /// Lists for `frame` (a `width`×`height` image cut into `tile`-pixel
    /// tiles), the balls coloured by `color(index)`.
    pub fn build(
        balls: &Balls,
        frame: &CameraFrame,
        width: u32,
        height: u32,
        tile: u32,
        color: impl Fn(usize) -> Vec3,
    ) -> Result<Self> {
        let tile = tile.max(1);
        let cols = width.div_ceil(tile);
        let rows = height.div_ceil(tile);
        let eye = frame.position().as_dvec3();
        let forward = frame.forward.as_dvec3();
        // Visible balls with their tile ranges and t_lo, in index order.
        let mut visible: Vec<(f64, u32, [u32; 4])> = Vec::with_capacity(balls.len());
        for (i, b) in balls.as_slice().iter().enumerate() {
            let Some(rect) = frame.sphere_rect(b.center, b.radius) else {
                continue;
            };
            let v = b.center.as_dvec3() - eye;
            let t_lo = match frame.projection() {
                Projection::Perspective => v.length() - b.radius as f64,
                Projection::Orthographic => v.dot(forward) - b.radius as f64,
            };
            let span = [
                rect.x0 / tile,
                rect.y0 / tile,
                (rect.x1 - 1) / tile,
                (rect.y1 - 1) / tile,
            ];
            visible.push((t_lo, i as u32, span));
        }
        visible.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));

        if visible.len() > u32::MAX as usize {
            return Err(Error::TooLarge {
                path: Default::default(),
                what: format!("{} balls in one frame", visible.len()),
            });
        }
        // The lists, in t_lo order.
        let lists = Bins::build((cols * rows) as usize, visible.len(), |k, put| {
            let [x0, y0, x1, y1] = visible[k].2;
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    put((ty * cols + tx) as usize);
                }
            }
        });
        let mut frame_balls = Vec::with_capacity(visible.len());
        for (t_lo, i, _) in &visible {
            let b = balls.as_slice()[*i as usize];
            let r = b.radius as f64;
            frame_balls.push(FrameBall {
                center: b.center.as_dvec3(),
                r2: r * r,
                inv_r2: 1.0 / (r * r),
                t_lo: *t_lo,
                color: color(*i as usize),
            });
        }
        Ok(TileLists {
            tile,
            cols,
            rows,
            width,
            height,
            balls: frame_balls,
            lists,
        })
    }

    /// The candidates of tile `(tx, ty)`, by `t_lo`.
    pub fn candidates(&self, tx: u32, ty: u32) -> &[u32] {
        self.lists.get((ty * self.cols + tx) as usize)
    }

    /// The pixels of tile `(tx, ty)`.
    pub fn rect(&self, tx: u32, ty: u32) -> PixelRect {
        PixelRect {
            x0: tx * self.tile,
            y0: ty * self.tile,
            x1: ((tx + 1) * self.tile).min(self.width),
            y1: ((ty + 1) * self.tile).min(self.height),
        }
    }

    /// Entries over all lists.
    pub fn entries(&self) -> usize {
        self.lists.entries()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::metaballs::balls::Ball;

    #[test]
    fn every_ball_a_pixel_ray_meets_is_in_its_tile_list_in_order() {
        let mut rng = fastrand::Rng::with_seed(5);
        let balls: Vec<Ball> = (0..60)
            .map(|_| Ball {
                center: Vec3::new(
                    rng.f32() * 4.0 - 2.0,
                    rng.f32() * 4.0 - 2.0,
                    rng.f32() * 4.0 - 2.0,
                ),
                radius: 0.05 + rng.f32() * 0.8,
                value: 0.0,
            })
            .collect();
        let balls = Balls::new(balls, false).unwrap();
        for (n, pos) in [
            Vec3::new(0.5, 1.0, 7.0),
            Vec3::new(-6.0, 2.0, -3.0),
            Vec3::new(0.0, 0.0, 1.5),
        ]
        .into_iter()
        .enumerate()
        {
            let mut cam = Camera::look_at(pos, Vec3::ZERO, 61, 47);
            if n == 1 {
                cam.projection = Projection::Orthographic;
            }
            let f = cam.frame().unwrap();
            let lists = TileLists::build(&balls, &f, 61, 47, 8, |_| Vec3::ONE).unwrap();
            for ty in 0..lists.rows {
                for tx in 0..lists.cols {
                    let cands = lists.candidates(tx, ty);
                    // In t_lo order.
                    assert!(cands.windows(2).all(|w| w[0] < w[1]));
                    let r = lists.rect(tx, ty);
                    for j in r.y0..r.y1 {
                        for i in r.x0..r.x1 {
                            let ray = f.ray(i, j);
                            for (k, fb) in lists.balls.iter().enumerate() {
                                let oc = fb.center - ray.origin.as_dvec3();
                                let b = oc.dot(ray.dir.as_dvec3());
                                let h2 = oc.length_squared() - b * b;
                                if h2 < fb.r2 && b + (fb.r2 - h2).sqrt() > 0.0 {
                                    assert!(cands.contains(&(k as u32)), "pixel {i},{j} ball {k}");
                                    // t_lo bounds the entry.
                                    assert!(b - (fb.r2 - h2).sqrt() >= fb.t_lo - 1e-9);
                                }
                            }
                        }
                    }
                }
            }
            // Balls wholly behind the eye are dropped, no others.
            assert!(lists.balls.len() <= balls.len());
        }
    }
}

//! File order: how the samples of a `.vol` file are cut into
//! batches, written one after another, and each batch into pieces, filled in
//! parallel.
//!
//! A piece is a box of voxels whose samples are contiguous in the file: in the
//! linear layout a run of x-slabs, of rows, or of one row's z; in the bricked
//! layout a run of whole bricks or a run of x-planes of one brick. Every piece
//! is computed on its own from the generator (a pure function of the voxel),
//! so the bytes never depend on how many threads filled them.

use glam::UVec3;
use raycaster::format::vol::VolLayout;
use raycaster::volume::BrickGrid;
use rayon::prelude::*;

use crate::generators::{Field, Region};

/// Bytes of one piece, the unit of parallel work (about).
pub const PIECE_BYTES: u64 = 256 << 10;
/// Bytes of one batch, the unit of writing (about; at least one brick).
pub const BATCH_BYTES: u64 = 2 << 20;

/// How the linear layout is cut into pieces.
#[derive(Debug, Clone, Copy)]
enum Split {
    /// `k` whole x-slabs per piece.
    Slabs { k: u32 },
    /// `k` rows of one slab per piece, `per_slab` pieces per slab.
    Rows { k: u32, per_slab: u32 },
    /// `k` samples of one row per piece, `per_row` pieces per row.
    Runs { k: u32, per_row: u32 },
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Linear {
        split: Split,
        pieces: u64,
        pieces_per_batch: u64,
    },
    Bricked {
        grid: BrickGrid,
        bricks: u64,
        bricks_per_batch: u64,
        /// Whole bricks per piece (bricks up to [`PIECE_BYTES`]), or 0.
        bricks_per_piece: u64,
        /// x-planes per piece when a brick is larger than a piece.
        planes_per_piece: u32,
    },
}

/// One unit of parallel work.
#[derive(Debug, Clone, Copy)]
enum Piece {
    Region(Region),
    Bricks { first: u64, count: u64 },
    BrickPlanes { brick: u64, x0: u32, x1: u32 },
}

/// Cuts `len` items holding `bytes` bytes in all into near-equal pieces of
/// about [`PIECE_BYTES`] at most: `(items per piece, pieces)`.
fn cut(len: u64, bytes: u64) -> (u64, u64) {
    let k = len.div_ceil(bytes.div_ceil(PIECE_BYTES));
    (k, len.div_ceil(k))
}

/// The order in which a volume's samples are produced and written.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    dims: UVec3,
    kind: Kind,
    sample_bytes: u64,
    batches: u64,
}

impl Plan {
    /// The plan for a volume of `dims` in `layout`, or `None` when its size
    /// overflows `u64` or a brick side is below 2.
    pub fn new(dims: UVec3, layout: VolLayout) -> Option<Plan> {
        if dims.cmpeq(UVec3::ZERO).any() {
            return None;
        }
        let (x, y, z) = (dims.x as u64, dims.y as u64, dims.z as u64);
        match layout {
            VolLayout::Linear => {
                let total = x.checked_mul(y)?.checked_mul(z)?;
                let slab = y * z;
                let (split, pieces) = if z >= PIECE_BYTES {
                    let (k, per_row) = cut(z, z);
                    let split = Split::Runs {
                        k: k as u32,
                        per_row: per_row as u32,
                    };
                    (split, (x * y).checked_mul(per_row)?)
                } else if slab >= PIECE_BYTES {
                    let (k, per_slab) = cut(y, slab);
                    let split = Split::Rows {
                        k: k as u32,
                        per_slab: per_slab as u32,
                    };
                    (split, x * per_slab)
                } else {
                    let k = (PIECE_BYTES / slab).clamp(1, x);
                    (Split::Slabs { k: k as u32 }, x.div_ceil(k))
                };
                let pieces_per_batch = (BATCH_BYTES / PIECE_BYTES).max(1);
                Some(Plan {
                    dims,
                    kind: Kind::Linear {
                        split,
                        pieces,
                        pieces_per_batch,
                    },
                    sample_bytes: total,
                    batches: pieces.div_ceil(pieces_per_batch),
                })
            }
            VolLayout::Bricked { side } => {
                let grid = BrickGrid::new(dims, side as u32).ok()?;
                let total = grid.total_len()?;
                let bricks = grid.brick_count()?;
                let len = grid.brick_len();
                let bricks_per_batch = (BATCH_BYTES / len).max(1);
                let (bricks_per_piece, planes_per_piece) = if len <= PIECE_BYTES {
                    (PIECE_BYTES / len, 0)
                } else {
                    let plane = (side as u64).pow(2);
                    (0, (PIECE_BYTES / plane).max(1) as u32)
                };
                Some(Plan {
                    dims,
                    kind: Kind::Bricked {
                        grid,
                        bricks,
                        bricks_per_batch,
                        bricks_per_piece,
                        planes_per_piece,
                    },
                    sample_bytes: total,
                    batches: bricks.div_ceil(bricks_per_batch),
                })
            }
        }
    }

    /// Sample bytes in the file (without the header).
    pub fn sample_bytes(&self) -> u64 {
        self.sample_bytes
    }

    /// Number of batches.
    pub fn batch_count(&self) -> u64 {
        self.batches
    }

    /// The linear piece `p` as a region.
    fn linear_region(&self, split: Split, p: u64) -> Region {
        let d = self.dims;
        let stride_x = d.y as usize * d.z as usize;
        let stride_y = d.z as usize;
        let (lo, hi) = match split {
            Split::Slabs { k } => {
                let x0 = p as u32 * k;
                let x1 = x0.saturating_add(k).min(d.x);
                (UVec3::new(x0, 0, 0), UVec3::new(x1, d.y, d.z))
            }
            Split::Rows { k, per_slab } => {
                let x = (p / per_slab as u64) as u32;
                let y0 = (p % per_slab as u64) as u32 * k;
                let y1 = y0.saturating_add(k).min(d.y);
                (UVec3::new(x, y0, 0), UVec3::new(x + 1, y1, d.z))
            }
            Split::Runs { k, per_row } => {
                let row = p / per_row as u64;
                let (x, y) = ((row / d.y as u64) as u32, (row % d.y as u64) as u32);
                let z0 = (p % per_row as u64) as u32 * k;
                let z1 = z0.saturating_add(k).min(d.z);
                (UVec3::new(x, y, z0), UVec3::new(x + 1, y + 1, z1))
            }
        };
        Region {
            lo,
            hi,
            stride_x,
            stride_y,
        }
    }

    /// The voxels of brick `brick`'s local x-planes `x0..x1` (clipped to the
    /// grid), laid out as in the brick: strides B², B.
    fn brick_region(&self, grid: &BrickGrid, brick: u64, x0: u32, x1: u32) -> Region {
        let n = grid.count;
        let k = (brick % n.z as u64) as u32;
        let j = (brick / n.z as u64 % n.y as u64) as u32;
        let i = (brick / (n.z as u64 * n.y as u64)) as u32;
        let b = grid.side;
        let origin = UVec3::new(i, j, k) * (b - 1);
        let lo = origin.saturating_add(UVec3::new(x0, 0, 0));
        let hi = origin.saturating_add(UVec3::new(x1, b, b)).min(self.dims);
        Region {
            lo,
            hi,
            stride_x: (b * b) as usize,
            stride_y: b as usize,
        }
    }

    /// The pieces of batch `batch`, with their byte lengths, in file order.
    fn pieces(&self, batch: u64) -> Vec<(Piece, usize)> {
        let mut out = Vec::new();
        match self.kind {
            Kind::Linear {
                split,
                pieces,
                pieces_per_batch,
            } => {
                let first = batch * pieces_per_batch;
                for p in first..(first + pieces_per_batch).min(pieces) {
                    let r = self.linear_region(split, p);
                    let len = (r.hi - r.lo).as_u64vec3().element_product() as usize;
                    out.push((Piece::Region(r), len));
                }
            }
            Kind::Bricked {
                grid,
                bricks,
                bricks_per_batch,
                bricks_per_piece,
                planes_per_piece,
            } => {
                let first = batch * bricks_per_batch;
                let end = (first + bricks_per_batch).min(bricks);
                let len = grid.brick_len() as usize;
                if bricks_per_piece > 0 {
                    let mut b = first;
                    while b < end {
                        let count = bricks_per_piece.min(end - b);
                        out.push((Piece::Bricks { first: b, count }, len * count as usize));
                        b += count;
                    }
                } else {
                    let side = grid.side;
                    let plane = (side * side) as usize;
                    for brick in first..end {
                        let mut x0 = 0;
                        while x0 < side {
                            let x1 = (x0 + planes_per_piece).min(side);
                            out.push((
                                Piece::BrickPlanes { brick, x0, x1 },
                                plane * (x1 - x0) as usize,
                            ));
                            x0 = x1;
                        }
                    }
                }
            }
        }
        out
    }

    /// Byte length of batch `batch`.
    pub fn batch_len(&self, batch: u64) -> usize {
        self.pieces(batch).iter().map(|(_, len)| len).sum()
    }

    /// Fills `buf` with the samples of batch `batch`, in file order, using all
    /// of rayon's threads. Once `cancelled()` is true the remaining pieces are
    /// skipped (the batch is then incomplete and must not be written).
    pub fn fill_batch(
        &self,
        batch: u64,
        field: &dyn Field,
        buf: &mut Vec<u8>,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) {
        let pieces = self.pieces(batch);
        let len: usize = pieces.iter().map(|(_, len)| len).sum();
        // Keeps the capacity of a recycled buffer; every piece zeroes its own part.
        buf.resize(len, 0);
        let mut rest: &mut [u8] = buf;
        let mut slices = Vec::with_capacity(pieces.len());
        for (_, len) in &pieces {
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(*len);
            slices.push(head);
            rest = tail;
        }
        pieces
            .into_par_iter()
            .zip(slices)
            .for_each(|((piece, _), out)| {
                if !cancelled() {
                    self.fill_piece(piece, field, out);
                }
            });
    }

    fn fill_piece(&self, piece: Piece, field: &dyn Field, out: &mut [u8]) {
        out.fill(0);
        match (piece, self.kind) {
            (Piece::Region(r), _) => field.fill(&r, out),
            (Piece::Bricks { first, count }, Kind::Bricked { grid, .. }) => {
                let len = grid.brick_len() as usize;
                debug_assert_eq!(out.len(), len * count as usize);
                for (i, brick) in out.chunks_mut(len).enumerate() {
                    let r = self.brick_region(&grid, first + i as u64, 0, grid.side);
                    if !r.is_empty() {
                        field.fill(&r, brick);
                    }
                }
            }
            (Piece::BrickPlanes { brick, x0, x1 }, Kind::Bricked { grid, .. }) => {
                let r = self.brick_region(&grid, brick, x0, x1);
                if !r.is_empty() {
                    field.fill(&r, out);
                }
            }
            // Brick pieces only come from bricked plans.
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Value = a hash of the voxel coordinate, never 0.
    struct Coords;
    fn code(x: u32, y: u32, z: u32) -> u8 {
        ((x.wrapping_mul(73) ^ y.wrapping_mul(151) ^ z.wrapping_mul(19)) % 255 + 1) as u8
    }
    impl Field for Coords {
        fn fill(&self, region: &Region, out: &mut [u8]) {
            region.for_each_row(out, |x, y, row| {
                for (i, v) in row.iter_mut().enumerate() {
                    *v = code(x, y, region.lo.z + i as u32);
                }
            });
        }
    }

    fn whole_file(plan: &Plan) -> Vec<u8> {
        let mut all = Vec::new();
        let mut buf = Vec::new();
        for b in 0..plan.batch_count() {
            plan.fill_batch(b, &Coords, &mut buf, &|| false);
            assert_eq!(buf.len(), plan.batch_len(b));
            all.extend_from_slice(&buf);
        }
        assert_eq!(all.len() as u64, plan.sample_bytes());
        all
    }

    fn check(dims: UVec3, layout: VolLayout) {
        let plan = Plan::new(dims, layout).unwrap();
        let data = whole_file(&plan);
        match layout {
            VolLayout::Linear => {
                for (i, &v) in data.iter().enumerate() {
                    let i = i as u64;
                    let (x, y, z) = (
                        i / (dims.y as u64 * dims.z as u64),
                        i / dims.z as u64 % dims.y as u64,
                        i % dims.z as u64,
                    );
                    assert_eq!(v, code(x as u32, y as u32, z as u32), "{dims} at {i}");
                }
            }
            VolLayout::Bricked { side } => {
                let grid = BrickGrid::new(dims, side as u32).unwrap();
                for (i, &v) in data.iter().enumerate() {
                    let want = grid
                        .voxel_at(i as u64, dims)
                        .map_or(0, |p| code(p.x, p.y, p.z));
                    assert_eq!(v, want, "{dims} B={side} at {i}");
                }
            }
        }
    }

    #[test]
    fn linear_orders_cover_the_file_in_order() {
        // Slabs, rows and runs of z.
        check(UVec3::new(37, 20, 9), VolLayout::Linear);
        check(UVec3::new(3, 1500, 700), VolLayout::Linear);
        check(UVec3::new(2, 3, 600_000), VolLayout::Linear);
        check(UVec3::new(1, 1, 1), VolLayout::Linear);
    }

    #[test]
    fn bricked_orders_cover_the_file_in_order() {
        for side in [2u8, 5, 16] {
            check(UVec3::new(37, 20, 9), VolLayout::Bricked { side });
        }
        check(UVec3::new(1, 1, 1), VolLayout::Bricked { side: 3 });
        // Bricks larger than a piece are split into x-planes.
        check(UVec3::new(130, 70, 90), VolLayout::Bricked { side: 120 });
    }

    #[test]
    fn oversized_volumes_have_no_plan() {
        assert!(Plan::new(UVec3::splat(u32::MAX), VolLayout::Linear).is_none());
        assert!(Plan::new(UVec3::splat(u32::MAX), VolLayout::Bricked { side: 2 }).is_none());
        assert!(Plan::new(UVec3::new(0, 1, 1), VolLayout::Linear).is_none());
    }
}

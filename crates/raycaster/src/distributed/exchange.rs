//! Sort-last compositing across ranks: which pixels of which partial image
//! go where, and in what order they are merged, for the three methods a
//! transport can run (the transport itself, MPI in `vol_app`, is not here).
//!
//! Every method starts from the same facts, which every rank can know
//! after one all-gather of the parts' screen rectangles: the rectangles,
//! the k-d tree ([`Partition`]) and the camera. From them each rank
//! computes the whole exchange (who sends what to whom, every message's
//! size), so no sizes travel.
//!
//! - **Gather** ([`CompositeMethod::Gather`]): every rank sends its
//!   partial image (24 bytes a pixel of its rectangle) to rank 0, which
//!   merges them all in visibility order ([`Compositor::composite`]). Rank
//!   0 receives and merges everything: its cost grows with P.
//! - **Direct send** ([`DirectSend`]): the union of the rectangles is cut
//!   into P horizontal bands, band `o` owned by rank `o`. Every rank sends
//!   each owner the part of its image inside the owner's band (at most
//!   P − 1 messages); the owner merges the P fragments of each of its
//!   pixels in visibility order — the same merges, in the same order, as
//!   the gather, so the frame is bit-identical — and rank 0 gathers the
//!   finished bands as RGB (3 bytes a pixel).
//! - **Binary swap** ([`BinarySwap`], P a power of two): at round `i`
//!   (from the deepest split of the k-d tree up to the root), each rank
//!   pairs with the rank in the same position on the other side of the
//!   split, the pair's current screen region is halved (along its longer
//!   side; the lower side's rank keeps the first half), each sends its
//!   partner the half it gives up and merges the half it keeps with the
//!   partner's, the side of the split that holds the eye in front. After
//!   log₂ P rounds each rank holds a finished 1/P of the region; rank 0
//!   gathers them as RGB. Only the bounding rectangle of the data a rank
//!   holds inside the half it gives up is sent (a rank's own rectangle at
//!   first), so early rounds send less than half the region. For other P
//!   the tree's two sides differ in size and [`CompositePlan::new`] falls
//!   back to direct send.
//!
//! **Exactness.** Direct send performs, for every pixel, the gather's
//! merges in the gather's order: identical bytes. Binary swap merges the
//! same fragments in the same visibility order but grouped as a tree
//! (`(f₀∘f₁)∘(f₂∘f₃)` instead of `((f₀∘f₁)∘f₂)∘f₃`): MIP, MinIP, iso and
//! pixels covered by at most two parts are identical; DVR's "over" and
//! avg's sums are associative only up to f32 rounding (a level at most),
//! and with early ray termination the opacity test sees the sub-tree's
//! opacity instead of the running one (a difference below
//! `1 − threshold`, like ERT across parts, see [`super::composite`]).

use super::composite::Compositor;
use super::partition::{Partition, SwapPair};
use super::render::PartialImage;
use crate::camera::{Camera, PixelRect};
use crate::error::{Error, Result};
use crate::volume::Grid;

/// How the ranks' partial images become the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum CompositeMethod {
    /// Everything to rank 0, which merges it.
    Gather,
    /// Fragments to the owners of P horizontal bands; RGB bands to rank 0.
    #[default]
    DirectSend,
    /// log₂ P pairwise exchanges of halves along the k-d tree (P a power
    /// of two, else direct send); RGB pieces to rank 0.
    BinarySwap,
}

impl CompositeMethod {
    /// The name the command line and `--stats` use.
    pub fn name(self) -> &'static str {
        match self {
            CompositeMethod::Gather => "gather",
            CompositeMethod::DirectSend => "direct-send",
            CompositeMethod::BinarySwap => "binary-swap",
        }
    }
}

/// The bounding rectangle of `rects` (empty when all are).
pub fn union_rect(rects: &[PixelRect]) -> PixelRect {
    rects
        .iter()
        .fold(PixelRect::default(), |u, r| u.bounding(r))
}

/// Direct send's bands: the rows of the union of the parts' rectangles cut
/// into one band per rank, as even as whole rows allow.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectSend {
    bands: Vec<PixelRect>,
}

impl DirectSend {
    /// The bands for ranks whose parts cover `rects` (one per rank).
    pub fn new(rects: &[PixelRect]) -> DirectSend {
        let u = union_rect(rects);
        let p = rects.len() as u64;
        let h = u64::from(u.y1 - u.y0);
        let bands = (0..p)
            .map(|o| {
                let band = PixelRect {
                    x0: u.x0,
                    x1: u.x1,
                    y0: u.y0 + (h * o / p) as u32,
                    y1: u.y0 + (h * (o + 1) / p) as u32,
                };
                if band.is_empty() {
                    PixelRect::default()
                } else {
                    band
                }
            })
            .collect();
        DirectSend { bands }
    }

    /// Rank `o`'s band.
    pub fn band(&self, o: usize) -> PixelRect {
        self.bands[o]
    }

    /// All bands, by rank.
    pub fn bands(&self) -> &[PixelRect] {
        &self.bands
    }
}

/// One round of binary swap for one rank.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SwapRound {
    /// The rank it exchanges with.
    pub partner: usize,
    /// Whether its side of the round's split is in front.
    pub front: bool,
    /// The half of the pair's region it keeps (the partner keeps the
    /// other).
    pub keep: PixelRect,
    /// What it sends: the bounding rectangle of its data in the other half.
    pub send: PixelRect,
    /// What it receives: the partner's data in `keep`.
    pub receive: PixelRect,
}

/// Binary swap's whole schedule: every rank's rounds and final region.
#[derive(Debug, Clone, PartialEq)]
pub struct BinarySwap {
    rounds: Vec<Vec<SwapRound>>,
    regions: Vec<PixelRect>,
}

impl BinarySwap {
    /// The schedule for `pairs` ([`Partition::swap_schedule`]) and the
    /// parts' screen rectangles `rects`.
    pub fn new(pairs: &[Vec<SwapPair>], rects: &[PixelRect]) -> Result<BinarySwap> {
        let p = rects.len();
        let bad = |m: String| Error::option("binary swap", m);
        if pairs.len() != p {
            return Err(bad(format!("{} schedules for {p} ranks", pairs.len())));
        }
        let levels = pairs.first().map_or(0, Vec::len);
        if pairs.iter().any(|s| s.len() != levels) || p != 1 << levels {
            return Err(bad(format!("{p} ranks are not a balanced tree")));
        }
        let mut region = vec![union_rect(rects); p];
        // The bounding rectangle of the data each rank holds in its region.
        let mut valid = rects.to_vec();
        let mut rounds = vec![Vec::with_capacity(levels); p];
        // `level` indexes every rank's schedule (`pairs[r][level]`), not
        // one sequence.
        #[allow(clippy::needless_range_loop)]
        for level in 0..levels {
            let mut next_region = region.clone();
            let mut next_valid = valid.clone();
            for r in 0..p {
                let pair = pairs[r][level];
                let q = pair.partner;
                if region[q] != region[r] || pairs[q][level].partner != r {
                    return Err(bad(format!(
                        "ranks {r} and {q} do not share a region at round {level}"
                    )));
                }
                let (first, second) = halves(region[r]);
                let (keep, give) = if pair.lower {
                    (first, second)
                } else {
                    (second, first)
                };
                let send = valid[r].intersect(&give);
                let receive = valid[q].intersect(&keep);
                next_region[r] = keep;
                next_valid[r] = valid[r].intersect(&keep).bounding(&receive);
                rounds[r].push(SwapRound {
                    partner: q,
                    front: pair.front,
                    keep,
                    send,
                    receive,
                });
            }
            region = next_region;
            valid = next_valid;
        }
        Ok(BinarySwap {
            rounds,
            regions: region,
        })
    }

    /// Rank `r`'s rounds, first to last.
    pub fn rounds(&self, r: usize) -> &[SwapRound] {
        &self.rounds[r]
    }

    /// The region rank `r` holds finished after the last round.
    pub fn final_region(&self, r: usize) -> PixelRect {
        self.regions[r]
    }

    /// The final regions, by rank (they tile the union of the parts'
    /// rectangles).
    pub fn final_regions(&self) -> &[PixelRect] {
        &self.regions
    }

    /// One round on one rank: `mine` (what the rank holds) merged with
    /// `incoming` (the partner's [`SwapRound::receive`] data) over the
    /// kept half, the front side first.
    pub fn step(
        compositor: &Compositor,
        round: &SwapRound,
        mine: &PartialImage,
        incoming: &PartialImage,
    ) -> Result<PartialImage> {
        // Both lie in the kept half, and merge_over reads only `rect`.
        let rect = mine.rect.intersect(&round.keep).bounding(&incoming.rect);
        let (front, back) = if round.front {
            (mine, incoming)
        } else {
            (incoming, mine)
        };
        compositor.merge_over(rect, mine.width, mine.height, [front, back])
    }
}

/// `r` halved along its longer side (columns on a tie): the first and the
/// second half.
fn halves(r: PixelRect) -> (PixelRect, PixelRect) {
    let (mut a, mut b) = (r, r);
    if r.x1 - r.x0 >= r.y1 - r.y0 {
        let mid = r.x0 + (r.x1 - r.x0) / 2;
        a.x1 = mid;
        b.x0 = mid;
    } else {
        let mid = r.y0 + (r.y1 - r.y0) / 2;
        a.y1 = mid;
        b.y0 = mid;
    }
    let norm = |h: PixelRect| {
        if h.is_empty() {
            PixelRect::default()
        } else {
            h
        }
    };
    (norm(a), norm(b))
}

/// One frame's compositing, as every rank computes it from the parts'
/// rectangles, the partition and the camera.
#[derive(Debug, Clone)]
pub enum CompositePlan {
    /// Everything to rank 0 (merged in `order`).
    Gather {
        /// Regions front to back.
        order: Vec<usize>,
    },
    /// Bands to owners (merged in `order`), then RGB to rank 0.
    DirectSend {
        /// Regions front to back.
        order: Vec<usize>,
        /// The bands.
        bands: DirectSend,
    },
    /// Pairwise rounds, then RGB to rank 0.
    BinarySwap(BinarySwap),
}

impl CompositePlan {
    /// The plan of `method` for the parts of `partition` (region `r` is
    /// rank `r`) covering `rects`, seen by `camera` over `grid`. Binary
    /// swap falls back to direct send when the k-d tree is not balanced
    /// (P not a power of two).
    pub fn new(
        method: CompositeMethod,
        partition: &Partition,
        camera: &Camera,
        grid: &Grid,
        rects: &[PixelRect],
    ) -> Result<CompositePlan> {
        if rects.len() != partition.regions().len() {
            return Err(Error::option(
                "ranks",
                format!(
                    "{} rectangles for {} regions",
                    rects.len(),
                    partition.regions().len()
                ),
            ));
        }
        let order = || super::visibility_order(partition, camera, grid);
        Ok(match method {
            CompositeMethod::Gather => CompositePlan::Gather { order: order() },
            CompositeMethod::BinarySwap => {
                let (projection, view) = super::view_of(camera, grid);
                match partition.swap_schedule(projection, view) {
                    Some(pairs) => CompositePlan::BinarySwap(BinarySwap::new(&pairs, rects)?),
                    None => CompositePlan::DirectSend {
                        order: order(),
                        bands: DirectSend::new(rects),
                    },
                }
            }
            CompositeMethod::DirectSend => CompositePlan::DirectSend {
                order: order(),
                bands: DirectSend::new(rects),
            },
        })
    }

    /// The method this plan runs (binary swap's fallback is direct send).
    pub fn method(&self) -> CompositeMethod {
        match self {
            CompositePlan::Gather { .. } => CompositeMethod::Gather,
            CompositePlan::DirectSend { .. } => CompositeMethod::DirectSend,
            CompositePlan::BinarySwap(_) => CompositeMethod::BinarySwap,
        }
    }

    /// The regions each rank sends to rank 0 as RGB at the end (direct
    /// send, binary swap); `None` for gather.
    pub fn final_regions(&self) -> Option<&[PixelRect]> {
        match self {
            CompositePlan::Gather { .. } => None,
            CompositePlan::DirectSend { bands, .. } => Some(bands.bands()),
            CompositePlan::BinarySwap(s) => Some(s.final_regions()),
        }
    }
}

/// Bytes and messages of one frame's compositing, per rank (partial
/// images as [`PartialImage::encode`] floats, 4 bytes each; final pieces
/// as RGB8; a rank's messages to itself not counted).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Bytes each rank sends.
    pub sent: Vec<u64>,
    /// Bytes each rank receives.
    pub received: Vec<u64>,
    /// Messages each rank sends.
    pub messages: Vec<u64>,
}

impl Traffic {
    fn new(p: usize) -> Traffic {
        Traffic {
            sent: vec![0; p],
            received: vec![0; p],
            messages: vec![0; p],
        }
    }

    fn add(&mut self, from: usize, to: usize, bytes: u64) {
        if from != to {
            self.sent[from] += bytes;
            self.received[to] += bytes;
            self.messages[from] += 1;
        }
    }
}

/// A frame composited by [`simulate`].
#[derive(Debug, Clone)]
pub struct Simulated {
    /// RGB8, row-major.
    pub rgb: Vec<u8>,
    /// The method that ran.
    pub method: CompositeMethod,
    /// What travelled.
    pub traffic: Traffic,
}

/// Runs `method` for P simulated ranks in one process: `images[r]` is rank
/// `r`'s partial image (region `r` of `partition`). Every message goes
/// through [`PartialImage::encode`] and [`PartialImage::decode`] as it
/// would on the wire. The reference the transport is tested against.
pub fn simulate(
    method: CompositeMethod,
    compositor: &Compositor,
    partition: &Partition,
    camera: &Camera,
    grid: &Grid,
    images: &[PartialImage],
) -> Result<Simulated> {
    let p = images.len();
    let Some(first) = images.first() else {
        return Err(Error::option("ranks", "nothing to composite"));
    };
    let (width, height) = (first.width, first.height);
    let rects: Vec<PixelRect> = images.iter().map(|i| i.rect).collect();
    let plan = CompositePlan::new(method, partition, camera, grid, &rects)?;
    let mut traffic = Traffic::new(p);
    // A message from `from` to `to` (none for an empty rectangle, which
    // the receiver knows from the plan, or to itself).
    let wire = |traffic: &mut Traffic, from: usize, to: usize, image: PartialImage| {
        if image.rect.is_empty() || from == to {
            return Ok(image);
        }
        let floats = image.encode();
        traffic.add(from, to, 4 * floats.len() as u64);
        PartialImage::decode(&floats)
    };
    let pieces: Vec<Vec<u8>> = match &plan {
        CompositePlan::Gather { order } => {
            let mut got = Vec::with_capacity(p);
            for (r, image) in images.iter().enumerate() {
                got.push(wire(&mut traffic, r, 0, image.clone())?);
            }
            let (_, _, rgb) = compositor.composite(order.iter().map(|&i| &got[i]))?;
            return Ok(Simulated {
                rgb,
                method: plan.method(),
                traffic,
            });
        }
        CompositePlan::DirectSend { order, bands } => {
            // inbox[o][s]: what owner o received from rank s.
            let mut inbox: Vec<Vec<PartialImage>> = vec![Vec::with_capacity(p); p];
            for (s, image) in images.iter().enumerate() {
                for (o, band) in bands.bands().iter().enumerate() {
                    inbox[o].push(wire(&mut traffic, s, o, image.crop(band))?);
                }
            }
            inbox
                .iter()
                .enumerate()
                .map(|(o, got)| {
                    let band = bands.band(o);
                    let merged = compositor.merge_over(
                        band,
                        width,
                        height,
                        order.iter().map(|&i| &got[i]),
                    )?;
                    Ok(compositor.resolve_rect(&merged, band))
                })
                .collect::<Result<_>>()?
        }
        CompositePlan::BinarySwap(swap) => {
            let mut held: Vec<PartialImage> = images.to_vec();
            let levels = swap.rounds(0).len();
            for level in 0..levels {
                let mut outgoing = Vec::with_capacity(p);
                for (r, image) in held.iter().enumerate() {
                    let round = swap.rounds(r)[level];
                    let piece = wire(&mut traffic, r, round.partner, image.crop(&round.send))?;
                    if piece.rect != swap.rounds(round.partner)[level].receive {
                        return Err(Error::option("binary swap", "sent rectangle mismatch"));
                    }
                    outgoing.push(piece);
                }
                held = held
                    .iter()
                    .enumerate()
                    .map(|(r, image)| {
                        let round = swap.rounds(r)[level];
                        BinarySwap::step(compositor, &round, image, &outgoing[round.partner])
                    })
                    .collect::<Result<_>>()?;
            }
            held.iter()
                .enumerate()
                .map(|(r, image)| compositor.resolve_rect(image, swap.final_region(r)))
                .collect()
        }
    };
    let regions = plan.final_regions().unwrap_or(&[]);
    for (r, piece) in pieces.iter().enumerate() {
        if !piece.is_empty() {
            traffic.add(r, 0, piece.len() as u64);
        }
    }
    let rgb = compositor.assemble(
        width,
        height,
        regions
            .iter()
            .copied()
            .zip(pieces.iter().map(Vec::as_slice)),
    )?;
    Ok(Simulated {
        rgb,
        method: plan.method(),
        traffic,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;
    use crate::distributed::CellWeights;
    use crate::integrator::{Fragment, RenderMode};
    use crate::transfer::TransferFunction;
    use glam::{UVec3, Vec3, Vec4};
    use std::time::Duration;

    /// A random partial image over a random rectangle of a `w`×`h` frame,
    /// with fragments plausible for `mode` (some pixels empty).
    fn random_image(rng: &mut fastrand::Rng, mode: RenderMode, w: u32, h: u32) -> PartialImage {
        let (x0, y0) = (rng.u32(0..w), rng.u32(0..h));
        let rect = PixelRect {
            x0,
            y0,
            x1: rng.u32(x0..=w),
            y1: rng.u32(y0..=h),
        };
        let rect = if rect.is_empty() {
            PixelRect::default()
        } else {
            rect
        };
        let fragments = (0..rect.area())
            .map(|_| {
                if rng.f32() < 0.2 {
                    return Fragment::default();
                }
                match mode {
                    RenderMode::Dvr => {
                        let a = if rng.f32() < 0.2 { 1.0 } else { rng.f32() };
                        let c = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * a;
                        Fragment {
                            rgba: c.extend(a),
                            value: 0.0,
                            count: 0,
                        }
                    }
                    RenderMode::Iso => Fragment {
                        rgba: Vec4::new(rng.f32(), rng.f32(), rng.f32(), 1.0),
                        value: rng.f32() * 100.0,
                        count: 1,
                    },
                    RenderMode::Avg => Fragment {
                        rgba: Vec4::ZERO,
                        value: rng.f32() * 2000.0,
                        count: rng.u32(1..20),
                    },
                    _ => Fragment {
                        rgba: Vec4::ZERO,
                        value: rng.f32() * 255.0,
                        count: 1,
                    },
                }
            })
            .collect();
        PartialImage {
            width: w,
            height: h,
            rect,
            fragments,
            samples: 0,
            time: Duration::ZERO,
        }
    }

    fn compositor(mode: RenderMode, ert: Option<f32>) -> Compositor {
        Compositor {
            mode,
            tf: TransferFunction::preset("ramp", crate::sample::SampleType::U8).unwrap(),
            ert,
            avg_norm: 255.0,
            background: Vec3::new(0.1, 0.2, 0.3),
        }
    }

    fn cameras(grid: &Grid) -> Vec<Camera> {
        let b = grid.bounds();
        let c = b.center();
        let d = (b.max - b.min).length();
        let mut v = vec![
            Camera::look_at(c + Vec3::new(0.7, 0.5, 0.8) * d, c, 37, 29),
            Camera::look_at(c - Vec3::new(0.2, 0.9, 0.3) * d, c, 37, 29),
        ];
        let inner = |u: Vec3| b.min + u * (b.max - b.min);
        v.push(Camera::look_at(
            inner(Vec3::new(0.6, 0.4, 0.7)),
            inner(Vec3::new(0.2, 0.5, 0.3)),
            37,
            29,
        ));
        let mut ortho = Camera::look_at(c + Vec3::new(-0.3, 0.2, 1.0) * d, c, 37, 29);
        ortho.projection = Projection::Orthographic;
        v.push(ortho);
        v
    }

    /// Max difference in levels between two RGB8 images.
    fn max_diff(a: &[u8], b: &[u8]) -> u8 {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn halves_tile_the_region() {
        for r in [
            PixelRect {
                x0: 3,
                y0: 5,
                x1: 20,
                y1: 9,
            },
            PixelRect {
                x0: 0,
                y0: 0,
                x1: 1,
                y1: 7,
            },
            PixelRect {
                x0: 0,
                y0: 0,
                x1: 1,
                y1: 1,
            },
        ] {
            let (a, b) = halves(r);
            assert_eq!(a.area() + b.area(), r.area());
            assert_eq!(a.bounding(&b), r);
            assert!(a.intersect(&b).is_empty());
        }
    }

    #[test]
    fn bands_tile_the_union() {
        let rects = [
            PixelRect {
                x0: 10,
                y0: 4,
                x1: 30,
                y1: 9,
            },
            PixelRect {
                x0: 2,
                y0: 7,
                x1: 12,
                y1: 40,
            },
            PixelRect::default(),
        ];
        let d = DirectSend::new(&rects);
        let u = union_rect(&rects);
        assert_eq!(
            u,
            PixelRect {
                x0: 2,
                y0: 4,
                x1: 30,
                y1: 40
            }
        );
        assert_eq!(d.bands().iter().map(PixelRect::area).sum::<u64>(), u.area());
        assert_eq!(d.bands()[0].y0, u.y0);
        assert_eq!(d.bands()[2].y1, u.y1);
        // More ranks than rows: some bands empty, still a tiling.
        let d = DirectSend::new(
            &[PixelRect {
                x0: 0,
                y0: 0,
                x1: 5,
                y1: 2,
            }; 5],
        );
        assert_eq!(d.bands().iter().map(PixelRect::area).sum::<u64>(), 10);
    }

    #[test]
    fn swap_schedule_exists_for_powers_of_two_only() {
        let dims = UVec3::new(64, 48, 40);
        for parts in 1..=9usize {
            let p = Partition::kd(dims, Vec3::ONE, parts, &CellWeights::voxels(dims)).unwrap();
            let s = p.swap_schedule(Projection::Perspective, Vec3::splat(-3.0));
            assert_eq!(s.is_some(), parts.is_power_of_two(), "{parts}");
            if let Some(s) = s {
                for (r, rounds) in s.iter().enumerate() {
                    assert_eq!(rounds.len(), parts.trailing_zeros() as usize);
                    for (i, pair) in rounds.iter().enumerate() {
                        // Regions are numbered in the tree's order: the
                        // partner at the i-th round from the bottom differs
                        // in bit i.
                        assert_eq!(pair.partner, r ^ (1 << i), "{parts}: {r} round {i}");
                        assert_ne!(pair.front, s[pair.partner][i].front);
                    }
                }
            }
        }
    }

    /// Every method against the gather (today's compositor) on random
    /// partial images, P = 1..8, every mode, ERT on and off, cameras
    /// outside and inside and orthographic. Direct send (and binary swap's
    /// fallback) must be identical; binary swap identical for MIP, MinIP
    /// and iso, within a level for DVR without ERT and avg, within the ERT
    /// bound with it.
    #[test]
    fn methods_match_the_gather() {
        let dims = UVec3::new(50, 40, 30);
        let grid = Grid::new(dims, Vec3::new(1.0, 1.2, 0.9));
        let mut rng = fastrand::Rng::with_seed(16);
        let modes = [
            (RenderMode::Dvr, None),
            (RenderMode::Dvr, Some(0.99)),
            (RenderMode::Mip, None),
            (RenderMode::Minip, None),
            (RenderMode::Avg, None),
            (RenderMode::Iso, None),
        ];
        for parts in 1..=8usize {
            let partition =
                Partition::kd(dims, grid.spacing, parts, &CellWeights::voxels(dims)).unwrap();
            for camera in cameras(&grid) {
                for (mode, ert) in modes {
                    let c = compositor(mode, ert);
                    let images: Vec<_> = (0..parts)
                        .map(|_| random_image(&mut rng, mode, camera.width, camera.height))
                        .collect();
                    let gather = simulate(
                        CompositeMethod::Gather,
                        &c,
                        &partition,
                        &camera,
                        &grid,
                        &images,
                    )
                    .unwrap();
                    let order = crate::distributed::visibility_order(&partition, &camera, &grid);
                    let (_, _, reference) = c.composite(order.iter().map(|&i| &images[i])).unwrap();
                    assert_eq!(gather.rgb, reference);
                    let direct = simulate(
                        CompositeMethod::DirectSend,
                        &c,
                        &partition,
                        &camera,
                        &grid,
                        &images,
                    )
                    .unwrap();
                    assert_eq!(
                        direct.rgb, reference,
                        "direct send, {parts} parts, {mode:?}"
                    );
                    let swap = simulate(
                        CompositeMethod::BinarySwap,
                        &c,
                        &partition,
                        &camera,
                        &grid,
                        &images,
                    )
                    .unwrap();
                    let what = format!("binary swap, {parts} parts, {mode:?} {ert:?}");
                    if !parts.is_power_of_two() {
                        assert_eq!(swap.method, CompositeMethod::DirectSend);
                        assert_eq!(swap.rgb, reference, "{what}");
                        continue;
                    }
                    assert_eq!(swap.method, CompositeMethod::BinarySwap);
                    let limit = match (mode, ert) {
                        (RenderMode::Dvr, Some(t)) => (255.0 * (1.0 - t)).ceil() as u8 + 1,
                        (RenderMode::Dvr | RenderMode::Avg, None) => 1,
                        _ => 0,
                    };
                    let d = max_diff(&swap.rgb, &reference);
                    assert!(d <= limit, "{what}: {d} levels");
                    if parts <= 2 {
                        assert_eq!(swap.rgb, reference, "{what}");
                    }
                }
            }
        }
    }

    #[test]
    fn traffic_follows_the_method() {
        // Four parts each covering a quarter of a 64x64 frame exactly.
        let (w, h) = (64u32, 64u32);
        let dims = UVec3::new(64, 64, 64);
        let grid = Grid::new(dims, Vec3::ONE);
        let partition = Partition::kd(dims, Vec3::ONE, 4, &CellWeights::voxels(dims)).unwrap();
        let camera = Camera::look_at(Vec3::new(32.0, 32.0, 200.0), Vec3::splat(32.0), w, h);
        let full = PixelRect {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        };
        let images: Vec<_> = (0..4)
            .map(|_| PartialImage {
                width: w,
                height: h,
                rect: full,
                fragments: vec![Fragment::default(); (w * h) as usize],
                samples: 0,
                time: Duration::ZERO,
            })
            .collect();
        let c = compositor(RenderMode::Dvr, None);
        let px = u64::from(w * h);
        let frag = |n: u64| 4 * (6 + 6 * n);
        let t = |m| {
            simulate(m, &c, &partition, &camera, &grid, &images)
                .unwrap()
                .traffic
        };
        let g = t(CompositeMethod::Gather);
        assert_eq!(g.sent, vec![0, frag(px), frag(px), frag(px)]);
        assert_eq!(g.received[0], 3 * frag(px));
        let d = t(CompositeMethod::DirectSend);
        // 3 bands of a quarter to others, then the RGB band to rank 0.
        assert_eq!(d.sent[1], 3 * frag(px / 4) + 3 * px / 4);
        assert_eq!(d.messages, vec![3, 4, 4, 4]);
        let s = t(CompositeMethod::BinarySwap);
        // Half, then a quarter, then the RGB quarter to rank 0.
        assert_eq!(s.sent[1], frag(px / 2) + frag(px / 4) + 3 * px / 4);
        assert_eq!(s.messages, vec![2, 3, 3, 3]);
    }
}

//! `vol_app render FILE --distributed`: sort-last distributed rendering
//! over MPI (`mpirun -n P vol_app render FILE --distributed ...`).
//!
//! Every rank reads the file's header, builds the same k-d partition (one
//! region per rank) and reads its region and ghost layer
//! ([`raycaster::distributed`]), and renders it into a partial image of
//! fragments. `--balance occupancy` (the default) balances the macrocells
//! the frame leaves occupied: the whole volume's macrocell ranges come
//! from the volume's cache when every rank finds it, else from a first
//! pass (each rank reads a voxel-balanced region, builds its macrocells'
//! ranges, an all-reduce combines them, rank 0 writes the cache);
//! `--balance voxels` balances voxel count. `--composite` says how the partial images become the frame
//! ([`raycaster::distributed::exchange`] computes who sends what to whom
//! from an all-gather of the parts' screen rectangles; this module moves
//! the bytes): `gather` (all to rank 0, which merges them in visibility
//! order), `direct-send` (an all-to-all-v of each rank's fragments to the
//! owners of P bands of rows, which merge them; the finished bands
//! gathered to rank 0 as RGB) or `binary-swap` (log₂ P rounds of
//! send-receive with the partner across a split of the k-d tree; the
//! finished pieces gathered as RGB; direct send when P is not a power of
//! two). Rank 0 writes the PNG and the `--stats` object (with `ranks`,
//! `rank_ms`, the bytes each rank read, the compositing time and the bytes
//! and messages each rank sends and receives per frame).
//!
//! No rank may wait for one that failed: opening is followed by an
//! all-reduce of an "ok" flag, so when any rank cannot open its part (a
//! missing file, a format that cannot be read in part), every rank returns
//! an error and exits non-zero. The transport is the `mpi` feature (rsmpi
//! over the system's MPI library); without it `--distributed` is an error.

use crate::anyhow_like::Error;
use crate::cli::RenderArgs;

/// Without the `mpi` feature: the error that says how to get it.
#[cfg(not(feature = "mpi"))]
pub fn run(_args: &RenderArgs) -> Result<(), Error> {
    Err("--distributed: this vol_app was built without MPI; rebuild with the mpi feature \
         (cargo build --release --workspace --features vol_app/mpi; needs an MPI library, libclang and pkg-config)"
        .into())
}

#[cfg(feature = "mpi")]
pub use transport::run;

#[cfg(feature = "mpi")]
mod transport {
    use std::time::Instant;

    use mpi::collective::SystemOperation;
    use mpi::datatype::{Partition as Parts, PartitionMut};
    use mpi::topology::SimpleCommunicator;
    use mpi::traits::*;
    use serde::Serialize;

    use raycaster::accel::MacrocellGrid;
    use raycaster::camera::PixelRect;
    use raycaster::distributed::{
        self, Balance, BinarySwap, CellWeights, CompositeMethod, CompositePlan, Compositor,
        PartFile, PartRenderer, PartScene, PartialImage, Partition,
    };
    use raycaster::prelude::*;
    use raycaster::scene::CacheReport;

    use super::{Error, RenderArgs};
    use crate::render_cmd::{camera_for, ms, render_options, transfer_function};
    use crate::stats::{median, peak_rss_mb, print_json};

    /// Test hook: the rank named here fails to open its part, as a rank
    /// on a node without the file would (`scripts/mpi_test.sh`).
    const FAIL_RANK_VAR: &str = "VOL_APP_DISTRIBUTED_FAIL_RANK";

    /// The `--stats` object of a distributed run.
    #[derive(Debug, Serialize)]
    struct DistributedStats {
        width: u32,
        height: u32,
        renderer: &'static str,
        /// Render threads per rank.
        threads: usize,
        frame_ms_median: f64,
        frame_ms: Vec<f64>,
        load_ms: f64,
        rays: u64,
        samples: u64,
        peak_rss_mb: f64,
        ranks: usize,
        /// Per rank, the median time to render its part (ms).
        rank_ms: Vec<f64>,
        /// Per rank, the bytes read from the file for its part.
        rank_bytes_read: Vec<u64>,
        /// Per rank, the samples its part took (the last frame).
        rank_samples: Vec<u64>,
        /// What the partition balances: "occupancy" or "voxels".
        balance: &'static str,
        /// Where occupancy balancing found the whole volume's macrocell
        /// ranges: "cache" or "first pass" ("" for voxels).
        balance_ranges: &'static str,
        /// Per rank, the bytes read by the first pass (0 with the cache).
        rank_bytes_read_balancing: Vec<u64>,
        /// Bytes all ranks send per frame (partial images, RGB pieces).
        bytes_exchanged: u64,
        /// Compositing on rank 0, median (ms; part of `frame_ms`): from
        /// the moment every rank has rendered to the frame on rank 0,
        /// the exchanges and merges included.
        composite_ms_median: f64,
        /// Per rank, the median time from the end of rendering to the end
        /// of its part in compositing.
        rank_composite_ms: Vec<f64>,
        /// Per rank, bytes sent per frame (partial images as 4-byte floats,
        /// 24 bytes a pixel plus a 24-byte header a message; final pieces
        /// as RGB, 3 bytes a pixel; nothing to itself).
        rank_bytes_sent: Vec<u64>,
        /// Per rank, bytes received per frame.
        rank_bytes_received: Vec<u64>,
        /// Per rank, messages sent per frame (besides the all-gather of
        /// the parts' screen rectangles, 16 bytes a rank).
        rank_messages_sent: Vec<u64>,
        /// How partial images travel: "gather" (all to rank 0),
        /// "direct-send" (to band owners), "binary-swap".
        compositing: &'static str,
        /// The `--composite` asked for (binary swap falls back to direct
        /// send when the rank count is not a power of two).
        composite_requested: &'static str,
    }

    /// Opens the file's header (and checks what `--distributed` cannot
    /// do), before any collective call.
    fn open_file(args: &RenderArgs, rank: usize) -> Result<PartFile, Error> {
        let path = args
            .file
            .as_deref()
            .ok_or("--distributed needs a volume FILE (the demo volume is not distributed)")?;
        if args.mode == RenderMode::Metaballs {
            return Err(
                "--distributed renders volumes; it does not work with --mode metaballs".into(),
            );
        }
        if std::env::var(FAIL_RANK_VAR).is_ok_and(|v| v == rank.to_string()) {
            return Err(format!(
                "rank {rank}: cannot open {} ({FAIL_RANK_VAR} is set to this rank)",
                path.display()
            )
            .into());
        }
        let raw = args.raw.open_options(LoadMode::Map).raw;
        Ok(PartFile::open_with(
            path,
            raw.as_ref(),
            args.distributed_read,
        )?)
    }

    /// The ghost layer the options need (1 voxel, 2 with gradients).
    fn ghost(args: &RenderArgs) -> u32 {
        distributed::ghost_layer(&RenderOptions {
            shading: args.shading.on(),
            gradient_opacity: args
                .gradient_opacity
                .map(|(g0, g1)| raycaster::integrator::GradientOpacity { g0, g1 }),
            ..RenderOptions::default()
        })
    }

    /// Where the whole volume's macrocell ranges for balancing came from.
    struct WholeRanges {
        grid: MacrocellGrid,
        /// "cache" or "first pass".
        source: &'static str,
        /// Bytes this rank read for them.
        bytes_read: u64,
        /// The volume's sample type (the widest any rank read when a
        /// rescale made the parts' types differ).
        sample_type: SampleType,
    }

    /// The whole volume's macrocell value ranges (side `m`, the scene's
    /// default), from the volume's cache when every rank finds it, else by
    /// a first pass: each rank reads a voxel-balanced region on
    /// `balance_cell` cells, builds its macrocells' ranges, and an
    /// all-reduce (min of minima, max of maxima) combines them; rank 0 then
    /// writes the cache, so the next run needs no pass.
    fn whole_ranges(
        world: &SimpleCommunicator,
        args: &RenderArgs,
        file: &PartFile,
        rank: usize,
        ranks: usize,
    ) -> Result<WholeRanges, Error> {
        let grid = file.grid();
        let m = raycaster::scene::default_macrocell(grid.dims);
        let keyed = if args.no_cache {
            None
        } else {
            file.cache_key(m)
        };
        let mut report = CacheReport::default();
        let cached = keyed.as_ref().and_then(|(key, shape)| {
            raycaster::scene::find_cached_macrocells(file.path(), key, *shape, None, &mut report)
        });
        if rank == 0 {
            for w in &report.warnings {
                eprintln!("vol_app: {w}");
            }
        }
        // Every rank must take the same path: the first pass is collective.
        if all_ok(world, cached.is_some())
            && let Some(grid) = cached
        {
            let sample_type = keyed.map_or(SampleType::F32, |(_, shape)| shape.sample_type);
            return Ok(WholeRanges {
                grid,
                source: "cache",
                bytes_read: 0,
                sample_type,
            });
        }
        let first = Partition::kd(
            grid.dims,
            grid.spacing,
            ranks,
            &CellWeights::uniform(grid.dims, distributed::balance_cell(grid.dims)),
        )
        .and_then(|p| distributed::region_macrocell_ranges(file, &p.regions()[rank], m));
        if !all_ok(world, first.is_ok()) {
            return Err(match first {
                Err(e) => e.into(),
                Ok(_) => format!(
                    "rank {rank}: another rank could not read its part of the volume for balancing (its error is above)"
                )
                .into(),
            });
        }
        let Ok(first) = first else {
            return Err("unreachable: every rank read its part".into());
        };
        // The sample type: the same on every rank unless a rescale gave
        // the parts different types; then f32, which holds them all.
        let code = first.sample_type as i32;
        let (mut code_lo, mut code_hi) = (0i32, 0i32);
        world.all_reduce_into(&code, &mut code_lo, SystemOperation::min());
        world.all_reduce_into(&code, &mut code_hi, SystemOperation::max());
        let sample_type = if code_lo == code_hi {
            first.sample_type
        } else {
            SampleType::F32
        };
        let bytes_read = first.bytes_read;
        let (mins, maxs): (Vec<f32>, Vec<f32>) = first.ranges.into_iter().unzip();
        let (mut lo, mut hi) = (vec![0f32; mins.len()], vec![0f32; maxs.len()]);
        world.all_reduce_into(&mins[..], &mut lo[..], SystemOperation::min());
        world.all_reduce_into(&maxs[..], &mut hi[..], SystemOperation::max());
        let count = MacrocellGrid::count_for(grid.dims, m);
        let whole = MacrocellGrid::from_ranges(m, count, lo.into_iter().zip(hi).collect());
        if rank == 0
            && let Some((key, shape)) = &keyed
        {
            let mut report = CacheReport::default();
            raycaster::scene::save_cached_macrocells(
                file.path(),
                key,
                *shape,
                &whole,
                None,
                &mut report,
            );
            for w in &report.warnings {
                eprintln!("vol_app: {w}");
            }
        }
        Ok(WholeRanges {
            grid: whole,
            source: "first pass",
            bytes_read,
            sample_type,
        })
    }

    /// Sets up the frame (TF, camera, options, renderer) on every rank for
    /// the whole volume's value range; an error on any rank ends all.
    fn set_up(
        world: &SimpleCommunicator,
        args: &RenderArgs,
        file: &PartFile,
        sample: SampleType,
        range: (f32, f32),
        rank: usize,
    ) -> Result<(TransferFunction, Camera, RenderOptions, PartRenderer), Error> {
        let setup = (|| -> Result<_, Error> {
            let tf = transfer_function(args, sample, range)?;
            let camera = camera_for(args, &file.grid().bounds())?;
            let options = render_options(args, range)?;
            let renderer = PartRenderer::new(args.threads as usize)?;
            Ok((tf, camera, options, renderer))
        })();
        if !all_ok(world, setup.is_ok()) {
            return Err(match setup {
                Err(e) => e,
                Ok(_) => format!("rank {rank}: another rank failed to set up the frame").into(),
            });
        }
        setup
    }

    /// Reads this rank's region of `partition`; an error on any rank ends
    /// all.
    fn open_region(
        world: &SimpleCommunicator,
        args: &RenderArgs,
        file: &PartFile,
        partition: &Partition,
        rank: usize,
    ) -> Result<(PartScene, u64), Error> {
        let opened = distributed::open_part(file, &partition.regions()[rank], ghost(args));
        if !all_ok(world, opened.is_ok()) {
            return Err(match opened {
                Err(e) => e.into(),
                Ok(_) => format!(
                    "rank {rank}: another rank could not open its part of the volume (its error is above)"
                )
                .into(),
            });
        }
        Ok(opened?)
    }

    /// Whether `ok` holds on every rank.
    fn all_ok<C: Communicator>(world: &C, ok: bool) -> bool {
        let mut all = 0i32;
        world.all_reduce_into(&i32::from(ok), &mut all, SystemOperation::min());
        all == 1
    }

    /// Runs `--distributed` as one rank of the MPI job.
    pub fn run(args: &RenderArgs) -> Result<(), Error> {
        let universe = mpi::initialize().ok_or("MPI is already initialised in this process")?;
        let world = universe.world();
        let (rank, ranks) = (world.rank() as usize, world.size() as usize);
        let root = world.process_at_rank(0);
        let load_start = Instant::now();

        let file = open_file(args, rank);
        if !all_ok(&world, file.is_ok()) {
            return Err(match file {
                Err(e) => e,
                Ok(_) => format!(
                    "rank {rank}: another rank could not open the volume (its error is above)"
                )
                .into(),
            });
        }
        let file = file?;
        let grid = file.grid();

        // The partition, the part, and the whole volume's value range (the
        // TF presets, the default iso value and the shading thresholds
        // depend on it).
        let (partition, part, bytes_read, tf, camera, options, mut renderer, balancing) =
            match args.balance {
                Balance::Occupancy => {
                    let whole = whole_ranges(&world, args, &file, rank, ranks)?;
                    let range = whole.grid.value_range();
                    let (tf, camera, options, renderer) =
                        set_up(&world, args, &file, whole.sample_type, range, rank)?;
                    let m = whole.grid.cell;
                    let coarse = whole
                        .grid
                        .coarsened(distributed::balance_cell(grid.dims) / m);
                    let weights = distributed::occupancy_weights_of(&grid, &coarse, &tf, &options);
                    let partition = Partition::kd(grid.dims, grid.spacing, ranks, &weights)?;
                    let (mut part, bytes) = open_region(&world, args, &file, &partition, rank)?;
                    part.value_range = range;
                    let balancing = (whole.source, whole.bytes_read);
                    (
                        partition, part, bytes, tf, camera, options, renderer, balancing,
                    )
                }
                Balance::Voxels => {
                    let partition = Partition::kd(
                        grid.dims,
                        grid.spacing,
                        ranks,
                        &CellWeights::voxels(grid.dims),
                    )?;
                    let (mut part, bytes) = open_region(&world, args, &file, &partition, rank)?;
                    let (mut lo, mut hi) = (0f32, 0f32);
                    world.all_reduce_into(&part.value_range.0, &mut lo, SystemOperation::min());
                    world.all_reduce_into(&part.value_range.1, &mut hi, SystemOperation::max());
                    part.value_range = (lo, hi);
                    let sample = part.scene.volume().sample_type();
                    let (tf, camera, options, renderer) =
                        set_up(&world, args, &file, sample, (lo, hi), rank)?;
                    (
                        partition,
                        part,
                        bytes,
                        tf,
                        camera,
                        options,
                        renderer,
                        ("", 0),
                    )
                }
            };
        let sample = part.scene.volume().sample_type();
        let load_ms = ms(load_start.elapsed());
        let compositor = distributed::compositor(&tf, &options, sample);
        let ctx = Ctx {
            world: &world,
            rank,
            ranks,
            compositor: &compositor,
        };

        let frames = if args.repeat == 1 { 1 } else { args.repeat + 1 };
        let mut frame_ms = Vec::new();
        let mut my_render_ms = Vec::new();
        let mut my_composite_ms = Vec::new();
        let mut last = None;
        let mut traffic = [0u64; 3];
        let mut samples = 0u64;
        let mut my_samples = 0u64;
        let mut method = args.composite;
        for n in 0..frames {
            world.barrier();
            let start = Instant::now();
            let image = renderer.render(&part, &camera, &tf, &options);
            // Also the point where every rank has finished rendering.
            if !all_ok(&world, image.is_ok()) {
                return Err(match image {
                    Err(e) => e.into(),
                    Ok(_) => format!("rank {rank}: another rank failed to render its part").into(),
                });
            }
            let Ok(image) = image else {
                return Err("unreachable: every rank rendered".into());
            };
            let composite_start = Instant::now();
            let (rgb, sent) = composite(&ctx, args.composite, &partition, &camera, &grid, &image)?;
            let composite_ms = ms(composite_start.elapsed());
            let elapsed = ms(start.elapsed());
            let timed = frames == 1 || n > 0;
            if timed {
                my_render_ms.push(ms(image.time));
                my_composite_ms.push(composite_ms);
                if rank == 0 {
                    frame_ms.push(elapsed);
                }
            }
            (method, traffic) = sent;
            my_samples = image.samples;
            let mut all_samples = 0u64;
            world.all_reduce_into(&image.samples, &mut all_samples, SystemOperation::sum());
            samples = all_samples;
            last = rgb;
        }
        // Per rank: the bytes read, the median render and compositing
        // times, and the last frame's traffic.
        let mine = [
            bytes_read as f64,
            median(&my_render_ms),
            median(&my_composite_ms),
            traffic[0] as f64,
            traffic[1] as f64,
            traffic[2] as f64,
            my_samples as f64,
            balancing.1 as f64,
        ];
        const COLUMNS: usize = 8;
        let mut all = vec![0f64; COLUMNS * ranks];
        if rank == 0 {
            root.gather_into_root(&mine[..], &mut all[..]);
        } else {
            root.gather_into(&mine[..]);
            return Ok(());
        }
        let column = |c: usize| -> Vec<f64> { all.chunks_exact(COLUMNS).map(|r| r[c]).collect() };
        let whole = |c: usize| -> Vec<u64> { column(c).into_iter().map(|v| v as u64).collect() };
        let read = whole(0);
        let rank_ms = column(1);
        let rank_composite_ms = column(2);
        let (rank_bytes_sent, rank_bytes_received, rank_messages_sent) =
            (whole(3), whole(4), whole(5));
        let (rank_samples, rank_bytes_read_balancing) = (whole(6), whole(7));
        let Some(rgb) = last else {
            return Err("no frame was rendered".into());
        };
        let (width, height) = (camera.width, camera.height);
        let out = match (&args.out, args.stats) {
            (Some(p), _) => Some(p.clone()),
            (None, false) => Some("out.png".into()),
            (None, true) => None,
        };
        if let Some(path) = &out {
            let frame = Frame {
                width,
                height,
                rgb,
                stats: FrameStats::default(),
            };
            frame.save_png(path)?;
        }
        if args.stats {
            print_json(&DistributedStats {
                width,
                height,
                renderer: "distributed",
                threads: renderer.threads(),
                frame_ms_median: median(&frame_ms),
                frame_ms,
                load_ms,
                rays: u64::from(width) * u64::from(height),
                samples,
                peak_rss_mb: peak_rss_mb(),
                ranks,
                rank_ms,
                rank_bytes_read: read,
                rank_samples,
                balance: args.balance.name(),
                balance_ranges: balancing.0,
                rank_bytes_read_balancing,
                bytes_exchanged: rank_bytes_sent.iter().sum(),
                composite_ms_median: rank_composite_ms[0],
                rank_composite_ms,
                rank_bytes_sent,
                rank_bytes_received,
                rank_messages_sent,
                compositing: method.name(),
                composite_requested: args.composite.name(),
            })?;
        } else if let Some(path) = &out {
            eprintln!(
                "vol_app: wrote {} ({width}x{height}, {ranks} ranks, {:.1} ms)",
                path.display(),
                frame_ms.last().copied().unwrap_or(0.0)
            );
        }
        Ok(())
    }

    /// What every compositing step needs.
    struct Ctx<'a> {
        world: &'a SimpleCommunicator,
        rank: usize,
        ranks: usize,
        compositor: &'a Compositor,
    }

    /// This rank's traffic in a frame: bytes sent, bytes received,
    /// messages sent.
    type Sent = (CompositeMethod, [u64; 3]);

    /// Composites the frame by `method` from this rank's `image`: the RGB
    /// frame on rank 0 (`None` elsewhere) and what this rank sent.
    fn composite(
        ctx: &Ctx<'_>,
        method: CompositeMethod,
        partition: &Partition,
        camera: &Camera,
        grid: &Grid,
        image: &PartialImage,
    ) -> Result<(Option<Vec<u8>>, Sent), Error> {
        let (world, rank, ranks) = (ctx.world, ctx.rank, ctx.ranks);
        // Every rank's screen rectangle: from them (and the tree and the
        // camera, which every rank has) each rank computes the whole
        // exchange, every message's size included.
        let r = image.rect;
        let mut all = vec![0u32; 4 * ranks];
        world.all_gather_into(&[r.x0, r.y0, r.x1, r.y1][..], &mut all[..]);
        let rects: Vec<PixelRect> = all
            .chunks_exact(4)
            .map(|c| PixelRect {
                x0: c[0],
                y0: c[1],
                x1: c[2],
                y1: c[3],
            })
            .collect();
        let plan = CompositePlan::new(method, partition, camera, grid, &rects)?;
        let mut traffic = [0u64; 3];
        let empty = image.crop(&PixelRect::default());
        let (width, height) = (image.width, image.height);
        let piece = match &plan {
            CompositePlan::Gather { order } => {
                let root = world.process_at_rank(0);
                let sent = image.encode();
                if rank != 0 {
                    root.gather_varcount_into(&sent[..]);
                    traffic = [4 * sent.len() as u64, 0, 1];
                    return Ok((None, (plan.method(), traffic)));
                }
                let counts: Vec<i32> = rects
                    .iter()
                    .map(|r| PartialImage::encoded_len(r) as i32)
                    .collect();
                let displs = offsets(&counts);
                let total: usize = counts.iter().map(|&c| c as usize).sum();
                let mut all = vec![0f32; total];
                {
                    let mut into = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                    root.gather_varcount_into_root(&sent[..], &mut into);
                }
                traffic[1] = 4 * (total - sent.len()) as u64;
                let images = (0..ranks)
                    .map(|r| {
                        let at = displs[r] as usize;
                        PartialImage::decode(&all[at..at + counts[r] as usize])
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                let (_, _, rgb) = ctx
                    .compositor
                    .composite(order.iter().map(|&i| &images[i]))?;
                return Ok((Some(rgb), (plan.method(), traffic)));
            }
            CompositePlan::DirectSend { order, bands } => {
                let band = bands.band(rank);
                // To each owner, the part of this image in its band; from
                // each rank, the part of its image in this band (nothing
                // to or from itself, nothing for an empty rectangle).
                let send_counts: Vec<i32> = bands
                    .bands()
                    .iter()
                    .enumerate()
                    .map(|(o, b)| wire_len(o == rank, &image.rect.intersect(b)))
                    .collect();
                let recv_rects: Vec<PixelRect> = rects.iter().map(|r| r.intersect(&band)).collect();
                let recv_counts: Vec<i32> = recv_rects
                    .iter()
                    .enumerate()
                    .map(|(s, r)| wire_len(s == rank, r))
                    .collect();
                let mut send = Vec::with_capacity(send_counts.iter().map(|&c| c as usize).sum());
                for (b, &c) in bands.bands().iter().zip(&send_counts) {
                    if c > 0 {
                        image.encode_crop_into(b, &mut send);
                    }
                }
                let mut recv = vec![0f32; recv_counts.iter().map(|&c| c as usize).sum()];
                let (send_displs, recv_displs) = (offsets(&send_counts), offsets(&recv_counts));
                {
                    let out = Parts::new(&send[..], &send_counts[..], &send_displs[..]);
                    let mut into =
                        PartitionMut::new(&mut recv[..], &recv_counts[..], &recv_displs[..]);
                    world.all_to_all_varcount_into(&out, &mut into);
                }
                traffic = [
                    4 * send.len() as u64,
                    4 * recv.len() as u64,
                    send_counts.iter().filter(|&&c| c > 0).count() as u64,
                ];
                // Its own part is merged from its image (merge_over reads
                // only the band).
                let got = (0..ranks)
                    .map(|s| {
                        if s == rank || recv_counts[s] == 0 {
                            Ok(empty.clone())
                        } else {
                            let at = recv_displs[s] as usize;
                            PartialImage::decode(&recv[at..at + recv_counts[s] as usize])
                        }
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                let part = |i: usize| if i == rank { image } else { &got[i] };
                let merged = ctx.compositor.merge_over(
                    band,
                    width,
                    height,
                    order.iter().map(|&i| part(i)),
                )?;
                ctx.compositor.resolve_rect(&merged, band)
            }
            CompositePlan::BinarySwap(swap) => {
                let mut held = std::borrow::Cow::Borrowed(image);
                for (level, round) in swap.rounds(rank).iter().enumerate() {
                    let partner = world.process_at_rank(round.partner as i32);
                    let tag = level as i32;
                    let send = (!round.send.is_empty()).then(|| {
                        let mut out = Vec::new();
                        held.encode_crop_into(&round.send, &mut out);
                        out
                    });
                    let mut recv = vec![0f32; wire_len(false, &round.receive) as usize];
                    match (&send, recv.is_empty()) {
                        (Some(send), false) => {
                            mpi::point_to_point::send_receive_into_with_tags(
                                &send[..],
                                &partner,
                                tag,
                                &mut recv[..],
                                &partner,
                                tag,
                            );
                        }
                        (Some(send), true) => partner.send_with_tag(&send[..], tag),
                        (None, false) => {
                            partner.receive_into_with_tag(&mut recv[..], tag);
                        }
                        (None, true) => {}
                    }
                    if let Some(send) = &send {
                        traffic[0] += 4 * send.len() as u64;
                        traffic[2] += 1;
                    }
                    traffic[1] += 4 * recv.len() as u64;
                    let incoming = if recv.is_empty() {
                        empty.clone()
                    } else {
                        PartialImage::decode(&recv)?
                    };
                    held = std::borrow::Cow::Owned(BinarySwap::step(
                        ctx.compositor,
                        round,
                        &held,
                        &incoming,
                    )?);
                }
                ctx.compositor.resolve_rect(&held, swap.final_region(rank))
            }
        };
        // The finished pieces (RGB) to rank 0.
        let regions = plan.final_regions().unwrap_or(&[]);
        let root = world.process_at_rank(0);
        if rank != 0 {
            root.gather_varcount_into(&piece[..]);
            if !piece.is_empty() {
                traffic[0] += piece.len() as u64;
                traffic[2] += 1;
            }
            return Ok((None, (plan.method(), traffic)));
        }
        let counts: Vec<i32> = regions.iter().map(|r| 3 * r.area() as i32).collect();
        let displs = offsets(&counts);
        let mut all = vec![0u8; counts.iter().map(|&c| c as usize).sum()];
        {
            let mut into = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
            root.gather_varcount_into_root(&piece[..], &mut into);
        }
        traffic[1] += (all.len() - piece.len()) as u64;
        let rgb = ctx.compositor.assemble(
            width,
            height,
            regions.iter().enumerate().map(|(r, region)| {
                let at = displs[r] as usize;
                (*region, &all[at..at + counts[r] as usize])
            }),
        )?;
        Ok((Some(rgb), (plan.method(), traffic)))
    }

    /// Floats on the wire for a partial image of `rect` (none to itself or
    /// for an empty rectangle).
    fn wire_len(to_self: bool, rect: &PixelRect) -> i32 {
        if to_self || rect.is_empty() {
            0
        } else {
            PartialImage::encoded_len(rect) as i32
        }
    }

    /// Displacements of consecutive blocks of `counts`.
    fn offsets(counts: &[i32]) -> Vec<i32> {
        counts
            .iter()
            .scan(0i32, |at, &c| {
                let d = *at;
                *at += c;
                Some(d)
            })
            .collect()
    }
}

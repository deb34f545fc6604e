//! `vol_app render FILE --distributed`: sort-last distributed rendering
//! over MPI (`mpirun -n P vol_app render FILE --distributed ...`).
//!
//! Every rank reads the file's header, builds the same k-d partition (one
//! region per rank, balanced by voxel count: the occupancy of the
//! macrocells would need the whole file), reads its region and ghost layer
//! ([`raycaster::distributed`]), and renders it into a partial image of
//! fragments. The partial images are gathered to rank 0, which composites
//! them in visibility order and writes the PNG and the `--stats` object
//! (with `ranks`, `rank_ms`, the bytes each rank read and the bytes
//! exchanged per frame).
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
    Err("--distributed: this vol_app was built without MPI; rebuild with --features mpi \
         (cargo build --release -p vol_app --features mpi; needs an MPI library, libclang and pkg-config)"
        .into())
}

#[cfg(feature = "mpi")]
pub use transport::run;

#[cfg(feature = "mpi")]
mod transport {
    use std::time::Instant;

    use mpi::collective::SystemOperation;
    use mpi::datatype::PartitionMut;
    use mpi::traits::*;
    use serde::Serialize;

    use raycaster::distributed::{
        self, CellWeights, PartFile, PartRenderer, PartScene, PartialImage, Partition,
    };
    use raycaster::prelude::*;

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
        /// Per rank, the bytes read from the file.
        rank_bytes_read: Vec<u64>,
        /// Bytes of partial images sent to rank 0 per frame (all ranks).
        bytes_exchanged: u64,
        /// Compositing on rank 0, median (ms; part of `frame_ms`).
        composite_ms_median: f64,
        /// How partial images travel: "gather" (all to rank 0).
        compositing: &'static str,
    }

    /// What a rank holds after opening its part.
    struct Opened {
        file: PartFile,
        partition: Partition,
        part: PartScene,
        bytes_read: u64,
    }

    fn open(args: &RenderArgs, rank: usize, ranks: usize) -> Result<Opened, Error> {
        let path = args
            .file
            .as_deref()
            .ok_or("--distributed needs a volume FILE (the demo volume is not distributed)")?;
        if args.mode == RenderMode::Metaballs {
            return Err(
                "--distributed renders volumes; it does not work with --mode metaballs".into(),
            );
        }
        if args.raw.open_options(LoadMode::Map).raw.is_some() {
            return Err("--distributed does not read raw files (--raw-dims) in part; convert them to .vol or NRRD".into());
        }
        if std::env::var(FAIL_RANK_VAR).is_ok_and(|v| v == rank.to_string()) {
            return Err(format!(
                "rank {rank}: cannot open {} ({FAIL_RANK_VAR} is set to this rank)",
                path.display()
            )
            .into());
        }
        let file = PartFile::open(path, args.distributed_read)?;
        let grid = file.grid();
        let partition = Partition::kd(
            grid.dims,
            grid.spacing,
            ranks,
            &CellWeights::voxels(grid.dims),
        )?;
        let region = partition.regions()[rank];
        // The ghost layer the options need (1 voxel, 2 with gradients).
        let ghost = distributed::ghost_layer(&RenderOptions {
            shading: args.shading.on(),
            gradient_opacity: args
                .gradient_opacity
                .map(|(g0, g1)| raycaster::integrator::GradientOpacity { g0, g1 }),
            ..RenderOptions::default()
        });
        let (part, bytes_read) = distributed::open_part(&file, &region, ghost)?;
        Ok(Opened {
            file,
            partition,
            part,
            bytes_read,
        })
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

        let opened = open(args, rank, ranks);
        if !all_ok(&world, opened.is_ok()) {
            return Err(match opened {
                Err(e) => e,
                Ok(_) => format!(
                    "rank {rank}: another rank could not open its part of the volume (its error is above)"
                )
                .into(),
            });
        }
        let Ok(Opened {
            file,
            partition,
            mut part,
            bytes_read,
        }) = opened
        else {
            return Err("unreachable: every rank opened its part".into());
        };

        // The whole volume's value range: the TF presets, the default iso
        // value and the shading thresholds depend on it.
        let (mut lo, mut hi) = (0f32, 0f32);
        world.all_reduce_into(&part.value_range.0, &mut lo, SystemOperation::min());
        world.all_reduce_into(&part.value_range.1, &mut hi, SystemOperation::max());
        part.value_range = (lo, hi);
        let grid = file.grid();
        let sample = part.scene.volume().sample_type();
        let setup = (|| -> Result<_, Error> {
            let tf = transfer_function(args, sample, (lo, hi))?;
            let camera = camera_for(args, &grid.bounds())?;
            let options = render_options(args, (lo, hi))?;
            let renderer = PartRenderer::new(args.threads as usize)?;
            Ok((tf, camera, options, renderer))
        })();
        if !all_ok(&world, setup.is_ok()) {
            return Err(match setup {
                Err(e) => e,
                Ok(_) => format!("rank {rank}: another rank failed to set up the frame").into(),
            });
        }
        let Ok((tf, camera, options, mut renderer)) = setup else {
            return Err("unreachable: every rank set up the frame".into());
        };
        let load_ms = ms(load_start.elapsed());
        let compositor = distributed::compositor(&tf, &options, sample);
        let order = distributed::visibility_order(&partition, &camera, &grid);

        let frames = if args.repeat == 1 { 1 } else { args.repeat + 1 };
        let mut frame_ms = Vec::new();
        let mut composite_ms = Vec::new();
        let mut rank_ms: Vec<Vec<f64>> = vec![Vec::new(); ranks];
        let mut last = None;
        let mut exchanged = 0u64;
        let mut samples = 0u64;
        for n in 0..frames {
            world.barrier();
            let start = Instant::now();
            let image = renderer.render(&part, &camera, &tf, &options);
            if !all_ok(&world, image.is_ok()) {
                return Err(match image {
                    Err(e) => e.into(),
                    Ok(_) => format!("rank {rank}: another rank failed to render its part").into(),
                });
            }
            let Ok(image) = image else {
                return Err("unreachable: every rank rendered".into());
            };
            let sent = image.encode();
            let render_ms = ms(image.time);
            let mut all_samples = 0u64;
            world.all_reduce_into(&image.samples, &mut all_samples, SystemOperation::sum());
            let timed = frames == 1 || n > 0;
            if rank == 0 {
                let mut counts = vec![0i32; ranks];
                root.gather_into_root(&(sent.len() as i32), &mut counts[..]);
                let mut times = vec![0f64; ranks];
                root.gather_into_root(&render_ms, &mut times[..]);
                let displs: Vec<i32> = counts
                    .iter()
                    .scan(0i32, |at, &c| {
                        let d = *at;
                        *at += c;
                        Some(d)
                    })
                    .collect();
                let total: usize = counts.iter().map(|&c| c as usize).sum();
                let mut all = vec![0f32; total];
                {
                    let mut into = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                    root.gather_varcount_into_root(&sent[..], &mut into);
                }
                let composite_start = Instant::now();
                let images = (0..ranks)
                    .map(|r| {
                        let at = displs[r] as usize;
                        PartialImage::decode(&all[at..at + counts[r] as usize])
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                let rgb = compositor.composite(order.iter().map(|&i| &images[i]))?;
                if timed {
                    composite_ms.push(ms(composite_start.elapsed()));
                    frame_ms.push(ms(start.elapsed()));
                    for (r, t) in times.into_iter().enumerate() {
                        rank_ms[r].push(t);
                    }
                }
                exchanged = 4 * total as u64;
                samples = all_samples;
                last = Some(rgb);
            } else {
                root.gather_into(&(sent.len() as i32));
                root.gather_into(&render_ms);
                root.gather_varcount_into(&sent[..]);
            }
        }
        let mut read = vec![0u64; ranks];
        if rank == 0 {
            root.gather_into_root(&bytes_read, &mut read[..]);
        } else {
            root.gather_into(&bytes_read);
            return Ok(());
        }
        let Some((width, height, rgb)) = last else {
            return Err("no frame was rendered".into());
        };
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
                rank_ms: rank_ms.iter().map(|t| median(t)).collect(),
                rank_bytes_read: read,
                bytes_exchanged: exchanged,
                composite_ms_median: median(&composite_ms),
                compositing: "gather",
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
}

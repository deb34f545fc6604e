//! Opening volumes on a background thread: read (or map) the file, build the
//! scene's acceleration data and the value histogram, reporting the phase and
//! progress as it goes. The UI polls a [`LoadJob`]; a failure is an error
//! message, never a panic in the UI thread.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, TryRecvError};
use glam::{UVec3, Vec3};
use raycaster::format::FileFormat;
use raycaster::prelude::*;
use raycaster::sequence::{Playback, Sequence, frame_files};
use raycaster::storage::StorageKind;

use super::timeline::Timeline;

/// File extensions the library reads (for the file dialog's filter).
pub const VOLUME_EXTENSIONS: &[&str] = &["vol", "nrrd", "nhdr", "nii", "gz", "dcm", "vseq"];

/// Where a volume comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A file, memory-mapped or read into RAM (with the description of a
    /// headerless file).
    File(PathBuf, LoadMode, Option<raycaster::format::RawOptions>),
    /// The built-in demo volume, generated in memory.
    Demo,
}

impl Source {
    /// What to call the source in messages.
    pub fn name(&self) -> String {
        match self {
            Source::File(p, ..) => p.display().to_string(),
            Source::Demo => "the built-in demo volume".into(),
        }
    }
}

/// Facts about a loaded volume, for the info panel.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeInfo {
    /// File name, or "built-in demo".
    pub name: String,
    /// The file, when there is one.
    pub path: Option<PathBuf>,
    /// Dimensions in voxels.
    pub dims: UVec3,
    /// Voxel spacing.
    pub spacing: Vec3,
    /// Sample type.
    pub sample_type: SampleType,
    /// Smallest and largest voxel value.
    pub value_range: (f32, f32),
    /// Memory layout.
    pub layout: Layout,
    /// RAM or memory-mapped.
    pub storage: StorageKind,
    /// Time from the start of loading to a ready scene.
    pub load_time: Duration,
    /// What the file stores (format, stored type, rescale, orientation,
    /// notes, size on disk), when there is a file.
    pub file: Option<raycaster::format::VolumeInfo>,
}

impl VolumeInfo {
    /// Bytes on disk, when the volume came from a file.
    pub fn file_size(&self) -> Option<u64> {
        self.file.as_ref().map(|f| f.file_bytes)
    }
}

/// Voxel counts per value bin over the volume's value range.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    /// Smallest and largest voxel value.
    pub range: (f32, f32),
    /// Value at the start of the first bin.
    pub lo: f32,
    /// Value at the end of the last bin.
    pub hi: f32,
    /// Counts per bin (of a regular subsample of at most [`HISTOGRAM_SAMPLES`] voxels).
    pub counts: Vec<u64>,
}

/// Most voxels the histogram looks at (a regular subsample of larger volumes).
pub const HISTOGRAM_SAMPLES: u64 = 1 << 21;

impl Histogram {
    /// The histogram of `volume`, whose values lie in `range`, calling
    /// `progress` with the fraction done.
    pub fn of(volume: &AnyVolume, range: (f32, f32), mut progress: impl FnMut(f32)) -> Self {
        let (lo, hi) = range;
        let integer = volume.sample_type() != SampleType::F32;
        let bins = if integer && hi - lo < 256.0 {
            (hi - lo) as usize + 1
        } else {
            256
        };
        // Integer data: bin i holds value lo + i exactly; otherwise equal widths.
        let (lo, hi) = if integer && hi - lo < 256.0 {
            (lo - 0.5, hi + 0.5)
        } else {
            (lo, hi.max(lo + f32::EPSILON * lo.abs().max(1.0)))
        };
        let dims = volume.grid().dims;
        let voxels = dims.as_dvec3().element_product();
        let mut counts = vec![0u64; bins];
        let bins = Bins {
            lo,
            scale: bins as f32 / (hi - lo),
            counts: &mut counts,
        };
        if volume.storage_kind() == StorageKind::Mapped && voxels > HISTOGRAM_SAMPLES as f64 {
            count_in_blocks(volume, bins, &mut progress);
        } else {
            count_on_lattice(volume, bins, &mut progress);
        }
        Histogram {
            range,
            lo,
            hi,
            counts,
        }
    }
}

/// Histogram bins being filled: value `v` goes to bin `(v − lo)·scale`,
/// clamped to the last.
struct Bins<'a> {
    lo: f32,
    scale: f32,
    counts: &'a mut [u64],
}

impl Bins<'_> {
    fn add(&mut self, v: f32) {
        let b = ((v - self.lo) * self.scale) as usize;
        let last = self.counts.len() - 1;
        self.counts[b.min(last)] += 1;
    }
}

/// Counts a regular lattice of at most [`HISTOGRAM_SAMPLES`] voxels (every
/// voxel of a small volume) into `counts`.
fn count_on_lattice(volume: &AnyVolume, bins: Bins<'_>, progress: &mut dyn FnMut(f32)) {
    let voxels = volume.grid().dims.as_dvec3().element_product();
    let stride = ((voxels / HISTOGRAM_SAMPLES as f64).cbrt().ceil() as u32).max(1);
    struct Count<'a> {
        stride: u32,
        bins: Bins<'a>,
        progress: &'a mut dyn FnMut(f32),
    }
    impl raycaster::volume::VolumeVisitor for Count<'_> {
        type Output = ();
        fn visit<V: raycaster::volume::Volume>(mut self, v: &V) {
            use raycaster::sample::Sample;
            let dims = v.grid().dims;
            let stride = self.stride;
            let xs = dims.x.div_ceil(stride);
            for (i, x) in (0..dims.x).step_by(stride as usize).enumerate() {
                for y in (0..dims.y).step_by(stride as usize) {
                    for z in (0..dims.z).step_by(stride as usize) {
                        self.bins.add(v.voxel(UVec3::new(x, y, z)).to_f32());
                    }
                }
                (self.progress)((i + 1) as f32 / xs as f32);
            }
        }
    }
    volume.visit(Count {
        stride,
        bins,
        progress,
    });
}

/// Samples per block of [`count_in_blocks`]: a page of 8-bit samples, and
/// one brick of side 16.
const HISTOGRAM_BLOCK: usize = 4096;

/// Counts [`HISTOGRAM_SAMPLES`] voxels of a memory-mapped volume taken as
/// whole blocks of consecutive samples spread evenly over its storage, so
/// that only those few pages of the file are read: a lattice over the whole
/// grid would touch nearly every page of a huge file (one per brick), which
/// is the whole file in memory. Padding past the grid's edge in the last
/// bricks is skipped; the voxels bricks share are counted once per copy.
fn count_in_blocks(volume: &AnyVolume, bins: Bins<'_>, progress: &mut dyn FnMut(f32)) {
    struct Blocks<'a> {
        volume: &'a AnyVolume,
        bins: Bins<'a>,
        progress: &'a mut dyn FnMut(f32),
    }
    impl raycaster::sample::SampleTypeVisitor for Blocks<'_> {
        type Output = ();
        fn visit<S: raycaster::sample::Sample>(mut self) {
            let Some(samples) = self.volume.samples::<S>() else {
                return;
            };
            let dims = self.volume.grid().dims;
            let bricks = match self.volume.addressing() {
                raycaster::volume::AnyAddressing::Bricked(b) => Some(*b.bricks()),
                raycaster::volume::AnyAddressing::Linear(_) => None,
            };
            let len = samples.len();
            let block = HISTOGRAM_BLOCK.min(len);
            let n = (HISTOGRAM_SAMPLES as usize / block).clamp(1, len / block);
            for i in 0..n {
                // Evenly spaced, aligned to blocks (to bricks of 16).
                let start = if n > 1 {
                    (len - block) / (n - 1) * i / block * block
                } else {
                    0
                };
                for (j, s) in samples[start..start + block].iter().enumerate() {
                    if let Some(b) = &bricks
                        && b.voxel_at((start + j) as u64, dims).is_none()
                    {
                        continue;
                    }
                    self.bins.add(s.to_f32());
                }
                (self.progress)((i + 1) as f32 / n as f32);
            }
        }
    }
    volume.sample_type().visit(Blocks {
        volume,
        bins,
        progress,
    });
}

/// Gradient magnitudes `|∇f|` (data units per world unit, the measure that
/// gradient opacity thresholds) binned over `0..=hi`, drawn behind the
/// viewer's g0/g1 controls.
#[derive(Debug, Clone, PartialEq)]
pub struct GradientHistogram {
    /// End of the last bin: 1.5 × the 99.9th percentile of the magnitudes
    /// (larger ones count in the last bin), so a few extreme edges do not
    /// squeeze the rest into the first bins.
    pub hi: f32,
    /// Counts per bin.
    pub counts: Vec<u64>,
}

/// Most gradients the histogram evaluates.
pub const GRADIENT_SAMPLES: u64 = 1 << 18;

/// Bins of the gradient histogram.
const GRADIENT_BINS: usize = 128;

impl GradientHistogram {
    /// The histogram of `volume`'s gradients, from the library's
    /// [`Volume::gradient`] at voxels:
    /// a regular lattice of at most [`GRADIENT_SAMPLES`] voxels, or for a
    /// large memory-mapped volume 4³ blocks of 16³ voxels spread over it,
    /// so that only their pages are read (see `count_in_blocks`).
    pub fn of(volume: &AnyVolume) -> Self {
        let dims = volume.grid().dims;
        let voxels = dims.as_dvec3().element_product();
        let blocks =
            volume.storage_kind() == StorageKind::Mapped && voxels > GRADIENT_SAMPLES as f64;
        // Per axis the voxel coordinates to visit.
        let axis = |n: u32| -> Vec<u32> {
            if blocks {
                let side = n.min(16);
                let m = 4u32.min(n / side).max(1);
                let mut v: Vec<u32> = (0..m)
                    .flat_map(|i| {
                        let start = if m > 1 { (n - side) * i / (m - 1) } else { 0 };
                        start..start + side
                    })
                    .collect();
                v.dedup();
                v
            } else {
                let stride = ((voxels / GRADIENT_SAMPLES as f64).cbrt().ceil() as u32).max(1);
                (0..n).step_by(stride as usize).collect()
            }
        };
        let coords = [axis(dims.x), axis(dims.y), axis(dims.z)];
        struct Magnitudes<'a>(&'a [Vec<u32>; 3]);
        impl raycaster::volume::VolumeVisitor for Magnitudes<'_> {
            type Output = Vec<f32>;
            fn visit<V: raycaster::volume::Volume>(self, v: &V) -> Vec<f32> {
                let [xs, ys, zs] = self.0;
                let mut out = Vec::with_capacity(xs.len() * ys.len() * zs.len());
                for &x in xs {
                    for &y in ys {
                        for &z in zs {
                            let p = UVec3::new(x, y, z).as_vec3();
                            out.push(v.gradient(p).length());
                        }
                    }
                }
                out
            }
        }
        let mut mags = volume.visit(Magnitudes(&coords));
        mags.retain(|m| m.is_finite());
        Self::from_magnitudes(&mut mags)
    }

    /// Bins `mags` (finite, ≥ 0; reordered).
    fn from_magnitudes(mags: &mut [f32]) -> Self {
        let mut counts = vec![0u64; GRADIENT_BINS];
        if mags.is_empty() {
            return GradientHistogram { hi: 1.0, counts };
        }
        let q = ((mags.len() - 1) as f64 * 0.999) as usize;
        let (_, p999, _) = mags.select_nth_unstable_by(q, f32::total_cmp);
        let hi = (1.5 * *p999).max(f32::MIN_POSITIVE * 1e6);
        let scale = GRADIENT_BINS as f32 / hi;
        for &m in mags.iter() {
            counts[((m * scale) as usize).min(GRADIENT_BINS - 1)] += 1;
        }
        GradientHistogram { hi, counts }
    }

    /// The bin holding magnitude `g`.
    pub fn bin_of(&self, g: f32) -> usize {
        ((g / self.hi * self.counts.len() as f32) as usize).min(self.counts.len() - 1)
    }
}

/// A volume ready to render.
#[derive(Debug)]
pub struct Loaded {
    /// The volume and its acceleration data.
    pub scene: Arc<Scene>,
    /// Facts for the info panel.
    pub info: VolumeInfo,
    /// Value histogram for the TF editor.
    pub histogram: Histogram,
    /// Gradient-magnitude histogram for the gradient opacity controls.
    pub gradient_histogram: GradientHistogram,
    /// The player, when the file is a sequence of several frames.
    pub timeline: Option<Timeline>,
}

/// The stage a load is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Reading the header and mapping (or reading) the samples.
    Opening,
    /// Building the macrocell grid for empty-space skipping.
    Accelerating,
    /// Counting values for the histogram.
    Histogram,
}

impl Phase {
    /// What the phase is doing, for the progress indicator.
    pub fn label(self) -> &'static str {
        match self {
            Phase::Opening => "opening",
            Phase::Accelerating => "building the skip grid",
            Phase::Histogram => "computing the histogram",
        }
    }
}

/// Progress shared between the loading thread and the UI.
#[derive(Debug, Default)]
struct Progress {
    phase: AtomicU32,
    /// Fraction of the phase done, as `f32` bits; NaN when unknown.
    fraction: AtomicU32,
}

impl Progress {
    fn set(&self, phase: Phase, fraction: Option<f32>) {
        self.phase.store(phase as u32, Ordering::Relaxed);
        self.fraction
            .store(fraction.unwrap_or(f32::NAN).to_bits(), Ordering::Relaxed);
    }

    fn get(&self) -> (Phase, Option<f32>) {
        let phase = match self.phase.load(Ordering::Relaxed) {
            0 => Phase::Opening,
            1 => Phase::Accelerating,
            _ => Phase::Histogram,
        };
        let f = f32::from_bits(self.fraction.load(Ordering::Relaxed));
        (phase, (!f.is_nan()).then_some(f))
    }
}

/// A volume being loaded on a background thread.
#[derive(Debug)]
pub struct LoadJob {
    source: Source,
    progress: Arc<Progress>,
    rx: Receiver<Result<Loaded, String>>,
    started: Instant,
}

/// How the viewer opens volumes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadOptions {
    /// Neither read nor write the macrocell cache (`--no-cache`).
    pub no_cache: bool,
    /// The most bytes of samples a volume decoded or read into RAM may take
    /// (gzip, DICOM, converted raw data, packed sequences): a larger one is
    /// refused with a message instead of exhausting memory. Mapped files do
    /// not count. `--max-memory`; by default [`default_memory_limit`].
    pub max_memory: Option<u64>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            no_cache: false,
            max_memory: default_memory_limit(),
        }
    }
}

/// Three quarters of the machine's physical memory (`MemTotal` of
/// `/proc/meminfo`), leaving room for the viewer itself and the system;
/// `None` where it cannot be read.
pub fn default_memory_limit() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemTotal:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib * 1024 / 4 * 3)
}

impl LoadJob {
    /// Starts loading `source` with `options`; `wake` is called from the
    /// loading thread whenever there is news (progress or the result).
    pub fn start(
        source: Source,
        options: LoadOptions,
        wake: impl Fn() + Send + Sync + 'static,
    ) -> Self {
        let wake: Arc<dyn Fn() + Send + Sync> = Arc::new(wake);
        let (tx, rx) = crossbeam_channel::bounded(1);
        let progress = Arc::new(Progress::default());
        let job = LoadJob {
            source: source.clone(),
            progress: progress.clone(),
            rx,
            started: Instant::now(),
        };
        let spawned = std::thread::Builder::new()
            .name("vol_app-load".into())
            .spawn(move || {
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    load(&source, options, &progress, wake.clone())
                }))
                .unwrap_or_else(|_| {
                    Err(format!("{}: internal error while loading", source.name()))
                });
                let _ = tx.send(result);
                wake();
            });
        if let Err(e) = spawned {
            let (tx, rx) = crossbeam_channel::bounded(1);
            let _ = tx.send(Err(format!("cannot start the loading thread: {e}")));
            return LoadJob { rx, ..job };
        }
        job
    }

    /// What is being loaded.
    pub fn source(&self) -> &Source {
        &self.source
    }

    /// The current phase and, when known, the fraction of it done.
    pub fn progress(&self) -> (Phase, Option<f32>) {
        self.progress.get()
    }

    /// Time since the load started.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// The result, once the load has finished.
    pub fn poll(&self) -> Option<Result<Loaded, String>> {
        match self.rx.try_recv() {
            Ok(r) => Some(r),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                Some(Err(format!("{}: loading stopped", self.source.name())))
            }
        }
    }
}

fn load(
    source: &Source,
    LoadOptions {
        no_cache,
        max_memory,
    }: LoadOptions,
    progress: &Arc<Progress>,
    wake: Arc<dyn Fn() + Send + Sync>,
) -> Result<Loaded, String> {
    let start = Instant::now();
    progress.set(Phase::Opening, None);
    wake();
    // Building the macrocell grid (when its cache is missing) reports its
    // fraction.
    let scene_options = {
        let (p, w) = (progress.clone(), wake.clone());
        raycaster::scene::SceneOptions {
            progress: Some(raycaster::format::Progress::new(move |f| {
                p.set(Phase::Accelerating, Some(f));
                w();
            })),
            cache: if no_cache {
                raycaster::accel::cache::CachePolicy::Off
            } else {
                raycaster::accel::cache::CachePolicy::Auto
            },
            ..Default::default()
        }
    };
    let mut timeline = None;
    let (scene, name, path, file) = match source {
        Source::File(path, mode, raw) => {
            // A folder holding one volume file (a scan beside its licence)
            // is that file, as on the command line.
            let path = &raycaster::sequence::resolve_dir(path).into_owned();
            // Decoding (gzip, DICOM slices) reports its fraction.
            let (p, w) = (progress.clone(), wake.clone());
            let options = raycaster::format::OpenOptions {
                mode: *mode,
                raw: raw.clone(),
                progress: Some(raycaster::format::Progress::new(move |f| {
                    p.set(Phase::Opening, Some(f));
                    w();
                })),
                volume: 0,
                max_memory,
            };
            let packed =
                raw.is_none() && raycaster::format::detect(path).ok() == Some(FileFormat::Vseq);
            let (scene, info, player) = if packed || !frame_files(path).is_empty() {
                open_sequence(path, &options)?
            } else {
                let opened =
                    Scene::open(path, &options, &scene_options).map_err(|e| e.to_string())?;
                let mut info = opened.info;
                // A cache that could not be read or written is worth a line
                // among the volume's notes (and on stderr), not a failed load.
                for w in opened.cache.warnings {
                    eprintln!("vol_app: warning: {w}");
                    info.notes.push(w);
                }
                if info.volumes > 1 {
                    // A 4-D file: its volumes are the frames (the first is
                    // read again, by the player).
                    open_sequence(path, &options)?
                } else {
                    (Arc::new(opened.scene), info, None)
                }
            };
            timeline = player;
            (scene, file_name(path), Some(path.clone()), Some(info))
        }
        Source::Demo => (
            Arc::new(Scene::with_options(
                crate::demo::demo_volume(),
                &scene_options,
            )),
            "built-in demo".to_string(),
            None,
            None,
        ),
    };
    let volume = scene.volume();
    let (sample_type, layout, storage) =
        (volume.sample_type(), volume.layout(), volume.storage_kind());
    // A packed sequence knows the range of all its frames: the TF fitted
    // to it holds for every frame.
    let value_range = timeline
        .as_ref()
        .and_then(|t| t.value_range())
        .unwrap_or_else(|| scene.value_range());
    progress.set(Phase::Histogram, Some(0.0));
    wake();
    let mut last_wake = Instant::now();
    let histogram = Histogram::of(scene.volume(), value_range, |f| {
        progress.set(Phase::Histogram, Some(f));
        if last_wake.elapsed() > Duration::from_millis(50) {
            last_wake = Instant::now();
            wake();
        }
    });
    let gradient_histogram = GradientHistogram::of(scene.volume());
    let grid = *scene.grid();
    Ok(Loaded {
        info: VolumeInfo {
            name,
            path,
            dims: grid.dims,
            spacing: grid.spacing,
            sample_type,
            value_range,
            layout,
            storage,
            load_time: start.elapsed(),
            file,
        },
        scene,
        histogram,
        gradient_histogram,
        timeline,
    })
}

/// Frames a sequence keeps decoded ahead: about [`AHEAD_BYTES`] of them,
/// 2 to 8.
fn frames_ahead(sequence: &Sequence) -> u32 {
    let dims = sequence.info().dims.as_dvec3();
    let bytes = dims.element_product() * sequence.sample_type().size() as f64;
    (AHEAD_BYTES as f64 / bytes.max(1.0)).clamp(2.0, 8.0) as u32
}

/// Memory the frames decoded ahead of a sequence may take.
const AHEAD_BYTES: u64 = 256 << 20;

/// Opens the sequence at `path` and decodes its first frame; its timeline
/// when it has several frames (one frame is a plain volume).
fn open_sequence(
    path: &Path,
    options: &raycaster::format::OpenOptions,
) -> Result<(Arc<Scene>, raycaster::format::VolumeInfo, Option<Timeline>), String> {
    // Later frames decode on the player's thread, not this load's.
    let options = raycaster::format::OpenOptions {
        progress: None,
        ..options.clone()
    };
    let sequence = Arc::new(Sequence::open(path, &options).map_err(|e| e.to_string())?);
    let info = sequence.info().clone();
    let scene_options = raycaster::scene::SceneOptions {
        cache: raycaster::accel::cache::CachePolicy::Off,
        ..Default::default()
    };
    // The window wraps around the end whether or not the viewer loops:
    // playing again from the last frame starts at the first, decoded.
    let playback = Playback::new(
        sequence.clone(),
        frames_ahead(&sequence),
        true,
        scene_options,
    )
    .map_err(|e| e.to_string())?;
    let first = playback.get(0).map_err(|e| e.to_string())?;
    let scene = first.scene.clone();
    let timeline = (sequence.frames() > 1).then(|| Timeline::new(playback, first));
    Ok((scene, info, timeline))
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait(job: &LoadJob) -> Result<Loaded, String> {
        let t = Instant::now();
        loop {
            if let Some(r) = job.poll() {
                return r;
            }
            assert!(t.elapsed() < Duration::from_secs(20), "load timed out");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn histogram_counts_every_integer_value_in_its_own_bin() {
        let grid = Grid::new(UVec3::new(4, 5, 6), Vec3::ONE);
        let v = AnyVolume::from_fn(grid, |p| (p.x * 10) as u8 + 3);
        let h = Histogram::of(&v, (3.0, 33.0), |_| {});
        assert_eq!(h.counts.len(), 31);
        assert_eq!(h.counts.iter().sum::<u64>(), 120);
        for (i, &c) in h.counts.iter().enumerate() {
            assert_eq!(c, if i % 10 == 0 { 30 } else { 0 }, "bin {i}");
        }
    }

    /// A mapped volume larger than the sample budget is counted in whole
    /// blocks: about the budget's worth of voxels, spread over the volume
    /// (both halves show in proportion), and none of the bricks' padding.
    #[test]
    fn a_large_mapped_volume_is_counted_in_blocks_without_padding() {
        let dir = std::env::temp_dir().join(format!("vol_app-hist-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("halves.vol");
        let dims = UVec3::splat(131); // 9 bricks of 16 per axis: padded
        let v = AnyVolume::from_fn(
            Grid::new(dims, Vec3::ONE),
            |p| {
                if p.x < 65 { 7u8 } else { 3 }
            },
        );
        raycaster::format::vol::write(
            &path,
            &v,
            raycaster::format::vol::VolLayout::Bricked { side: 16 },
        )
        .unwrap();
        let mapped = raycaster::format::open(&path, LoadMode::Map).unwrap();
        assert_eq!(mapped.storage_kind(), StorageKind::Mapped);
        let h = Histogram::of(&mapped, (0.0, 7.0), |_| {});
        std::fs::remove_dir_all(&dir).ok();
        let total: u64 = h.counts.iter().sum();
        assert!(
            (HISTOGRAM_SAMPLES / 2..=HISTOGRAM_SAMPLES).contains(&total),
            "{total}"
        );
        assert_eq!(h.counts[0], 0, "padding counted");
        assert_eq!(total, h.counts[3] + h.counts[7]);
        let share = h.counts[7] as f64 / total as f64;
        assert!((0.4..0.6).contains(&share), "{share}");
    }

    /// A ramp `v = 2·x` with x spacing 0.5 has `|∇f| = 4` everywhere but on
    /// its two x faces, where SPEC §8's index-clamped difference gives 2.
    #[test]
    fn gradient_histogram_of_a_ramp_has_the_ramps_slope() {
        let dims = UVec3::new(20, 6, 7);
        let grid = Grid::new(dims, Vec3::new(0.5, 1.0, 2.0));
        let v = AnyVolume::from_fn(grid, |p| (p.x * 2) as u8);
        let h = GradientHistogram::of(&v);
        let total: u64 = h.counts.iter().sum();
        assert_eq!(total, 20 * 6 * 7);
        let faces = 2 * 6 * 7;
        assert_eq!(h.counts[h.bin_of(4.0)], total - faces, "{h:?}");
        assert_eq!(h.counts[h.bin_of(2.0)], faces, "{h:?}");
        assert!((h.hi - 6.0).abs() < 1e-4, "{}", h.hi);
    }

    /// A mapped volume larger than the budget is sampled in blocks, and a
    /// step edge shows as large gradients beside a zero peak.
    #[test]
    fn gradient_histogram_of_a_large_mapped_volume_samples_blocks() {
        let dir = std::env::temp_dir().join(format!("vol_app-ghist-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("step.vol");
        let dims = UVec3::splat(80);
        let v = AnyVolume::from_fn(
            Grid::new(dims, Vec3::ONE),
            |p| {
                if p.x < 30 { 0u8 } else { 200 }
            },
        );
        raycaster::format::vol::write(&path, &v, raycaster::format::vol::VolLayout::Linear)
            .unwrap();
        let mapped = raycaster::format::open(&path, LoadMode::Map).unwrap();
        let h = GradientHistogram::of(&mapped);
        std::fs::remove_dir_all(&dir).ok();
        let total: u64 = h.counts.iter().sum();
        assert_eq!(total, 64u64.pow(3), "4³ blocks of 16³");
        // Blocks start at x = 0, 21, 42, 64; the one at 21 holds the edge:
        // voxels x = 29 and 30 have |∇f| = (200 − 0)/2, 16 × 16 of them per
        // block and plane, in 4 × 4 blocks along y and z.
        let edge = 2 * 16 * 16 * 16;
        assert_eq!(h.counts[h.bin_of(100.0)], edge, "{h:?}");
        assert_eq!(h.counts[0], total - edge);
        assert!((h.hi - 150.0).abs() < 1e-3, "{}", h.hi);
    }

    /// The viewer's memory limit refuses a gzip file that would decode past
    /// it, with the file and the limit in the message.
    #[test]
    fn a_volume_over_the_memory_limit_is_an_error_naming_the_limit() {
        let dir = std::env::temp_dir().join(format!("vol_app-maxmem-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("v.nrrd");
        let v = AnyVolume::from_fn(Grid::new(UVec3::splat(40), Vec3::ONE), |p| p.x as u16);
        let gzip = raycaster::format::save::SaveOptions {
            gzip: true,
            ..Default::default()
        };
        raycaster::format::save::save(&path, &v, &gzip).unwrap();
        let source = Source::File(path.clone(), LoadMode::Map, None);
        let limited = LoadOptions {
            no_cache: true,
            max_memory: Some(100_000),
        };
        let err = wait(&LoadJob::start(source.clone(), limited, || {})).unwrap_err();
        let roomy = LoadOptions {
            max_memory: Some(128_000),
            ..limited
        };
        let ok = wait(&LoadJob::start(source, roomy, || {}));
        std::fs::remove_dir_all(&dir).ok();
        assert!(
            err.contains("v.nrrd") && err.contains("more than the limit of"),
            "{err}"
        );
        assert!(ok.is_ok());
        assert!(default_memory_limit().is_some_and(|m| m > 0));
    }

    /// A folder holding one scan and its licence loads the scan.
    #[test]
    fn a_folder_with_one_scan_loads_the_scan() {
        let dir = std::env::temp_dir().join(format!("vol_app-folder-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let v = AnyVolume::from_fn(Grid::new(UVec3::new(9, 7, 5), Vec3::ONE), |p| p.x as u16);
        raycaster::format::save::save(&dir.join("scan.nrrd"), &v, &Default::default()).unwrap();
        std::fs::write(dir.join("LICENSE"), "Permission is hereby granted").unwrap();
        let source = Source::File(dir.clone(), LoadMode::Map, None);
        let loaded = wait(&LoadJob::start(source, LoadOptions::default(), || {}));
        std::fs::remove_dir_all(&dir).ok();
        let loaded = loaded.unwrap();
        assert_eq!(loaded.info.dims, UVec3::new(9, 7, 5));
        assert_eq!(loaded.info.name, "scan.nrrd");
    }

    #[test]
    fn the_demo_loads_and_a_missing_file_is_an_error() {
        let job = LoadJob::start(Source::Demo, LoadOptions::default(), || {});
        let loaded = wait(&job).unwrap();
        assert_eq!(loaded.info.dims, UVec3::splat(crate::demo::DEMO_SIZE));
        assert_eq!(loaded.info.storage, StorageKind::Ram);
        assert!(loaded.histogram.counts.iter().sum::<u64>() > 0);
        let job = LoadJob::start(
            Source::File("/nonexistent/x.vol".into(), LoadMode::Map, None),
            LoadOptions::default(),
            || {},
        );
        let err = wait(&job).unwrap_err();
        assert!(err.contains("/nonexistent/x.vol"), "{err}");
    }
}

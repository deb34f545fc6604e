//! A [`Scene`]: a volume together with the acceleration data built from it
//! once, ready to be rendered any number of times.
//!
//! Renderers reach the volume's concrete type once per frame through
//! [`AnyVolume::visit`], never per sample.
//!
//! [`Scene::open`] opens a file and finds its macrocell grid in the
//! file's cache ([`crate::accel::cache`]) when there is a valid one, so
//! that opening a huge memory-mapped volume reads a few megabytes instead
//! of the whole file; otherwise it builds the grid and writes the cache.

use std::path::{Path, PathBuf};

use crate::accel::MacrocellGrid;
use crate::accel::cache::{self, CacheKey, CacheMiss, CachePolicy, GridShape};
use crate::error::Result;
use crate::format::{OpenOptions, Progress, VolumeInfo};
use crate::volume::{AnyVolume, Grid};

/// A volume and its macrocell value ranges.
#[derive(Debug)]
pub struct Scene {
    id: u64,
    volume: AnyVolume,
    macrocells: MacrocellGrid,
    value_range: (f32, f32),
}

impl Scene {
    /// Builds the macrocell grid of `volume` (one pass over the data) with
    /// the default macrocell size (see [`default_macrocell`]).
    pub fn new(volume: AnyVolume) -> Self {
        Self::with_options(volume, &SceneOptions::default())
    }

    /// As [`Scene::new`] with an explicit macrocell side in voxels.
    pub fn with_macrocell(volume: AnyVolume, cell: u32) -> Self {
        Self::with_options(
            volume,
            &SceneOptions {
                macrocell: Some(cell),
                ..SceneOptions::default()
            },
        )
    }

    /// Builds the macrocell grid of `volume` as `options` say (side and
    /// progress; the cache options apply to [`Scene::open`] only), in
    /// parallel on the current rayon pool.
    pub fn with_options(volume: AnyVolume, options: &SceneOptions) -> Self {
        let cell = options
            .macrocell
            .unwrap_or_else(|| default_macrocell(volume.grid().dims));
        let grid = MacrocellGrid::build_any(&volume, cell, options.progress.as_ref());
        Self::from_grid(volume, grid)
    }

    /// Opens the volume file `path` (see [`crate::format::open_file`]) and
    /// makes its scene, reading the macrocell grid from the file's cache
    /// when a valid one exists and writing one when it is built (see
    /// [`crate::accel::cache`] for where, and when a cache is stale). A
    /// cache that cannot be read or written costs a warning in the
    /// [`CacheReport`], never the open. Files whose samples come from more
    /// than the one file named (a detached NRRD header, a DICOM series) get
    /// no cache. A folder holding one volume file opens that file, with its
    /// cache ([`crate::sequence::resolve_dir`]).
    pub fn open(path: &Path, open: &OpenOptions, options: &SceneOptions) -> Result<OpenedScene> {
        let path = &*crate::format::volume_path(path, open);
        let opened = crate::format::open_file(path, open)?;
        let volume = opened.volume;
        let cell = options
            .macrocell
            .unwrap_or_else(|| default_macrocell(volume.grid().dims))
            .max(1);
        let shape = GridShape {
            sample_type: volume.sample_type(),
            dims: volume.grid().dims,
            cell,
        };
        let mut report = CacheReport::default();
        let key = match options.cache {
            CachePolicy::Off => None,
            CachePolicy::Auto => cache_key(path, &opened.info, open, &mut report),
        };
        let cached = key.as_ref().and_then(|key| {
            find_cached_macrocells(path, key, shape, options.cache_dir.as_deref(), &mut report)
        });
        // The grid, and whether the cache must be written: when there was
        // none, or when it was written from ranges alone (a distributed
        // run's first pass), whose uniform flags are right but fewer, so
        // shaded frames would march cells they could composite: those are
        // completed once and kept.
        let (grid, save) = match cached {
            Some(mut grid) if !grid.shells_found => {
                grid.find_uniform_shells_any(&volume);
                (grid, true)
            }
            Some(grid) => (grid, false),
            None => (
                MacrocellGrid::build_any(&volume, cell, options.progress.as_ref()),
                true,
            ),
        };
        if save && let Some(key) = &key {
            save_cached_macrocells(
                path,
                key,
                shape,
                &grid,
                options.cache_dir.as_deref(),
                &mut report,
            );
        }
        Ok(OpenedScene {
            scene: Self::from_grid(volume, grid),
            info: opened.info,
            cache: report,
        })
    }

    /// The scene of `volume` with its grid `macrocells`.
    fn from_grid(volume: AnyVolume, macrocells: MacrocellGrid) -> Self {
        let value_range = macrocells.value_range();
        static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Scene {
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            volume,
            macrocells,
            value_range,
        }
    }

    /// A number unique to this scene in this process (keys renderers' caches).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The volume.
    pub fn volume(&self) -> &AnyVolume {
        &self.volume
    }

    /// Dimensions, spacing and origin.
    pub fn grid(&self) -> &Grid {
        self.volume.grid()
    }

    /// The macrocell grid.
    pub fn macrocells(&self) -> &MacrocellGrid {
        &self.macrocells
    }

    /// Smallest and largest voxel value.
    pub fn value_range(&self) -> (f32, f32) {
        self.value_range
    }

    /// An error when the volume is a mapped file that another program has
    /// truncated or modified since it was opened (reading it could crash
    /// the process with SIGBUS, or render stale skip data); see
    /// `storage::Source`. Every renderer checks it before each frame.
    pub fn check_source(&self) -> Result<()> {
        self.volume.storage().check_source()
    }
}

/// How [`Scene::open`] and [`Scene::with_options`] make the acceleration
/// data.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneOptions {
    /// Macrocell side in voxels; `None` for [`default_macrocell`].
    pub macrocell: Option<u32>,
    /// Whether [`Scene::open`] reads and writes the macrocell cache.
    pub cache: CachePolicy,
    /// Where caches go (and are looked for) besides the volume's own
    /// directory; `None` for [`cache::user_cache_dir`].
    pub cache_dir: Option<PathBuf>,
    /// Told the fraction of the macrocell grid built (not called when the
    /// grid comes from the cache).
    pub progress: Option<Progress>,
}

/// What [`Scene::open`] did with the macrocell cache.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CacheReport {
    /// The cache the grid was read from.
    pub loaded: Option<PathBuf>,
    /// The cache the grid was written to after building it (or after
    /// completing the uniform flags of a cache made from ranges alone).
    pub saved: Option<PathBuf>,
    /// Caches ignored as damaged, or that could not be written: for the
    /// user, once per open.
    pub warnings: Vec<String>,
}

/// A scene opened from a file.
#[derive(Debug)]
pub struct OpenedScene {
    /// The volume and its acceleration data.
    pub scene: Scene,
    /// What the file stores.
    pub info: VolumeInfo,
    /// Where the macrocell grid came from or went.
    pub cache: CacheReport,
}

/// The cache key of `path`, or `None` when the file gets no cache: when it
/// is not one regular file holding all the samples (a DICOM series, a
/// detached header), or when it cannot be read for the key (then with a
/// warning).
fn cache_key(
    path: &Path,
    info: &VolumeInfo,
    open: &OpenOptions,
    report: &mut CacheReport,
) -> Option<CacheKey> {
    let meta = std::fs::metadata(path).ok()?;
    // A file of several volumes (a 4-D file, a sequence) would need one
    // cache per volume under one name; its frames are built as they come.
    if !meta.is_file() || meta.len() != info.file_bytes || info.volumes > 1 {
        return None;
    }
    // How the bytes were read: a raw file read with other dimensions or
    // type is another volume.
    let description = match &open.raw {
        Some(raw) => format!("{} {raw:?}", info.format.name()),
        None => info.format.name().to_string(),
    };
    match CacheKey::of(path, &description) {
        Ok(key) => Some(key),
        Err(e) => {
            report.warnings.push(format!(
                "{}: no macrocell cache: cannot read the file's fingerprint: {e}",
                path.display()
            ));
            None
        }
    }
}

/// The macrocell grid of the volume file `path` (identified by `key`, of
/// `shape`) from a valid cache in the places [`Scene::open`] looks (next
/// to the volume, then `dir` or the per-user cache directory), or `None`.
/// A damaged cache adds a warning to `report`; the one read is noted there.
pub fn find_cached_macrocells(
    path: &Path,
    key: &CacheKey,
    shape: GridShape,
    dir: Option<&Path>,
    report: &mut CacheReport,
) -> Option<MacrocellGrid> {
    for place in cache_places(path, shape.cell, dir) {
        match cache::load(&place, key, shape) {
            Ok(grid) => {
                report.loaded = Some(place);
                return Some(grid);
            }
            Err(CacheMiss::Corrupt(why)) => report.warnings.push(format!(
                "{}: ignoring a damaged macrocell cache ({why}); rebuilding it",
                place.display()
            )),
            Err(CacheMiss::Absent | CacheMiss::Stale) => {}
        }
    }
    None
}

/// Writes `grid` as the macrocell cache of the volume file `path` in the
/// first of [`Scene::open`]'s places that takes it; where none does, adds
/// a warning to `report` (a cache is an optimisation, never an error).
pub fn save_cached_macrocells(
    path: &Path,
    key: &CacheKey,
    shape: GridShape,
    grid: &MacrocellGrid,
    dir: Option<&Path>,
    report: &mut CacheReport,
) {
    let mut failures = Vec::new();
    for place in cache_places(path, shape.cell, dir) {
        // A directory without write permission is left alone even by a
        // process that could write into it anyway (root): a shared data
        // set, read-only on purpose.
        if let Some(dir) = place.parent().filter(|d| !d.as_os_str().is_empty())
            && std::fs::metadata(dir).is_ok_and(|m| m.permissions().readonly())
        {
            failures.push(format!("{}: a read-only directory", dir.display()));
            continue;
        }
        let made = match place.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => {
                std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))
            }
            _ => Ok(()),
        };
        match made.and_then(|()| cache::store(&place, key, shape, grid).map_err(|e| e.to_string()))
        {
            Ok(()) => {
                report.saved = Some(place);
                return;
            }
            Err(e) => failures.push(e),
        }
    }
    report.warnings.push(format!(
        "{}: could not save the macrocell cache, so the next open reads the whole volume again ({})",
        path.display(),
        if failures.is_empty() {
            "no per-user cache directory".to_string()
        } else {
            failures.join("; ")
        }
    ));
}

/// Where the cache of `path` may be, in the order looked in and written:
/// next to the volume, then in `dir` (or the per-user cache directory).
fn cache_places(path: &Path, cell: u32, dir: Option<&Path>) -> Vec<PathBuf> {
    let mut places = vec![cache::sidecar_path(path, cell)];
    if let Some(dir) = dir.map(Path::to_path_buf).or_else(cache::user_cache_dir) {
        places.push(cache::cache_path_in(&dir, path, cell));
    }
    places
}

/// The macrocell side used by [`Scene::new`]: the smallest of 4, 8, 16, 32
/// voxels that keeps the grid within 16 M cells. Small cells skip more empty
/// space and find more uniform regions (measured on the 800³ benchmark: 4³
/// cells take 24% fewer instructions per frame than 8³); the cap bounds the
/// memory and the per-transfer-function rebuild time of huge volumes.
pub fn default_macrocell(dims: glam::UVec3) -> u32 {
    let cells = |m: u32| {
        let n = |d: u32| (d.max(2) - 1).div_ceil(m) as u64;
        n(dims.x) * n(dims.y) * n(dims.z)
    };
    [4, 8, 16]
        .into_iter()
        .find(|&m| cells(m) <= 1 << 24)
        .unwrap_or(32)
}

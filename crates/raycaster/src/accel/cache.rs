//! The macrocell cache: a volume file's [`MacrocellGrid`] kept in a sidecar
//! file, so that opening the volume again reads a few megabytes instead of
//! every page of the volume.
//!
//! Building the grid reads every sample. For a memory-mapped file that
//! means paging in the whole file, although a frame touches only the bricks
//! its rays cross; with the cache the open reads the cache and a few sampled
//! blocks of the volume (the fingerprint below), and rendering maps only
//! what it samples.
//!
//! **Where.** Next to the volume, as `NAME.m<side>.rcidx` (one file per
//! macrocell side, so the side is part of the key); where that cannot be
//! written, or the directory is read-only by its permissions (respected
//! even by root), in the per-user cache directory
//! (`$XDG_CACHE_HOME/raycaster`, else `~/.cache/raycaster`) under a name
//! that adds a hash of the volume's absolute path. Both places are looked
//! in when opening.
//!
//! **Staleness.** A cache holds the key of the file it was built from: its
//! length, its modification time, a CRC-32 of its first 64 KiB (every
//! header of the formats read) and of 16 blocks of 4 KiB spread evenly over
//! the rest, and a description of how the file was read (format, raw
//! description). A cache whose key differs from the file's is rebuilt. The
//! grid it holds must also have the volume's dimensions, sample type and
//! macrocell side.
//!
//! **Damage.** A CRC-32 over the whole cache file guards against a
//! truncated or damaged cache; such a file is ignored with a warning and
//! rebuilt. Caches are written under a temporary name and renamed
//! ([`write_atomically_unsynced`](crate::format::atomic::write_atomically_unsynced)),
//! so a reader never sees half of one; they are not synced to the disk,
//! since the checksum catches what a crash may leave.
//!
//! **The file** (all numbers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 0..8 | magic `RCMCIDX\0` |
//! | 8..12 | version, `u32` (3) |
//! | 12..20 | the volume file's length, `u64` |
//! | 20..28, 28..32 | its modification time: seconds since the Unix epoch `i64`, nanoseconds `u32` |
//! | 32..36 | the CRC-32 fingerprint of its sampled bytes, `u32` |
//! | 36..40, 40.. | length `u32` and UTF-8 bytes of the description of how it was read |
//! | then | sample type `u8` (0 u8, 1 i8, 2 u16, 3 i16, 4 f32), dimensions 3 × `u32`, macrocell side `u32`, cells per axis 3 × `u32` |
//! | then | per cell (x slowest, z fastest) its minimum and maximum in the sample type |
//! | then | `u8` 1 when the uniform flags include the cells found by their voxel shells ([`MacrocellGrid::shells_found`]), else 0 |
//! | then | the uniform flags ([`MacrocellGrid::uniform`]), one bit per cell, least significant bit first |
//! | last 4 | CRC-32 of all bytes before it |

use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use glam::UVec3;

use super::MacrocellGrid;
use crate::sample::SampleType;

const MAGIC: &[u8; 8] = b"RCMCIDX\0";
/// 3 since a cache says whether its uniform flags include the cells found
/// by their voxel shells (a distributed run's first pass writes flags from
/// the ranges alone; an open completes them). Version 1 held only those
/// flags, and version 2 did not say which it held: both are rebuilt.
const VERSION: u32 = 3;
/// Bytes of the file's start in the fingerprint: every header the readers
/// parse (NIfTI's 352 bytes, NRRD's text header, the `.vol` 26 bytes).
const HEAD_BYTES: u64 = 64 << 10;
/// Blocks sampled from the rest of the file, and their size.
const SAMPLED_BLOCKS: u64 = 16;
const BLOCK_BYTES: u64 = 4 << 10;

/// Whether [`Scene::open`](crate::scene::Scene::open) keeps the macrocell
/// grid in a cache file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CachePolicy {
    /// Read the cache when it is valid; otherwise build the grid and write
    /// the cache (next to the volume, else in the per-user cache
    /// directory).
    #[default]
    Auto,
    /// Neither read nor write a cache: build the grid from the samples.
    Off,
}

/// What identifies the file a cache was built from (see the module
/// documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheKey {
    /// Length of the volume file in bytes.
    pub len: u64,
    /// Modification time: seconds since the Unix epoch and nanoseconds.
    pub mtime: (i64, u32),
    /// CRC-32 of the file's head and sampled blocks.
    pub fingerprint: u32,
    /// How the file was read (format and raw description).
    pub description: String,
}

impl CacheKey {
    /// The key of `path` as it is now, read as `description` says.
    pub fn of(path: &Path, description: &str) -> std::io::Result<Self> {
        let mut file = std::fs::File::open(path)?;
        let meta = file.metadata()?;
        let len = meta.len();
        let mtime = match meta.modified()?.duration_since(std::time::UNIX_EPOCH) {
            Ok(d) => (d.as_secs() as i64, d.subsec_nanos()),
            Err(before) => {
                let d = before.duration();
                (-(d.as_secs() as i64), d.subsec_nanos())
            }
        };
        let mut crc = crc32fast::Hasher::new();
        let mut buf = vec![0u8; HEAD_BYTES as usize];
        let head = HEAD_BYTES.min(len);
        file.read_exact(&mut buf[..head as usize])?;
        crc.update(&buf[..head as usize]);
        if len > HEAD_BYTES + BLOCK_BYTES {
            // Evenly spaced blocks after the head, the last ending at the
            // file's end.
            let span = len - HEAD_BYTES - BLOCK_BYTES;
            for i in 0..SAMPLED_BLOCKS {
                let at = HEAD_BYTES + span * (i + 1) / SAMPLED_BLOCKS;
                file.seek(SeekFrom::Start(at))?;
                file.read_exact(&mut buf[..BLOCK_BYTES as usize])?;
                crc.update(&buf[..BLOCK_BYTES as usize]);
            }
        }
        Ok(CacheKey {
            len,
            mtime,
            fingerprint: crc.finalize(),
            description: description.to_string(),
        })
    }
}

/// Why a cache file was not used.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheMiss {
    /// There is none (or it cannot be read).
    Absent,
    /// It was built from another version of the file, or for another
    /// macrocell side or reading: rebuild it silently.
    Stale,
    /// It is damaged (truncated, wrong checksum, not a cache): rebuild it
    /// and tell the user.
    Corrupt(String),
}

/// What a grid must look like to be the one of this volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridShape {
    /// The volume's sample type.
    pub sample_type: SampleType,
    /// The volume's dimensions.
    pub dims: UVec3,
    /// Macrocell side in voxels.
    pub cell: u32,
}

/// The sidecar name of the cache of `volume` for macrocells of `cell`
/// voxels: `NAME.m<cell>.rcidx` in the volume's directory.
pub fn sidecar_path(volume: &Path, cell: u32) -> PathBuf {
    let name = volume
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    volume.with_file_name(format!("{name}.m{cell}.rcidx"))
}

/// The per-user cache directory: `$XDG_CACHE_HOME/raycaster`, else
/// `$HOME/.cache/raycaster` (`%LOCALAPPDATA%\raycaster` on Windows); `None`
/// when none of these is set.
pub fn user_cache_dir() -> Option<PathBuf> {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    var("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| var("HOME").map(|h| Path::new(&h).join(".cache")))
        .or_else(|| var("LOCALAPPDATA").map(PathBuf::from))
        .map(|d| d.join("raycaster"))
}

/// The name of the cache of `volume` in a shared cache directory `dir`: the
/// sidecar name prefixed with a hash of the volume's absolute path, so that
/// volumes of one name in different directories do not share a cache.
pub fn cache_path_in(dir: &Path, volume: &Path, cell: u32) -> PathBuf {
    let absolute = std::fs::canonicalize(volume).unwrap_or_else(|_| volume.to_path_buf());
    // FNV-1a (64 bits): stable across builds and platforms, unlike std's
    // hasher, so that a cache name survives an upgrade.
    let hash = absolute
        .to_string_lossy()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
        });
    let sidecar = sidecar_path(volume, cell);
    let name = sidecar
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    dir.join(format!("{hash:016x}-{name}"))
}

/// Reads the cache at `path` for a volume whose file has key `key` and
/// whose grid must have `shape`.
pub fn load(path: &Path, key: &CacheKey, shape: GridShape) -> Result<MacrocellGrid, CacheMiss> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(_) => return Err(CacheMiss::Absent),
    };
    decode(&bytes, key, shape)
}

/// Writes `grid`, the grid of the file with key `key`, to `path`
/// atomically.
pub fn store(
    path: &Path,
    key: &CacheKey,
    shape: GridShape,
    grid: &MacrocellGrid,
) -> crate::Result<()> {
    let bytes = encode(key, shape, grid);
    // Not synced: a cache that a crash leaves half-written fails its
    // checksum and is rebuilt.
    crate::format::atomic::write_atomically_unsynced(path, |w| std::io::Write::write_all(w, &bytes))
}

fn type_tag(t: SampleType) -> u8 {
    match t {
        SampleType::U8 => 0,
        SampleType::I8 => 1,
        SampleType::U16 => 2,
        SampleType::I16 => 3,
        SampleType::F32 => 4,
    }
}

/// The cache file's bytes.
fn encode(key: &CacheKey, shape: GridShape, grid: &MacrocellGrid) -> Vec<u8> {
    let cells = grid.ranges.len();
    let size = shape.sample_type.size();
    let mut out = Vec::with_capacity(80 + key.description.len() + cells * 2 * size + cells / 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&key.len.to_le_bytes());
    out.extend_from_slice(&key.mtime.0.to_le_bytes());
    out.extend_from_slice(&key.mtime.1.to_le_bytes());
    out.extend_from_slice(&key.fingerprint.to_le_bytes());
    out.extend_from_slice(&(key.description.len() as u32).to_le_bytes());
    out.extend_from_slice(key.description.as_bytes());
    out.push(type_tag(shape.sample_type));
    for v in [shape.dims.x, shape.dims.y, shape.dims.z, grid.cell] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in grid.count.to_array() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    // The ranges hold values of the sample type (exact in f32), so they go
    // back to that type: a quarter of the bytes for 8-bit data.
    let values = grid.ranges.iter().flat_map(|&(lo, hi)| [lo, hi]);
    match shape.sample_type {
        SampleType::U8 => out.extend(values.map(|v| v as u8)),
        SampleType::I8 => out.extend(values.map(|v| v as i8 as u8)),
        SampleType::U16 => values.for_each(|v| out.extend_from_slice(&(v as u16).to_le_bytes())),
        SampleType::I16 => values.for_each(|v| out.extend_from_slice(&(v as i16).to_le_bytes())),
        SampleType::F32 => values.for_each(|v| out.extend_from_slice(&v.to_le_bytes())),
    }
    out.push(grid.shells_found as u8);
    for chunk in grid.uniform.chunks(8) {
        out.push(
            chunk
                .iter()
                .enumerate()
                .fold(0u8, |b, (i, &u)| b | (u as u8) << i),
        );
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// A little-endian reader over a byte slice that reports running out.
struct Cursor<'a>(&'a [u8]);

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CacheMiss> {
        if self.0.len() < n {
            return Err(CacheMiss::Corrupt("cut short".into()));
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Ok(a)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], CacheMiss> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn u32(&mut self) -> Result<u32, CacheMiss> {
        self.array().map(u32::from_le_bytes)
    }
}

fn decode(bytes: &[u8], key: &CacheKey, shape: GridShape) -> Result<MacrocellGrid, CacheMiss> {
    let corrupt = |why: &str| CacheMiss::Corrupt(why.to_string());
    if bytes.len() < MAGIC.len() + 8 || &bytes[..MAGIC.len()] != MAGIC {
        return Err(corrupt("not a macrocell cache"));
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    let mut c = Cursor(&body[MAGIC.len()..]);
    if c.u32()? != VERSION {
        // Another version's cache: rebuilt and replaced, no warning.
        return Err(CacheMiss::Stale);
    }
    if crc32fast::hash(body).to_le_bytes() != crc {
        return Err(corrupt("checksum mismatch (truncated or damaged)"));
    }
    let len = u64::from_le_bytes(c.array()?);
    let mtime = (i64::from_le_bytes(c.array()?), c.u32()?);
    let fingerprint = c.u32()?;
    let n = c.u32()? as usize;
    let description = c.take(n)?;
    if len != key.len
        || mtime != key.mtime
        || fingerprint != key.fingerprint
        || description != key.description.as_bytes()
    {
        return Err(CacheMiss::Stale);
    }
    let tag = c.take(1)?[0];
    let dims = UVec3::new(c.u32()?, c.u32()?, c.u32()?);
    let cell = c.u32()?;
    let count = UVec3::new(c.u32()?, c.u32()?, c.u32()?);
    if tag != type_tag(shape.sample_type) || dims != shape.dims || cell != shape.cell {
        return Err(CacheMiss::Stale);
    }
    if count != MacrocellGrid::count_for(dims, cell) {
        return Err(corrupt("cell count does not fit the dimensions"));
    }
    let cells = count.as_u64vec3().element_product() as usize;
    let size = shape.sample_type.size();
    let values = c.take(cells * 2 * size)?;
    let shells_found = match c.take(1)?[0] {
        0 => false,
        1 => true,
        _ => return Err(corrupt("bad shells flag")),
    };
    let uniform = c.take(cells.div_ceil(8))?;
    if !c.0.is_empty() {
        return Err(corrupt("trailing bytes"));
    }
    // Millions of cells for a large volume (16 M at most): decoded in
    // parallel on the current rayon pool, each decoder monomorphised so the
    // loop vectorises.
    fn pairs<const N: usize>(values: &[u8], f: fn([u8; N]) -> f32) -> Vec<(f32, f32)> {
        use rayon::prelude::*;
        values
            .par_chunks_exact(2 * N)
            .with_min_len(1 << 14)
            .map(|p| {
                let (a, b) = p.split_at(N);
                let v = |x: &[u8]| f(std::array::from_fn(|i| x[i]));
                (v(a), v(b))
            })
            .collect()
    }
    let ranges = match shape.sample_type {
        SampleType::U8 => pairs::<1>(values, |b| b[0] as f32),
        SampleType::I8 => pairs::<1>(values, |b| b[0] as i8 as f32),
        SampleType::U16 => pairs::<2>(values, |b| u16::from_le_bytes(b) as f32),
        SampleType::I16 => pairs::<2>(values, |b| i16::from_le_bytes(b) as f32),
        SampleType::F32 => pairs::<4>(values, f32::from_le_bytes),
    };
    use rayon::prelude::*;
    // (NaN compares false both ways, as the sequential check did.)
    if ranges
        .par_iter()
        .with_min_len(1 << 14)
        .any(|&(lo, hi)| lo > hi)
    {
        return Err(corrupt("a cell's minimum exceeds its maximum"));
    }
    let uniform = (0..cells)
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|i| uniform[i / 8] >> (i % 8) & 1 == 1)
        .collect();
    Ok(MacrocellGrid {
        cell,
        count,
        ranges,
        uniform,
        shells_found,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(t: SampleType) -> (GridShape, MacrocellGrid) {
        let dims = UVec3::new(9, 5, 13);
        let cell = 4;
        let count = MacrocellGrid::count_for(dims, cell);
        let n = count.as_u64vec3().element_product() as usize;
        let lo = if t == SampleType::U8 || t == SampleType::U16 {
            0.0
        } else {
            -7.0
        };
        let ranges = (0..n)
            .map(|i| (lo + (i % 5) as f32, lo + (i % 5 + i % 3) as f32))
            .collect();
        let shape = GridShape {
            sample_type: t,
            dims,
            cell,
        };
        (shape, MacrocellGrid::from_ranges(cell, count, ranges))
    }

    fn key() -> CacheKey {
        CacheKey {
            len: 1234,
            mtime: (1_700_000_000, 5),
            fingerprint: 0xdead_beef,
            description: "test".into(),
        }
    }

    #[test]
    fn every_sample_type_round_trips() {
        use SampleType::*;
        for t in [U8, I8, U16, I16, F32] {
            for shells in [false, true] {
                let (shape, mut g) = grid(t);
                g.shells_found = shells;
                let bytes = encode(&key(), shape, &g);
                let back = decode(&bytes, &key(), shape).unwrap();
                assert_eq!((back.cell, back.count), (g.cell, g.count), "{t}");
                assert_eq!(back.ranges, g.ranges, "{t}");
                assert_eq!(back.uniform, g.uniform, "{t}");
                assert_eq!(back.shells_found, shells, "{t}");
            }
        }
    }

    #[test]
    fn another_key_or_shape_is_stale_and_damage_is_corrupt() {
        let (shape, g) = grid(SampleType::I16);
        let bytes = encode(&key(), shape, &g);
        let stale = [
            CacheKey { len: 1, ..key() },
            CacheKey {
                mtime: (1_700_000_000, 6),
                ..key()
            },
            CacheKey {
                fingerprint: 1,
                ..key()
            },
            CacheKey {
                description: "raw".into(),
                ..key()
            },
        ];
        for k in &stale {
            assert_eq!(decode(&bytes, k, shape).unwrap_err(), CacheMiss::Stale);
        }
        for s in [
            GridShape { cell: 8, ..shape },
            GridShape {
                sample_type: SampleType::U16,
                ..shape
            },
            GridShape {
                dims: UVec3::new(9, 5, 12),
                ..shape
            },
        ] {
            assert_eq!(decode(&bytes, &key(), s).unwrap_err(), CacheMiss::Stale);
        }
        // Every truncation and every flipped byte is caught (no panic).
        for cut in 0..bytes.len() {
            let r = decode(&bytes[..cut], &key(), shape);
            assert!(matches!(r, Err(CacheMiss::Corrupt(_))), "cut at {cut}");
        }
        for at in (0..bytes.len()).step_by(7) {
            let mut b = bytes.clone();
            b[at] ^= 0x10;
            let r = decode(&b, &key(), shape);
            assert!(r.is_err(), "flip at {at}");
        }
    }

    #[test]
    fn cache_names_depend_on_the_side_and_the_directory() {
        let a = Path::new("/data/a/head.vol");
        assert_eq!(sidecar_path(a, 8), Path::new("/data/a/head.vol.m8.rcidx"));
        let dir = Path::new("/cache");
        let (x, y) = (
            cache_path_in(dir, a, 8),
            cache_path_in(dir, Path::new("/data/b/head.vol"), 8),
        );
        assert_ne!(x, y);
        assert!(x.starts_with(dir) && x.to_string_lossy().ends_with("-head.vol.m8.rcidx"));
        assert_ne!(cache_path_in(dir, a, 4), x);
    }
}

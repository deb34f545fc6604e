//! Voxel storage: samples held in RAM or memory-mapped from a file, behind
//! one type.
//!
//! A mapped file is never copied: opening a 10 GB volume costs a `mmap` call,
//! and the operating system pages data in as rays touch it.

use std::fs::File;
use std::path::Path;

use crate::error::{Error, Result};
use crate::sample::Sample;

/// Where a volume's samples live.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageKind {
    /// Owned memory.
    Ram,
    /// A read-only memory map of the file.
    Mapped,
}

/// How to bring a file's samples into memory when opening it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LoadMode {
    /// Map the file (the default: instant, works for files larger than RAM).
    #[default]
    Map,
    /// Read the whole file into RAM (on Linux, in transparent huge pages
    /// where available, which makes random sampling faster).
    Ram,
}

/// A contiguous run of samples of type `S`, owned or mapped.
pub struct Storage<S: Sample> {
    /// Keeps the memory that `ptr` points into alive.
    owner: Owner<S>,
    ptr: *const S,
    len: usize,
}

// The fields are only held, never read: they keep `ptr`'s memory alive.
#[allow(dead_code)]
enum Owner<S> {
    Owned(Vec<S>),
    /// A file mapped read-only.
    Mapped(memmap2::Mmap),
    /// RAM from an anonymous map (huge-page friendly), read-only.
    Anonymous(memmap2::Mmap),
}

// SAFETY: `ptr` points into memory owned by `owner` (a `Vec<S>` or a read-only
// map), which is immutable for the storage's whole life; `S: Send + Sync`, so
// sharing or sending the read-only view is as safe as sharing `&[S]`.
unsafe impl<S: Sample> Send for Storage<S> {}
// SAFETY: as for `Send`: the storage is never written after construction.
unsafe impl<S: Sample> Sync for Storage<S> {}

impl<S: Sample> Storage<S> {
    /// Storage that owns `samples`.
    pub fn from_vec(samples: Vec<S>) -> Self {
        let ptr = samples.as_ptr();
        let len = samples.len();
        Storage {
            owner: Owner::Owned(samples),
            ptr,
            len,
        }
    }

    /// Brings `len` samples starting at byte `offset` of `path` into memory,
    /// mapped or read according to `mode`. When the mapped bytes are not aligned
    /// for `S`, they are copied into RAM instead.
    pub fn open(path: &Path, offset: u64, len: usize, mode: LoadMode) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let too_large = || Error::InvalidArgument(format!("{}: volume too large", path.display()));
        let bytes = len
            .checked_mul(std::mem::size_of::<S>())
            .ok_or_else(too_large)?;
        let start = usize::try_from(offset).map_err(|_| too_large())?;
        let end = start.checked_add(bytes).ok_or_else(too_large)?;
        match mode {
            LoadMode::Map => {
                // SAFETY: the map is read-only. Its bytes could change under us
                // only if another process truncated or rewrote the file while it
                // is mapped (then reads fault or see new bytes, which never
                // breaks bounds: the length is fixed); that is the contract of
                // every memory-mapped reader, and the alternative (copying tens
                // of GB) defeats the purpose.
                let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
                if map.len() < end {
                    return Err(Error::InvalidArgument(format!(
                        "{}: file has {} bytes, fewer than its {} samples need",
                        path.display(),
                        map.len(),
                        len
                    )));
                }
                #[cfg(unix)]
                let _ = map.advise(memmap2::Advice::WillNeed);
                match bytemuck::try_cast_slice::<u8, S>(&map[start..end]) {
                    Ok(samples) => {
                        let ptr = samples.as_ptr();
                        Ok(Storage {
                            owner: Owner::Mapped(map),
                            ptr,
                            len,
                        })
                    }
                    // Misaligned for S: copy once rather than read unaligned
                    // in the hot loop.
                    Err(_) => Ok(Storage::from_vec(bytemuck::pod_collect_to_vec(
                        &map[start..end],
                    ))),
                }
            }
            LoadMode::Ram => {
                use std::io::{Read, Seek, SeekFrom};
                let mut f = file;
                f.seek(SeekFrom::Start(offset))
                    .map_err(|e| Error::io(path, e))?;
                let mut block = anonymous_block(bytes).map_err(|e| Error::io(path, e))?;
                f.read_exact(&mut block[..bytes])
                    .map_err(|e| Error::io(path, e))?;
                let map = block.make_read_only().map_err(|e| Error::io(path, e))?;
                let ptr = map.as_ptr() as *const S;
                // Anonymous maps are page-aligned, so aligned for every S.
                debug_assert!(bytemuck::try_cast_slice::<u8, S>(&map[..bytes]).is_ok());
                Ok(Storage {
                    owner: Owner::Anonymous(map),
                    ptr,
                    len,
                })
            }
        }
    }

    /// The samples.
    #[inline(always)]
    pub fn as_slice(&self) -> &[S] {
        // SAFETY: `ptr` and `len` describe memory owned by `self.owner`
        // (checked at construction: a Vec's own buffer, or a range inside the
        // map checked against the map's length and S's alignment). Neither a
        // Vec's heap buffer nor a map moves when the Storage moves, and the
        // owner is never mutated, so the slice is valid for `&self`'s lifetime.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the samples are in RAM or mapped from a file.
    pub fn kind(&self) -> StorageKind {
        match self.owner {
            Owner::Mapped(_) => StorageKind::Mapped,
            Owner::Owned(_) | Owner::Anonymous(_) => StorageKind::Ram,
        }
    }
}

impl<S: Sample> std::fmt::Debug for Storage<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Storage")
            .field("kind", &self.kind())
            .field("len", &self.len)
            .finish()
    }
}

/// Anonymous memory for `bytes` bytes (at least one page), backed by
/// transparent huge pages where the kernel allows: a volume read into RAM is
/// sampled at random, and 2 MB pages cut the TLB misses of such access.
fn anonymous_block(bytes: usize) -> std::io::Result<memmap2::MmapMut> {
    let block = memmap2::MmapMut::map_anon(bytes.max(1))?;
    #[cfg(target_os = "linux")]
    let _ = block.advise(memmap2::Advice::HugePage);
    Ok(block)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn owned_storage_round_trips() {
        let s = Storage::from_vec(vec![1u16, 2, 3]);
        assert_eq!(s.as_slice(), &[1, 2, 3]);
        assert_eq!(s.kind(), StorageKind::Ram);
    }

    #[test]
    fn mapped_and_ram_storage_agree_and_survive_moves_across_threads() {
        let dir = std::env::temp_dir().join(format!("rc-storage-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bytes.bin");
        let data: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&path, &data).unwrap();
        let mapped = Storage::<u8>::open(&path, 3, 9_000, LoadMode::Map).unwrap();
        let ram = Storage::<u8>::open(&path, 3, 9_000, LoadMode::Ram).unwrap();
        assert_eq!(mapped.kind(), StorageKind::Mapped);
        assert_eq!(mapped.as_slice(), &data[3..9_003]);
        assert_eq!(ram.as_slice(), mapped.as_slice());
        // Misaligned u16 view: copied, same values.
        let odd = Storage::<u16>::open(&path, 1, 100, LoadMode::Map).unwrap();
        let expect: Vec<u16> = data[1..201]
            .chunks(2)
            .map(|c| u16::from_ne_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(odd.as_slice(), &expect[..]);
        // Shared read-only access from several threads (the Send/Sync claim).
        let shared = std::sync::Arc::new(mapped);
        let sums: Vec<u64> = (0..4)
            .map(|_| {
                let s = shared.clone();
                std::thread::spawn(move || s.as_slice().iter().map(|&v| v as u64).sum::<u64>())
            })
            .map(|h| h.join().unwrap())
            .collect();
        let want: u64 = data[3..9_003].iter().map(|&v| v as u64).sum();
        assert!(sums.iter().all(|&s| s == want));
        // Too short a file is an error, not a bad read.
        assert!(Storage::<u8>::open(&path, 9_999, 2, LoadMode::Map).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}

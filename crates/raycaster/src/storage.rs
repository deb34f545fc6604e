//! Voxel storage: samples held in RAM or memory-mapped from a file, behind
//! one type.
//!
//! A mapped file is never copied: opening a 10 GB volume costs a `mmap` call,
//! and the operating system pages data in as rays touch it.

use std::fs::File;
use std::path::Path;

use crate::error::{Error, Result};
use crate::sample::{Sample, SampleType};

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

/// A contiguous array of samples of one [`SampleType`], owned or mapped.
///
/// The storage itself is untyped (the tag says what it holds), so one
/// volume type serves every sample type; [`Storage::as_slice`] hands out the
/// typed view once per frame, not per sample.
pub struct Storage {
    /// Keeps the memory that `ptr` points into alive.
    owner: Owner,
    ptr: *const u8,
    /// Number of samples.
    len: usize,
    sample_type: SampleType,
}

// The fields are only held, never read: they keep `ptr`'s memory alive.
#[allow(dead_code)]
enum Owner {
    /// A `Vec<S>` of the storage's sample type (type-erased; only dropped).
    Vec(Box<dyn std::any::Any + Send + Sync>),
    /// A file mapped read-only, with what [`Storage::check_source`] needs.
    Mapped(memmap2::Mmap, Source),
    /// RAM from an anonymous map (huge-page friendly), read-only.
    Anonymous(memmap2::Mmap),
}

// SAFETY: `ptr` points into memory owned by `owner` (a `Vec` or a read-only
// map), which is immutable for the storage's whole life; every sample type is
// plain data (`Pod + Send + Sync`), so sharing or sending the read-only view
// is as safe as sharing `&[S]`.
unsafe impl Send for Storage {}
// SAFETY: as for `Send`: the storage is never written after construction.
unsafe impl Sync for Storage {}

impl Storage {
    /// Storage that owns `samples`.
    pub fn from_vec<S: Sample>(samples: Vec<S>) -> Self {
        let ptr = samples.as_ptr() as *const u8;
        let len = samples.len();
        Storage {
            // Moving the Vec into the box moves its header, not its buffer.
            owner: Owner::Vec(Box::new(samples)),
            ptr,
            len,
            sample_type: S::TYPE,
        }
    }

    /// Brings `len` samples of `sample_type` starting at byte `offset` of
    /// `path` into memory, mapped or read according to `mode`. When the
    /// mapped bytes are not aligned for the type, they are copied into RAM
    /// instead.
    pub fn open(
        path: &Path,
        offset: u64,
        sample_type: SampleType,
        len: usize,
        mode: LoadMode,
    ) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let too_large = || Error::TooLarge {
            path: path.to_path_buf(),
            what: format!("{len} samples of {sample_type}"),
        };
        let bytes = len.checked_mul(sample_type.size()).ok_or_else(too_large)?;
        let start = usize::try_from(offset).map_err(|_| too_large())?;
        let end = start.checked_add(bytes).ok_or_else(too_large)?;
        let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        if file_len < end as u64 {
            return Err(Error::format(
                path,
                crate::error::FormatError::WrongLength {
                    expected: end as u64,
                    found: file_len,
                    detail: format!("{offset} bytes + {len} samples of {sample_type}"),
                },
            ));
        }
        let storage = |owner, ptr| Storage {
            owner,
            ptr,
            len,
            sample_type,
        };
        let in_ram = |fill: &mut dyn FnMut(&mut [u8]) -> std::io::Result<()>| {
            let map = read_only_block(bytes, fill).map_err(|e| Error::io(path, e))?;
            let ptr = map.as_ptr();
            Ok(storage(Owner::Anonymous(map), ptr))
        };
        match mode {
            LoadMode::Map => {
                // SAFETY: the map is read-only. Its bytes could change under us
                // only if another process truncated or rewrote the file while it
                // is mapped (then reads fault or see new bytes, which never
                // breaks bounds: the length is fixed); that is the contract of
                // every memory-mapped reader, and the alternative (copying tens
                // of GB) defeats the purpose.
                let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
                // (`get`: the file may have shrunk since its length was read.)
                let Some(mapped) = map.get(start..end) else {
                    return Err(Error::io(path, std::io::ErrorKind::UnexpectedEof.into()));
                };
                #[cfg(unix)]
                let _ = map.advise(memmap2::Advice::WillNeed);
                let ptr = mapped.as_ptr();
                if (ptr as usize).is_multiple_of(sample_type.size()) {
                    let source = Source::new(file, path, end as u64);
                    return Ok(storage(Owner::Mapped(map, source), ptr));
                }
                // Misaligned for the type: copy once into page-aligned RAM
                // rather than read unaligned in the hot loop.
                in_ram(&mut |block| {
                    block.copy_from_slice(mapped);
                    Ok(())
                })
            }
            LoadMode::Ram => {
                use std::io::{Read, Seek, SeekFrom};
                let mut f = file;
                in_ram(&mut |block| {
                    f.seek(SeekFrom::Start(offset))?;
                    f.read_exact(block)
                })
            }
        }
    }

    /// The samples as `S`, which must be the storage's sample type (panics
    /// otherwise: a caller bug, not a data problem).
    #[inline(always)]
    pub fn as_slice<S: Sample>(&self) -> &[S] {
        assert_eq!(S::TYPE, self.sample_type, "storage read as the wrong type");
        // SAFETY: `ptr` and `len` describe `len` samples of `sample_type`
        // (== S, checked above) in memory owned by `self.owner`, aligned for
        // the type (checked at construction: a Vec<S>'s own buffer, or a
        // page-aligned or alignment-checked range inside a map of sufficient
        // length). Neither a Vec's heap buffer nor a map moves when the
        // Storage moves, and the owner is never mutated, so the slice is
        // valid for `&self`'s lifetime.
        unsafe { std::slice::from_raw_parts(self.ptr as *const S, self.len) }
    }

    /// The samples as bytes in native byte order.
    pub fn as_bytes(&self) -> &[u8] {
        // SAFETY: as in `as_slice`: `len · size` bytes owned by `owner`,
        // and every byte of a plain-data sample is initialised.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len * self.sample_type.size()) }
    }

    /// Lets the operating system drop this process's mapping of the pages
    /// that lie wholly inside `bytes` (a range of [`Storage::as_bytes`]) of a
    /// mapped file; they stay in the page cache, and a later read maps them
    /// again with the same contents. A pass over the whole file (building the
    /// macrocell grid without its cache) calls this behind itself, so that
    /// the process's resident set stays a few slabs and not the file. Does
    /// nothing for samples in RAM, or where the system refuses.
    pub fn release_pages(&self, bytes: std::ops::Range<usize>) {
        #[cfg(unix)]
        if let Owner::Mapped(map, _) = &self.owner {
            // A multiple of every page size in use (4, 16 and 64 KiB), so
            // that the range is page-aligned wherever this runs.
            const PAGE: usize = 1 << 16;
            let base = self.ptr as usize - map.as_ptr() as usize;
            let end = (base + bytes.end.min(self.len * self.sample_type.size())) / PAGE * PAGE;
            let start = (base + bytes.start).div_ceil(PAGE) * PAGE;
            if start < end && end <= map.len() {
                // SAFETY: the map is a shared, read-only mapping of a file
                // (`Mmap::map`), never written through. Dropping its pages
                // only unmaps them from this process: the next access faults
                // them in again from the page cache or the file, with the
                // bytes the file holds, which are the bytes every `&[S]`
                // handed out has been reading (the same caveat as the map
                // itself: another process rewriting the file). It is not a
                // private or anonymous mapping, whose pages DONTNEED would
                // zero; `Owner::Mapped` holds only file maps.
                let _ = unsafe {
                    map.unchecked_advise_range(
                        memmap2::UncheckedAdvice::DontNeed,
                        start,
                        end - start,
                    )
                };
            }
        }
        #[cfg(not(unix))]
        let _ = bytes;
    }

    /// For a mapped file: an error when the file was changed in place since
    /// it was mapped (see `Source`); always `Ok` for samples in RAM. The
    /// frame driver calls it before every frame (one `fstat`).
    pub fn check_source(&self) -> Result<()> {
        match &self.owner {
            Owner::Mapped(_, source) => source.check(),
            _ => Ok(()),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The type of the samples.
    pub fn sample_type(&self) -> SampleType {
        self.sample_type
    }

    /// Whether the samples are in RAM or mapped from a file.
    pub fn kind(&self) -> StorageKind {
        match self.owner {
            Owner::Mapped(..) => StorageKind::Mapped,
            Owner::Vec(_) | Owner::Anonymous(_) => StorageKind::Ram,
        }
    }
}

impl std::fmt::Debug for Storage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Storage")
            .field("kind", &self.kind())
            .field("type", &self.sample_type)
            .field("len", &self.len)
            .finish()
    }
}

/// `bytes` bytes of anonymous memory (at least one page, so aligned for
/// every sample type) filled by `fill`, then made read-only. The memory is
/// backed by transparent huge pages where the kernel allows: a volume read
/// into RAM is sampled at random, and 2 MB pages cut the TLB misses of such
/// access.
fn read_only_block(
    bytes: usize,
    fill: &mut dyn FnMut(&mut [u8]) -> std::io::Result<()>,
) -> std::io::Result<memmap2::Mmap> {
    let mut block = memmap2::MmapMut::map_anon(bytes.max(1))?;
    #[cfg(target_os = "linux")]
    let _ = block.advise(memmap2::Advice::HugePage);
    fill(&mut block[..bytes])?;
    block.make_read_only()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn owned_storage_round_trips() {
        let s = Storage::from_vec(vec![1u16, 2, 3]);
        assert_eq!(s.as_slice::<u16>(), &[1, 2, 3]);
        assert_eq!(s.sample_type(), SampleType::U16);
        assert_eq!(s.kind(), StorageKind::Ram);
    }

    #[test]
    fn mapped_and_ram_storage_agree_and_survive_moves_across_threads() {
        let dir = std::env::temp_dir().join(format!("rc-storage-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bytes.bin");
        let data: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&path, &data).unwrap();
        let mapped = Storage::open(&path, 3, SampleType::U8, 9_000, LoadMode::Map).unwrap();
        let ram = Storage::open(&path, 3, SampleType::U8, 9_000, LoadMode::Ram).unwrap();
        assert_eq!(mapped.kind(), StorageKind::Mapped);
        assert_eq!(mapped.as_slice::<u8>(), &data[3..9_003]);
        assert_eq!(ram.as_slice::<u8>(), mapped.as_slice::<u8>());
        // Misaligned u16 view: copied, same values.
        let odd = Storage::open(&path, 1, SampleType::U16, 100, LoadMode::Map).unwrap();
        let expect: Vec<u16> = data[1..201]
            .chunks(2)
            .map(|c| u16::from_ne_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(odd.as_slice::<u16>(), &expect[..]);
        // Shared read-only access from several threads (the Send/Sync claim).
        let shared = std::sync::Arc::new(mapped);
        let sums: Vec<u64> = (0..4)
            .map(|_| {
                let s = shared.clone();
                std::thread::spawn(move || {
                    s.as_slice::<u8>().iter().map(|&v| v as u64).sum::<u64>()
                })
            })
            .map(|h| h.join().unwrap())
            .collect();
        let want: u64 = data[3..9_003].iter().map(|&v| v as u64).sum();
        assert!(sums.iter().all(|&s| s == want));
        // Too short a file is a length error naming the file, mapped or read.
        for mode in [LoadMode::Map, LoadMode::Ram] {
            let e = Storage::open(&path, 9_999, SampleType::U8, 2, mode).unwrap_err();
            assert!(
                matches!(e, Error::Format { .. }) && e.to_string().contains("bytes.bin"),
                "{mode:?}: {e}"
            );
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

/// The file behind a mapping, to notice when another program changes it.
///
/// Reading a mapped page past the end of a file that was truncated after
/// mapping raises SIGBUS and kills the process; a file rewritten in place
/// shows new bytes under a macrocell grid built from the old ones. So before
/// each frame the open file is `fstat`ed: a length below the mapped range or
/// a new modification time is an error ("reopen it") instead of a crash or
/// a wrong image. Replacing the file by renaming a new one over it (as this
/// library's writers do) leaves the open file, and so the mapping, intact:
/// it keeps rendering the old contents. What remains is a race: a file
/// truncated *during* a frame can still fault that frame.
#[derive(Debug)]
pub(crate) struct Source {
    file: File,
    path: std::path::PathBuf,
    /// The end of the mapped samples, in bytes from the file's start.
    end: u64,
    modified: Option<std::time::SystemTime>,
}

impl Source {
    fn new(file: File, path: &Path, end: u64) -> Self {
        let modified = file.metadata().and_then(|m| m.modified()).ok();
        Source {
            file,
            path: path.to_path_buf(),
            end,
            modified,
        }
    }

    fn check(&self) -> Result<()> {
        let meta = self.file.metadata().map_err(|e| Error::io(&self.path, e))?;
        let changed = |what: String| {
            Error::format(
                &self.path,
                crate::error::FormatError::Invalid(format!(
                    "the file changed on disk since it was opened ({what}); open it again"
                )),
            )
        };
        if meta.len() < self.end {
            return Err(changed(format!(
                "now {} bytes, its samples need {}",
                meta.len(),
                self.end
            )));
        }
        if meta.modified().ok() != self.modified {
            return Err(changed("modified".into()));
        }
        Ok(())
    }
}

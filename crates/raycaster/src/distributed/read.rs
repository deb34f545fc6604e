//! Partial reading: the voxels of one region plus its ghost layer, read by
//! seeks from the file, so a rank holds only its part of the volume.
//!
//! [`PartFile::open`] reads the header alone and finds where the samples
//! are: `.vol` linear (z fastest) and bricked files, NRRD and NIfTI files
//! with raw (uncompressed) samples, described as a
//! [`SampleLayout`] as their readers describe them. [`PartFile::read_box`]
//! reads the rows (or for a bricked file, the bricks) that meet the box,
//! merging adjacent runs into one read, and counts the bytes. The bytes are
//! then decoded by [`samples::from_reader`], the same decoder the
//! whole-file readers use (byte order, rescale to data units).
//!
//! Data that cannot be read in part (gzip-compressed NRRD or NIfTI, DICOM
//! series, other formats) is an error naming the file, unless the policy
//! is [`ReadPolicy::Whole`]: then every rank opens the whole file and keeps
//! its box.

use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};

use crate::error::{Error, Result};
use crate::format::samples::{self, Endian, Rescale, SampleLayout, Stream};
use crate::format::{FileFormat, OpenOptions, RawOptions, nifti, nrrd, vol};
use crate::sample::SampleType;
use crate::volume::{AnyVolume, AxisOrder, BrickGrid, Grid, Volume, VolumeVisitor};

/// Whether a rank reads only its part of the file or all of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ReadPolicy {
    /// Only the part and its ghost layer, by seeks (an error for data that
    /// must be decoded whole).
    #[default]
    Part,
    /// The whole file on every rank (any format; costs the whole file's
    /// memory and I/O per rank).
    Whole,
}

/// Where the samples of a file are.
#[derive(Debug)]
enum Samples {
    /// `.vol` linear: u8, z fastest, after the header.
    VolLinear,
    /// `.vol` bricked: whole bricks of B³ u8 after the header.
    VolBricked(BrickGrid),
    /// An array of samples in `layout.order` at `offset` of `data`.
    Array {
        data: PathBuf,
        offset: u64,
        layout: SampleLayout,
        rescale: Option<Rescale>,
    },
    /// Opened whole ([`ReadPolicy::Whole`]).
    Whole(AnyVolume),
}

/// A volume file opened for reading parts of it.
#[derive(Debug)]
pub struct PartFile {
    path: PathBuf,
    /// The format detected (`None` when opened whole).
    format: Option<FileFormat>,
    /// The description of a headerless file.
    raw: Option<RawOptions>,
    grid: Grid,
    samples: Samples,
    file_bytes: u64,
}

/// One region's samples read from a [`PartFile`].
#[derive(Debug)]
pub struct PartVolume {
    /// The voxels of the box, placed at their world position.
    pub volume: AnyVolume,
    /// First voxel of the box in the whole grid.
    pub offset: UVec3,
    /// Bytes read from disk for it.
    pub bytes_read: u64,
}

/// The error for a file whose samples cannot be read in part.
fn cannot_part(path: &Path, why: &str) -> Error {
    Error::Partial {
        path: path.to_path_buf(),
        reason: format!("{why} must be read whole; use --distributed-read whole"),
    }
}

impl PartFile {
    /// Reads the header of `path` (any supported format is detected as
    /// [`crate::format::detect`] does) and finds its samples; with
    /// [`ReadPolicy::Whole`] opens the whole volume.
    pub fn open(path: &Path, policy: ReadPolicy) -> Result<Self> {
        Self::open_with(path, None, policy)
    }

    /// As [`PartFile::open`], or, with `raw`, a headerless file of samples
    /// as `raw` describes them (read in part like the samples of a raw
    /// NRRD).
    pub fn open_with(path: &Path, raw: Option<&RawOptions>, policy: ReadPolicy) -> Result<Self> {
        let file_bytes = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        if policy == ReadPolicy::Whole {
            let options = OpenOptions {
                raw: raw.cloned(),
                ..OpenOptions::default()
            };
            let opened = crate::format::open_file(path, &options)?;
            return Ok(PartFile {
                path: path.to_path_buf(),
                format: None,
                raw: raw.cloned(),
                grid: *opened.volume.grid(),
                samples: Samples::Whole(opened.volume),
                file_bytes: opened.info.file_bytes.max(file_bytes),
            });
        }
        let format = match raw {
            Some(_) => FileFormat::Raw,
            None => crate::format::detect(path)?,
        };
        let (grid, samples) = match (format, raw) {
            (FileFormat::Raw, Some(raw)) => {
                if std::fs::metadata(path)
                    .map_err(|e| Error::io(path, e))?
                    .is_dir()
                {
                    return Err(Error::format(
                        path,
                        crate::error::FormatError::Invalid("is a directory, not a raw file".into()),
                    ));
                }
                let layout = SampleLayout {
                    dims: raw.dims,
                    spacing: raw.spacing,
                    sample: raw.sample,
                    endian: raw.endian,
                    order: raw.order,
                };
                let grid = Grid::new(layout.dims, layout.spacing);
                let samples = Samples::Array {
                    data: path.to_path_buf(),
                    offset: raw.offset,
                    layout,
                    rescale: None,
                };
                (grid, samples)
            }
            (format, _) => match format {
                FileFormat::Vol => {
                    let h = vol::read_header(path)?;
                    let samples = match h.layout {
                        vol::VolLayout::Linear => Samples::VolLinear,
                        vol::VolLayout::Bricked { side } => {
                            Samples::VolBricked(BrickGrid::new(h.dims, side as u32)?)
                        }
                    };
                    (h.grid(), samples)
                }
                FileFormat::Nrrd => {
                    let h = nrrd::NrrdHeader::read(path)?;
                    if h.encoding != nrrd::Encoding::Raw {
                        return Err(cannot_part(path, "gzip-compressed data"));
                    }
                    h.layout.validate(path)?;
                    let bytes = h.layout.byte_len(path)?;
                    let offset = match h.data_offset {
                        Some(o) => o,
                        None => {
                            let len = std::fs::metadata(&h.data_file)
                                .map_err(|e| Error::io(&h.data_file, e))?
                                .len();
                            len.saturating_sub(bytes.saturating_mul(h.extra_volumes))
                        }
                    };
                    let grid = Grid::new(h.layout.dims, h.layout.spacing);
                    let samples = Samples::Array {
                        data: h.data_file,
                        offset,
                        layout: h.layout,
                        rescale: None,
                    };
                    (grid, samples)
                }
                FileFormat::Nifti => match nifti::locate_samples(path)? {
                    Some(at) => (
                        Grid::new(at.layout.dims, at.layout.spacing),
                        Samples::Array {
                            data: at.data,
                            offset: at.offset,
                            layout: at.layout,
                            rescale: at.rescale,
                        },
                    ),
                    None => return Err(cannot_part(path, "gzip-compressed data")),
                },
                other => {
                    return Err(cannot_part(path, &format!("a {} file", other.name())));
                }
            },
        };
        if let Samples::Array {
            data,
            offset,
            layout,
            ..
        } = &samples
        {
            // The file must hold the samples the header promises.
            let need = offset.saturating_add(layout.byte_len(data)?);
            let len = std::fs::metadata(data)
                .map_err(|e| Error::io(data, e))?
                .len();
            if len < need {
                return Err(Error::format(
                    data,
                    crate::error::FormatError::WrongLength {
                        expected: need,
                        found: len,
                        detail: format!("{offset} bytes of header + samples"),
                    },
                ));
            }
        }
        Ok(PartFile {
            path: path.to_path_buf(),
            format: Some(format),
            raw: raw.cloned(),
            grid,
            samples,
            file_bytes,
        })
    }

    /// The key and grid shape of this file's macrocell cache for cells of
    /// `cell` voxels, the cache [`Scene::open`] reads and writes, or `None`
    /// when the file gets no cache here: opened whole, samples in another
    /// file (a detached NRRD header), more than one volume in the file, a
    /// rescale (whose result type depends on the data), or a fingerprint
    /// that cannot be read.
    ///
    /// [`Scene::open`]: crate::scene::Scene::open
    pub fn cache_key(
        &self,
        cell: u32,
    ) -> Option<(
        crate::accel::cache::CacheKey,
        crate::accel::cache::GridShape,
    )> {
        let format = self.format?;
        let sample_type = match &self.samples {
            Samples::VolLinear | Samples::VolBricked(_) => SampleType::U8,
            Samples::Array {
                data,
                offset,
                layout,
                rescale: None,
            } if data == &self.path
                && layout
                    .byte_len(data)
                    .is_ok_and(|n| offset.saturating_add(n) == self.file_bytes) =>
            {
                layout.sample
            }
            _ => return None,
        };
        // The description Scene::open keys a cache with.
        let description = match &self.raw {
            Some(raw) => format!("{} {raw:?}", format.name()),
            None => format.name().to_string(),
        };
        let key = crate::accel::cache::CacheKey::of(&self.path, &description).ok()?;
        let shape = crate::accel::cache::GridShape {
            sample_type,
            dims: self.grid.dims,
            cell,
        };
        Some((key, shape))
    }

    /// The whole volume's grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// The file's length in bytes (for a whole read: what the reader read).
    pub fn file_bytes(&self) -> u64 {
        self.file_bytes
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads the voxels `lo..=hi` (voxel coordinates of the whole grid) into
    /// a volume in RAM placed at their world position.
    pub fn read_box(&self, lo: UVec3, hi: UVec3) -> Result<PartVolume> {
        let d = self.grid.dims;
        if lo.cmpgt(hi).any() || hi.cmpge(d).any() {
            return Err(Error::option(
                "region",
                format!(
                    "voxels {lo}..={hi} are not inside a {}x{}x{} grid",
                    d.x, d.y, d.z
                ),
            ));
        }
        let n = hi - lo + UVec3::ONE;
        let origin = self.grid.origin + lo.as_vec3() * self.grid.spacing;
        let sub = Grid {
            dims: n,
            spacing: self.grid.spacing,
            origin,
        };
        let path = &self.path;
        let (volume, bytes_read) = match &self.samples {
            Samples::Whole(volume) => (extract(volume, lo, sub)?, self.file_bytes),
            Samples::VolLinear => {
                let mut runs = Runs::new(path)?;
                for x in lo.x..=hi.x {
                    for y in lo.y..=hi.y {
                        let row = (x as u64 * d.y as u64 + y as u64) * d.z as u64;
                        runs.push(vol::HEADER_LEN as u64 + row + lo.z as u64, n.z as u64);
                    }
                }
                let bytes = runs.read()?;
                let layout = u8_layout(n, self.grid.spacing, AxisOrder::ZFast);
                (decode(path, &bytes, &layout, None)?, bytes.len() as u64)
            }
            Samples::VolBricked(bricks) => read_bricks(path, bricks, lo, hi, self.grid.spacing)?,
            Samples::Array {
                data,
                offset,
                layout,
                rescale,
            } => {
                let size = layout.sample.size() as u64;
                let mut runs = Runs::new(data)?;
                match layout.order {
                    AxisOrder::XFast => {
                        for z in lo.z..=hi.z {
                            for y in lo.y..=hi.y {
                                let row = (z as u64 * d.y as u64 + y as u64) * d.x as u64;
                                runs.push(offset + (row + lo.x as u64) * size, n.x as u64 * size);
                            }
                        }
                    }
                    AxisOrder::ZFast => {
                        for x in lo.x..=hi.x {
                            for y in lo.y..=hi.y {
                                let row = (x as u64 * d.y as u64 + y as u64) * d.z as u64;
                                runs.push(offset + (row + lo.z as u64) * size, n.z as u64 * size);
                            }
                        }
                    }
                }
                let bytes = runs.read()?;
                let part = SampleLayout { dims: n, ..*layout };
                (decode(data, &bytes, &part, *rescale)?, bytes.len() as u64)
            }
        };
        Ok(PartVolume {
            volume: volume.with_origin(origin),
            offset: lo,
            bytes_read,
        })
    }
}

fn u8_layout(dims: UVec3, spacing: Vec3, order: AxisOrder) -> SampleLayout {
    SampleLayout {
        dims,
        spacing,
        sample: SampleType::U8,
        endian: Endian::Little,
        order,
    }
}

/// Decodes sample bytes as the whole-file readers do.
fn decode(
    path: &Path,
    bytes: &[u8],
    layout: &SampleLayout,
    rescale: Option<Rescale>,
) -> Result<AnyVolume> {
    samples::from_reader(path, bytes, layout, rescale, Stream::default())
}

/// Byte ranges of a file to read, adjacent ones merged.
struct Runs<'a> {
    path: &'a Path,
    file: std::fs::File,
    runs: Vec<(u64, u64)>,
    total: u64,
}

impl<'a> Runs<'a> {
    fn new(path: &'a Path) -> Result<Self> {
        Ok(Runs {
            path,
            file: std::fs::File::open(path).map_err(|e| Error::io(path, e))?,
            runs: Vec::new(),
            total: 0,
        })
    }

    fn push(&mut self, offset: u64, len: u64) {
        self.total += len;
        if let Some(last) = self.runs.last_mut()
            && last.0 + last.1 == offset
        {
            last.1 += len;
            return;
        }
        self.runs.push((offset, len));
    }

    /// Reads every run, in order, into one buffer.
    fn read(self) -> Result<Vec<u8>> {
        let total = usize::try_from(self.total).map_err(|_| Error::TooLarge {
            path: self.path.to_path_buf(),
            what: "part of the volume".into(),
        })?;
        let mut buf = vec![0u8; total];
        let mut at = 0usize;
        for (offset, len) in self.runs {
            let len = len as usize;
            self.file
                .read_exact_at(&mut buf[at..at + len], offset)
                .map_err(|e| Error::io(self.path, e))?;
            at += len;
        }
        Ok(buf)
    }
}

/// Reads the bricks of a bricked `.vol` file that hold voxels of
/// `lo..=hi` (each voxel from the brick [`BrickGrid::split`] assigns it
/// to) and assembles the box, z fastest.
fn read_bricks(
    path: &Path,
    bricks: &BrickGrid,
    lo: UVec3,
    hi: UVec3,
    spacing: Vec3,
) -> Result<(AnyVolume, u64)> {
    let b = bricks.side;
    let split = |v: UVec3| {
        UVec3::new(
            bricks.split(v.x, bricks.count.x).0,
            bricks.split(v.y, bricks.count.y).0,
            bricks.split(v.z, bricks.count.z).0,
        )
    };
    let (b0, b1) = (split(lo), split(hi));
    let n = hi - lo + UVec3::ONE;
    let mut out = vec![0u8; n.as_u64vec3().element_product() as usize];
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let brick_len = bricks.brick_len() as usize;
    let mut brick = vec![0u8; brick_len];
    let mut read = 0u64;
    for i in b0.x..=b1.x {
        for j in b0.y..=b1.y {
            for k in b0.z..=b1.z {
                let index = (i as u64 * bricks.count.y as u64 + j as u64) * bricks.count.z as u64
                    + k as u64;
                file.read_exact_at(
                    &mut brick,
                    vol::HEADER_LEN as u64 + index * brick_len as u64,
                )
                .map_err(|e| Error::io(path, e))?;
                read += brick_len as u64;
                let base = UVec3::new(i, j, k) * (b - 1);
                // The voxels this brick is assigned, within the box.
                let own = |c: u32, axis: usize| {
                    let count = bricks.count[axis];
                    let first = base[axis];
                    let last = if c + 1 == count {
                        first + b - 1
                    } else {
                        first + b - 2
                    };
                    (first.max(lo[axis]), last.min(hi[axis]))
                };
                let (x0, x1) = own(i, 0);
                let (y0, y1) = own(j, 1);
                let (z0, z1) = own(k, 2);
                if x0 > x1 || y0 > y1 || z0 > z1 {
                    continue;
                }
                let run = (z1 - z0 + 1) as usize;
                for x in x0..=x1 {
                    for y in y0..=y1 {
                        let src = (((x - base.x) * b + (y - base.y)) * b + (z0 - base.z)) as usize;
                        let dst = (((x - lo.x) as u64 * n.y as u64 + (y - lo.y) as u64)
                            * n.z as u64
                            + (z0 - lo.z) as u64) as usize;
                        out[dst..dst + run].copy_from_slice(&brick[src..src + run]);
                    }
                }
            }
        }
    }
    let layout = u8_layout(n, spacing, AxisOrder::ZFast);
    Ok((decode(path, &out, &layout, None)?, read))
}

/// The voxels `lo..lo + sub.dims` of `volume` copied into a volume in RAM
/// (z fastest), of the same sample type.
pub fn extract(volume: &AnyVolume, lo: UVec3, sub: Grid) -> Result<AnyVolume> {
    struct Extract {
        lo: UVec3,
        sub: Grid,
    }
    impl VolumeVisitor for Extract {
        type Output = Result<AnyVolume>;
        fn visit<V: Volume>(self, v: &V) -> Result<AnyVolume> {
            let n = self.sub.dims;
            let mut out: Vec<V::Sample> =
                Vec::with_capacity(n.as_u64vec3().element_product() as usize);
            for x in 0..n.x {
                for y in 0..n.y {
                    for z in 0..n.z {
                        out.push(v.voxel(self.lo + UVec3::new(x, y, z)));
                    }
                }
            }
            samples::from_samples(self.sub, out, AxisOrder::ZFast, None)
        }
    }
    volume.visit(Extract { lo, sub })
}

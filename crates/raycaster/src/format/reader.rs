//! The one interface every volume file reader implements ([`Reader`]), the
//! table of the readers that detection chooses from ([`READERS`]), and
//! detection itself.
//!
//! Detection shows every reader the same [`Probe`] of the file (name, first
//! bytes, length, whether it is a directory); each answers with how strongly
//! it [`Claim`]s the file. The strongest claim wins; between equal claims,
//! the reader earlier in [`READERS`] does. A file no reader claims is an
//! error naming it. Headerless (raw) files carry nothing to detect: they are
//! read when [`OpenOptions::raw`] describes them.

use std::path::Path;

use super::{FileFormat, OpenOptions, Opened, davis, dicom, nifti, nrrd, raw, vol, vseq};
use crate::error::{Error, FormatError, Result};

/// How many first bytes of a file a [`Probe`] holds: a whole NIfTI-1 header
/// and its extension flag, and the DICOM preamble with its `DICM` marker.
pub const PROBE_LEN: usize = 352;

/// What detection shows a reader of a file.
#[derive(Debug, Clone, Copy)]
pub struct Probe<'a> {
    /// The path as given.
    pub path: &'a Path,
    /// The file name, lower-case (empty when the path has none).
    pub name: &'a str,
    /// The first [`PROBE_LEN`] bytes (fewer for a shorter file, none for a
    /// directory).
    pub head: &'a [u8],
    /// The file's length in bytes (0 for a directory).
    pub len: u64,
    /// Whether the path is a directory.
    pub is_dir: bool,
}

impl Probe<'_> {
    /// The name's extension after its last dot, lower-case; empty without
    /// a dot.
    pub fn extension(&self) -> &str {
        self.name.rsplit_once('.').map_or("", |(_, e)| e)
    }
}

/// How strongly a reader claims a file, weakest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Claim {
    /// The name is one this reader takes when no other reader claims the
    /// file, so that its error says what is wrong with the header (a
    /// `.vol` whose header is broken).
    Fallback,
    /// The name is this format's.
    Name,
    /// The bytes are this format's (a magic number, a header whose implied
    /// length matches the file), or a name that stands in for bytes that
    /// cannot be looked at before decoding.
    Content,
}

/// A reader of one file format (paired with its [`FileFormat`] in
/// [`READERS`]).
pub trait Reader: Sync {
    /// How strongly this reader claims the file `probe` shows; `None` when
    /// it is not this reader's.
    fn sniff(&self, probe: &Probe) -> Option<Claim>;

    /// Opens `path` as this format. Readers that decode for a while report
    /// to `options.progress`; those that map files honour `options.mode`.
    fn open(&self, path: &Path, options: &OpenOptions) -> Result<Opened>;
}

/// The readers detection chooses from, in the order that settles equal
/// claims: NRRD's and NIfTI's magic numbers are checked before DICOM's
/// preamble, and the `.vol` format of this project before the UC Davis one
/// that shares its extension.
pub static READERS: &[(FileFormat, &dyn Reader)] = &[
    (FileFormat::Nrrd, &nrrd::NrrdReader),
    (FileFormat::Nifti, &nifti::NiftiReader),
    (FileFormat::Dicom, &dicom::DicomReader),
    (FileFormat::Vol, &vol::VolReader),
    (FileFormat::DavisVol, &davis::DavisReader),
    (FileFormat::Vseq, &vseq::VseqReader),
];

/// The reader for `path`: the raw reader when `options.raw` describes the
/// file, else the one detection picks.
pub fn reader_for(path: &Path, options: &OpenOptions) -> Result<&'static dyn Reader> {
    if options.raw.is_some() {
        return Ok(&raw::RawReader);
    }
    detect_reader(path).map(|(_, reader)| reader)
}

/// Guesses the format of `path` from its name and first bytes.
pub fn detect(path: &Path) -> Result<FileFormat> {
    detect_claim(path).map(|(format, _)| format)
}

/// [`detect`] and how strongly the format's reader claims the file: a
/// [`Claim::Fallback`] is a file with no extension and no header any reader
/// knows (a `LICENSE`, a `README`), taken as a `.vol` only so that opening
/// it names what is wrong.
pub fn detect_claim(path: &Path) -> Result<(FileFormat, Claim)> {
    detect_strongest(path).map(|(claim, (format, _))| (format, claim))
}

/// The format and reader of [`detect_strongest`].
fn detect_reader(path: &Path) -> Result<(FileFormat, &'static dyn Reader)> {
    detect_strongest(path).map(|(_, found)| found)
}

/// The reader whose claim on `path` is strongest (see the module
/// documentation), with its claim.
fn detect_strongest(path: &Path) -> Result<(Claim, (FileFormat, &'static dyn Reader))> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let is_dir = meta.is_dir();
    let head = if is_dir {
        Vec::new()
    } else {
        super::read_head(path, PROBE_LEN)?
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let probe = Probe {
        path,
        name: &name,
        head: &head,
        len: if is_dir { 0 } else { meta.len() },
        is_dir,
    };
    strongest(&probe).ok_or_else(|| unrecognised(path, probe.extension()))
}

/// The reader with the strongest claim on `probe` (the earliest in
/// [`READERS`] among equals), with its claim.
fn strongest(probe: &Probe) -> Option<(Claim, (FileFormat, &'static dyn Reader))> {
    let mut best: Option<(Claim, (FileFormat, &'static dyn Reader))> = None;
    for &(format, reader) in READERS {
        if let Some(claim) = reader.sniff(probe)
            && best.is_none_or(|(strongest, _)| claim > strongest)
        {
            best = Some((claim, (format, reader)));
        }
    }
    best
}

/// The error for a file no reader claims: headerless extensions get the
/// options that describe them, others the list of what is read.
fn unrecognised(path: &Path, ext: &str) -> Error {
    let why = match ext {
        "raw" | "bin" | "dat" | "img" => {
            format!("a .{ext} file has no header: describe it with --raw-dims and --raw-type")
        }
        "csv" | "xyz" => {
            format!("a .{ext} file is a list of points: render it with --mode metaballs")
        }
        other => format!(
            "extension .{other}; supported: .vol, .nrrd, .nhdr, .nii, .nii.gz, .dcm or a DICOM directory, .vseq, raw with --raw-dims/--raw-type"
        ),
    };
    Error::format(path, FormatError::Unrecognised(why))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::davis::DavisHeader;
    use crate::format::vol::{VolHeader, VolLayout};
    use glam::{UVec3, Vec3};

    /// The format detection picks for a file `name` starting with `head`
    /// and `len` bytes long (`None`: unrecognised).
    fn pick(name: &str, head: &[u8], len: u64) -> Option<FileFormat> {
        pick_probe(name, head, len, false)
    }

    fn pick_probe(name: &str, head: &[u8], len: u64, is_dir: bool) -> Option<FileFormat> {
        let probe = Probe {
            path: Path::new(name),
            name,
            head,
            len,
            is_dir,
        };
        strongest(&probe).map(|(_, (format, _))| format)
    }

    fn nifti_head() -> Vec<u8> {
        let mut h = vec![0u8; PROBE_LEN];
        h[..4].copy_from_slice(&348i32.to_le_bytes());
        h[344..348].copy_from_slice(b"n+1\0");
        h
    }

    fn dicom_head() -> Vec<u8> {
        let mut h = vec![0u8; PROBE_LEN];
        h[128..132].copy_from_slice(b"DICM");
        h
    }

    /// An unrecognised file's error says what to do for the extensions
    /// that have an answer, and lists the formats otherwise.
    #[test]
    fn unrecognised_files_are_told_what_to_do() {
        let says = |name: &str, needle: &str| {
            let ext = name.rsplit_once('.').map_or("", |(_, e)| e);
            let e = unrecognised(Path::new(name), ext).to_string();
            assert!(e.contains(name) && e.contains(needle), "{name}: {e}");
        };
        says("points.csv", "--mode metaballs");
        says("cloud.xyz", "--mode metaballs");
        says("scan.raw", "--raw-dims");
        says("notes.txt", "supported: .vol");
    }

    #[test]
    fn content_beats_names_and_the_table_order_settles_ties() {
        use FileFormat::*;
        let nrrd = b"NRRD0004\ntype: uchar\n".to_vec();
        let (nii, dcm) = (nifti_head(), dicom_head());
        let none = [0u8; 8];
        let cases: &[(&str, &[u8], Option<FileFormat>)] = &[
            ("a.nrrd", &nrrd, Some(Nrrd)),
            ("a.nhdr", &none, Some(Nrrd)),
            ("a.dat", &nrrd, Some(Nrrd)),
            ("a.nrrd", &nii, Some(Nifti)),
            ("a.nii", &none, Some(Nifti)),
            ("a.nii", &dcm, Some(Dicom)),
            ("a.nii.gz", &dcm, Some(Nifti)),
            ("a.hdr", &none, Some(Nifti)),
            ("a.nii.gz", &nrrd, Some(Nrrd)),
            ("a.dcm", &none, Some(Dicom)),
            ("a.ima", &nrrd, Some(Nrrd)),
            ("a.img", &dcm, Some(Dicom)),
            ("a.img", &none, None),
            ("a.raw", &none, None),
            ("a.xyz", &none, None),
            ("a.gz", &none, None),
        ];
        for &(name, head, want) in cases {
            assert_eq!(pick(name, head, 1000), want, "{name}");
        }
    }

    #[test]
    fn the_two_vol_formats_are_told_apart_by_length() {
        use FileFormat::*;
        let vol = VolHeader {
            dims: UVec3::new(4, 5, 6),
            spacing: Vec3::ONE,
            layout: VolLayout::Linear,
        }
        .to_bytes();
        let davis = DavisHeader {
            dims: UVec3::new(4, 5, 6),
            border: 0,
            spacing: Vec3::ONE,
        }
        .to_bytes();
        assert_eq!(pick("a.vol", &vol, 26 + 120), Some(Vol));
        assert_eq!(pick("noext", &vol, 26 + 120), Some(Vol));
        // A .vol header with the wrong length: its own reader says so.
        assert_eq!(pick("a.vol", &vol, 99), Some(Vol));
        assert_eq!(pick("a.vol", &davis, 28 + 120), Some(DavisVol));
        // A truncated UC Davis file (its bytes are no .vol header).
        assert_eq!(pick("a.vol", &davis, 100), Some(DavisVol));
        // Garbage: the .vol reader reports the header.
        assert_eq!(pick("a.vol", &[7u8; 30], 30), Some(Vol));
        // The content of a .vol under a headerless extension is not looked at.
        assert_eq!(pick("a.raw", &vol, 26 + 120), None);
    }

    #[test]
    fn directories_are_dicom_series_whatever_their_name() {
        for name in ["series", "a.nii.gz", "a.nrrd", "a.vol"] {
            let format = pick_probe(name, &[], 0, true);
            assert_eq!(format, Some(FileFormat::Dicom), "{name}");
        }
    }

    /// Without a feature, the file is still detected and opening it names
    /// the file and the feature.
    #[cfg(not(all(feature = "gzip", feature = "dicom")))]
    #[test]
    fn missing_features_are_named() {
        let dir = std::env::temp_dir().join(format!("rc-features-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let options = OpenOptions::default();
        if !cfg!(feature = "dicom") {
            let series = dir.join("series");
            std::fs::create_dir_all(&series).unwrap();
            assert_eq!(detect(&series).unwrap(), FileFormat::Dicom);
            let e = crate::format::open_file(&series, &options).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "{}: DICOM support is not compiled in (enable the `dicom` feature of raycaster)",
                    series.display()
                )
            );
        }
        if !cfg!(feature = "gzip") {
            let nii = dir.join("x.nii.gz");
            std::fs::write(&nii, [0x1f, 0x8b, 8, 0]).unwrap();
            assert_eq!(detect(&nii).unwrap(), FileFormat::Nifti);
            let e = crate::format::open_file(&nii, &options).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "{}: gzip support is not compiled in (enable the `gzip` feature of raycaster)",
                    nii.display()
                )
            );
            let volume = crate::volume::AnyVolume::from_fn(
                crate::volume::Grid::new(UVec3::ONE, Vec3::ONE),
                |_| 1u8,
            );
            let out = dir.join("out.nii.gz");
            let options = crate::format::save::SaveOptions::default();
            let e = crate::format::save::save(&out, &volume, &options).unwrap_err();
            assert!(e.to_string().contains("enable the `gzip` feature"), "{e}");
            assert!(!out.exists());
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

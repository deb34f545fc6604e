//! Unit tests of the DICOM reader: the geometry and pixel helpers, and
//! small synthetic series written to disk with DICOM-rs in every native
//! transfer syntax.

use std::path::{Path, PathBuf};

use dicom_core::value::PrimitiveValue;
use dicom_dictionary_std::tags;
use glam::{UVec3, Vec3};

use super::geometry::{
    SAME_POSITION_MM, SPACING_TOLERANCE, SliceSpacing, drop_duplicates, order_along, round_noise,
    slice_normal,
};
use super::header::{native_endian_of, unsupported_syntax};
use super::looks_like;
use super::pixels::{Allocated, PixelFormat};
use crate::format::Opened;
use crate::format::samples::{Endian, Rescale};
use crate::sample::SampleType;
use crate::volume::AnyVolume;

/// Opens a series (or the series of a file) without progress.
fn open(path: &Path) -> crate::Result<Opened> {
    super::series::open(path, None, None)
}

/// The unit normal of `o`, which must define a plane.
fn normal(o: &[f64; 6]) -> [f64; 3] {
    slice_normal(o).expect("a plane")
}

#[test]
fn normal_is_row_cross_column() {
    assert_eq!(normal(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
    // Sagittal: rows along y, columns along -z: normal along -x.
    assert_eq!(normal(&[0.0, 1.0, 0.0, 0.0, 0.0, -1.0]), [-1.0, 0.0, 0.0]);
    // Cosines rounded to six decimals: still a unit normal.
    let n = normal(&[0.866025, 0.5, 0.0, -0.5, 0.866025, 0.0]);
    assert!((n[2] - 1.0).abs() < 1e-15, "{n:?}");
    // Parallel or missing directions define no plane.
    assert_eq!(slice_normal(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]), None);
    assert_eq!(slice_normal(&[0.0; 6]), None);
    assert_eq!(slice_normal(&[f64::NAN, 0.0, 0.0, 0.0, 1.0, 0.0]), None);
}

#[test]
fn spacing_noise_is_rounded_away() {
    assert_eq!(round_noise(3.000_000_2), 3.0);
    assert_eq!(round_noise(2.999_999_8), 3.0);
    assert_eq!(round_noise(0.703_125), 0.703_125);
    assert_eq!(round_noise(1.25), 1.25);
    // Real spacings with more digits move by far less than a millionth.
    let r = round_noise(0.488_281_25);
    assert!((r - 0.488_281_25).abs() < 1e-6 * 0.49, "{r}");
    // Far from any 6-digit value: unchanged.
    assert_eq!(round_noise(3.000_004), 3.000_004);
    assert_eq!(round_noise(1234.5678), 1234.5678);
    assert_eq!(round_noise(0.0), 0.0);
}

#[test]
fn slices_sort_by_projection_not_input_order() {
    let n = normal(&[0.0, 1.0, 0.0, 0.0, 0.0, -1.0]); // -x
    let positions = [
        [3.0, 5.0, 1.0],
        [-3.0, 0.0, 0.0],
        [0.0, 9.0, 9.0],
        [6.0, 0.0, 0.0],
    ];
    let order: Vec<usize> = order_along(&positions, n).iter().map(|o| o.0).collect();
    // Projections: -3, 3, 0, -6 → ascending: 3, 0, 2, 1.
    assert_eq!(order, [3, 0, 2, 1]);
}

#[test]
fn oblique_normal_projection() {
    let c = std::f64::consts::FRAC_1_SQRT_2;
    let o = [1.0, 0.0, 0.0, 0.0, c, -c];
    let n = normal(&o);
    let positions: Vec<[f64; 3]> = [2.0, 0.0, 1.0]
        .iter()
        .map(|&t| [5.0, t * n[1], t * n[2]])
        .collect();
    let sorted = order_along(&positions, n);
    assert_eq!(sorted.iter().map(|o| o.0).collect::<Vec<_>>(), [1, 2, 0]);
    assert!((sorted[2].1 - 2.0).abs() < 1e-12);
}

#[test]
fn duplicates_keep_first_in_input_order() {
    let positions = [
        [0.0, 0.0, 3.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 3.004],
        [0.0, 0.0, 6.0],
    ];
    let sorted = order_along(&positions, [0.0, 0.0, 1.0]);
    let (kept, dropped) = drop_duplicates(&sorted, SAME_POSITION_MM);
    assert_eq!(dropped, 1);
    assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), [1, 0, 3]);
}

#[test]
fn spacing_is_mean_gap_and_detects_variation() {
    let s = SliceSpacing::of(&[0.0, 3.0, 6.0, 9.0]).unwrap();
    assert_eq!(s.mean, 3.0);
    assert!(!s.varies(SPACING_TOLERANCE));
    let s = SliceSpacing::of(&[0.0, 3.0, 6.01, 9.0]).unwrap();
    assert!(!s.varies(SPACING_TOLERANCE), "{s:?}");
    let s = SliceSpacing::of(&[0.0, 3.0, 9.0, 12.0]).unwrap();
    assert_eq!(s.mean, 4.0);
    assert_eq!((s.min, s.max), (3.0, 6.0));
    assert!(s.varies(SPACING_TOLERANCE));
    assert!(SliceSpacing::of(&[1.0]).is_none());
    assert!(SliceSpacing::of(&[]).is_none());
}

#[test]
fn bits_stored_masks_or_sign_extends() {
    let mut f = PixelFormat {
        rows: 1,
        columns: 1,
        allocated: Allocated::Sixteen,
        bits_stored: 12,
        signed: false,
    };
    assert_eq!(f.fix(0xf123), 0x0123);
    f.signed = true;
    assert_eq!(f.fix(0x0800) as i16, -2048);
    assert_eq!(f.fix(0xf7ff) as i16, 2047);
    f.bits_stored = 16;
    assert_eq!(f.fix(0xf123), 0xf123);
    let g = PixelFormat {
        allocated: Allocated::Eight,
        bits_stored: 7,
        signed: true,
        ..f
    };
    assert_eq!(g.fix(0x40) as u8 as i8, -64);
}

#[test]
fn transfer_syntaxes() {
    assert_eq!(native_endian_of("1.2.840.10008.1.2"), Some(Endian::Little));
    assert_eq!(native_endian_of("1.2.840.10008.1.2.2"), Some(Endian::Big));
    assert_eq!(native_endian_of("1.2.840.10008.1.2.4.70"), None);
    let e = unsupported_syntax("1.2.840.10008.1.2.4.70").to_string();
    assert!(e.contains("JPEG Lossless SV1"), "{e}");
}

#[test]
fn dicom_magic() {
    let mut head = vec![0u8; 132];
    assert!(!looks_like(&head));
    head[128..132].copy_from_slice(b"DICM");
    assert!(looks_like(&head));
    assert!(looks_like(&[2, 0, 0, 0, b'U', b'L', 4, 0]));
}

// ------------------------------------------- synthetic series on disk

use dicom_core::{DataElement, VR};
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};

const EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";

/// A temporary directory, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Self {
        use std::sync::atomic::{AtomicU32, Ordering};
        static N: AtomicU32 = AtomicU32::new(0);
        let p = std::env::temp_dir().join(format!(
            "raycaster-dicom-unit-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// One synthetic slice: 4 columns x 3 rows.
#[derive(Clone)]
struct Synth {
    ts: &'static str,
    series: &'static str,
    instance: i32,
    /// Position along the normal of the oblique orientation below.
    along: f64,
    bits: u16,
    stored: u16,
    signed: bool,
    rescale: Option<(&'static str, &'static str)>,
    /// 16-bit data written as OB bytes in the transfer syntax's order.
    as_ob: bool,
    /// The words (8-bit data: low bytes), rows of 4.
    words: Vec<u16>,
    /// Image Orientation (Patient), written with `{}`.
    orientation: [f64; 6],
    /// Rows and Columns written as UL with these values instead of US 3, 4.
    dims_ul: Option<(u32, u32)>,
    /// A sequence holding one item with a Red Palette LUT Data (OW) element
    /// of these bytes, before the pixel data.
    nested: Option<Vec<u8>>,
}

/// Row direction, column direction; normal = row x col.
const ORIENT: [f64; 6] = [0.6, 0.8, 0.0, 0.0, 0.0, -1.0];

impl Synth {
    fn new(ts: &'static str, instance: i32, along: f64) -> Self {
        Synth {
            ts,
            series: "1.2.3.4",
            instance,
            along,
            bits: 16,
            stored: 16,
            signed: false,
            rescale: None,
            as_ob: false,
            words: (0..12).map(|i| (instance as u16) * 100 + i).collect(),
            orientation: ORIENT,
            dims_ul: None,
            nested: None,
        }
    }

    fn write(&self, path: &Path) {
        let n = normal(&self.orientation);
        let p: Vec<String> = (0..3)
            .map(|i| format!("{}", 10.0 + n[i] * self.along))
            .collect();
        let s = |t, vr, v: &str| DataElement::new(t, vr, PrimitiveValue::from(v));
        let us = |t, v: u16| DataElement::new(t, VR::US, PrimitiveValue::from(v));
        let sop = format!("{}.{}", self.series, self.instance);
        let orientation: Vec<String> = self.orientation.iter().map(|c| c.to_string()).collect();
        let mut elements = vec![
            s(tags::SOP_CLASS_UID, VR::UI, "1.2.840.10008.5.1.4.1.1.4"),
            s(tags::SOP_INSTANCE_UID, VR::UI, &sop),
            s(tags::SLICE_THICKNESS, VR::DS, "5"),
            s(tags::SERIES_INSTANCE_UID, VR::UI, self.series),
            s(tags::INSTANCE_NUMBER, VR::IS, &self.instance.to_string()),
            s(tags::IMAGE_POSITION_PATIENT, VR::DS, &p.join("\\")),
            s(
                tags::IMAGE_ORIENTATION_PATIENT,
                VR::DS,
                &orientation.join("\\"),
            ),
            us(tags::SAMPLES_PER_PIXEL, 1),
            s(tags::PHOTOMETRIC_INTERPRETATION, VR::CS, "MONOCHROME2"),
            s(tags::PIXEL_SPACING, VR::DS, "0.5\\0.75"),
            us(tags::BITS_ALLOCATED, self.bits),
            us(tags::BITS_STORED, self.stored),
            us(tags::HIGH_BIT, self.stored - 1),
            us(tags::PIXEL_REPRESENTATION, self.signed as u16),
        ];
        match self.dims_ul {
            None => elements.extend([us(tags::ROWS, 3), us(tags::COLUMNS, 4)]),
            Some((rows, columns)) => elements.extend([
                DataElement::new(tags::ROWS, VR::UL, PrimitiveValue::from(rows)),
                DataElement::new(tags::COLUMNS, VR::UL, PrimitiveValue::from(columns)),
            ]),
        }
        if let Some(bytes) = &self.nested {
            let item = InMemDicomObject::from_element_iter([DataElement::new(
                tags::RED_PALETTE_COLOR_LOOKUP_TABLE_DATA,
                VR::OW,
                PrimitiveValue::from(bytes.clone()),
            )]);
            elements.push(DataElement::new(
                tags::REFERENCED_IMAGE_SEQUENCE,
                VR::SQ,
                dicom_core::value::DataSetSequence::from(vec![item]),
            ));
        }
        if let Some((slope, intercept)) = self.rescale {
            elements.push(s(tags::RESCALE_INTERCEPT, VR::DS, intercept));
            elements.push(s(tags::RESCALE_SLOPE, VR::DS, slope));
        }
        let big = self.ts == EXPLICIT_BE;
        let pixels = if self.bits == 8 {
            let b: Vec<u8> = self.words.iter().map(|&w| w as u8).collect();
            DataElement::new(tags::PIXEL_DATA, VR::OB, PrimitiveValue::from(b))
        } else if self.as_ob {
            let b: Vec<u8> = self
                .words
                .iter()
                .flat_map(|&w| {
                    if big {
                        w.to_be_bytes()
                    } else {
                        w.to_le_bytes()
                    }
                })
                .collect();
            DataElement::new(tags::PIXEL_DATA, VR::OB, PrimitiveValue::from(b))
        } else {
            DataElement::new(
                tags::PIXEL_DATA,
                VR::OW,
                PrimitiveValue::U16(self.words.clone().into()),
            )
        };
        elements.push(pixels);
        InMemDicomObject::from_element_iter(elements)
            .with_meta(FileMetaTableBuilder::new().transfer_syntax(self.ts))
            .unwrap()
            .write_to_file(path)
            .unwrap();
    }
}

/// Writes `slices` as `s<index>.dcm` (names in the order given).
fn write_all(dir: &TempDir, slices: &[Synth]) {
    for (i, s) in slices.iter().enumerate() {
        s.write(&dir.0.join(format!("s{i}.dcm")));
    }
}

fn samples_f32(v: &AnyVolume) -> Vec<f32> {
    v.all_values()
}

/// Files written in reverse position order under increasing names, with
/// bits above Bits Stored set: every native transfer syntax (and OB
/// instead of OW) reads the same, in position order, masked.
#[test]
fn native_transfer_syntaxes_read_alike() {
    let mut reference: Option<Vec<f32>> = None;
    for (ts, as_ob, name) in [
        (EXPLICIT_LE, false, "Explicit VR Little Endian"),
        (IMPLICIT_LE, false, "Implicit VR Little Endian"),
        (EXPLICIT_BE, false, "Explicit VR Big Endian"),
        (EXPLICIT_BE, true, "Explicit VR Big Endian"),
        (EXPLICIT_LE, true, "Explicit VR Little Endian"),
    ] {
        let dir = TempDir::new();
        let slices: Vec<Synth> = (0..5)
            .map(|k| {
                let mut s = Synth::new(ts, k + 1, 2.5 * (4 - k) as f64 - 7.0);
                s.stored = 12;
                s.as_ob = as_ob;
                s.words.iter_mut().for_each(|w| *w |= 0xa000);
                s
            })
            .collect();
        write_all(&dir, &slices);
        let o = open(&dir.0).unwrap();
        assert_eq!(o.info.encoding, name);
        assert_eq!(o.info.dims, UVec3::new(4, 3, 5));
        assert!(
            (o.info.spacing - Vec3::new(0.75, 0.5, 2.5))
                .abs()
                .max_element()
                < 1e-5
        );
        assert_eq!(o.info.stored_type, SampleType::U16);
        assert!(o.info.notes.is_empty(), "{:?}", o.info.notes);
        let v = samples_f32(&o.volume);
        // z = 0 is the lowest position: instance 5; x-fast rows of 4.
        for z in 0..5 {
            for i in 0..12 {
                let want = ((5 - z) * 100 + i) as f32;
                assert_eq!(v[z * 12 + i], want, "{ts} ob={as_ob} z={z} i={i}");
            }
        }
        match &reference {
            None => reference = Some(v),
            Some(r) => assert_eq!(r, &v),
        }
    }
}

#[test]
fn eight_bit_signed_with_rescale_and_per_slice_rescale() {
    let dir = TempDir::new();
    let slices: Vec<Synth> = (0..3)
        .map(|k| {
            let mut s = Synth::new(EXPLICIT_LE, k + 1, 3.0 * k as f64);
            s.bits = 8;
            s.stored = 8;
            s.signed = true;
            s.words = (0..12).map(|i| (i as i8 - 6) as u8 as u16).collect();
            s.rescale = Some(("2", "-100"));
            s
        })
        .collect();
    write_all(&dir, &slices);
    let o = open(&dir.0).unwrap();
    assert_eq!(o.info.stored_type, SampleType::I8);
    assert_eq!(o.info.rescale, Rescale::non_identity(2.0, -100.0));
    assert_eq!(o.volume.sample_type(), SampleType::I16);
    let v = samples_f32(&o.volume);
    assert_eq!(v[0], -112.0);
    assert_eq!(v[11], -90.0);

    // Slopes that differ per slice: values in f32, per slice.
    let dir = TempDir::new();
    let mut slices = slices;
    slices[1].rescale = Some(("0.5", "1"));
    write_all(&dir, &slices);
    let o = open(&dir.0).unwrap();
    assert_eq!(o.info.rescale, None);
    assert_eq!(o.volume.sample_type(), SampleType::F32);
    assert!(o.info.notes.iter().any(|n| n.contains("per slice")));
    let v = samples_f32(&o.volume);
    assert_eq!((v[0], v[12], v[24]), (-112.0, -2.0, -112.0));
}

#[test]
fn series_choice_duplicates_gaps_and_single_slices() {
    let dir = TempDir::new();
    let mut slices: Vec<Synth> = (0..6)
        .map(|k| Synth::new(EXPLICIT_LE, k + 1, 2.0 * k as f64))
        .collect();
    // Another series of 2 slices, a duplicate position (a later
    // instance), and a gap: positions 0 2 4 6 8 10, drop 8.
    for k in 0..2 {
        let mut s = Synth::new(EXPLICIT_LE, k + 1, 5.0 * k as f64);
        s.series = "1.2.3.5";
        slices.push(s);
    }
    let mut dup = Synth::new(EXPLICIT_LE, 9, 4.0);
    dup.words = vec![7; 12];
    slices.push(dup);
    slices.remove(4);
    write_all(&dir, &slices);

    let o = open(&dir.0).unwrap();
    let notes = o.info.notes.join("; ");
    assert_eq!(o.info.dims.z, 5, "{notes}");
    assert!(
        notes.contains("directory holds 2 series; opened 1.2.3.4 (6 slices), the largest"),
        "{notes}"
    );
    assert!(notes.contains("1 of 6 slices share a position"), "{notes}");
    assert!(
        notes.contains("varies from 2 to 4 mm; using the mean 2.5 mm"),
        "{notes}"
    );
    assert!((o.info.spacing.z - 2.5).abs() < 1e-6);
    // The duplicate (instance 9) lost to instance 3 at position 4.
    let v = samples_f32(&o.volume);
    assert_eq!(v[2 * 12], 300.0);

    // A file of the small series opens that series.
    let small = dir.0.join(format!("s{}.dcm", 5));
    let o = open(&small).unwrap();
    assert_eq!(o.info.dims.z, 2);
    assert!((o.info.spacing.z - 5.0).abs() < 1e-6);
    assert!(o.info.notes[0].contains("opened 1.2.3.5 (2 slices), the one holding the file given"));

    // One slice: spacing from Slice Thickness.
    let one = TempDir::new();
    write_all(&one, &[Synth::new(IMPLICIT_LE, 1, 0.0)]);
    let o = open(&one.0).unwrap();
    assert_eq!(o.info.dims, UVec3::new(4, 3, 1));
    assert_eq!(o.info.spacing.z, 5.0);
    assert!(
        o.info
            .orientation
            .as_deref()
            .unwrap()
            .starts_with("row (0.6,0.8,0) col (0,0,-1)")
    );
}

/// Cosines rounded to six decimals (their cross product is 0.9999993 long)
/// and positions with sub-micrometre jitter: the slice spacing is still
/// exactly 3 mm, not 2.999998 or 3.0000002.
#[test]
fn slice_spacing_has_no_float_noise() {
    let dir = TempDir::new();
    let jitter = [0.0, 1e-7, 3e-7, 2e-7, 8e-7];
    let slices: Vec<Synth> = (0..5)
        .map(|k| {
            let mut s = Synth::new(EXPLICIT_LE, k + 1, 3.0 * k as f64 + jitter[k as usize]);
            s.orientation = [0.866025, 0.5, 0.0, -0.5, 0.866025, 0.0];
            s
        })
        .collect();
    write_all(&dir, &slices);
    let o = open(&dir.0).unwrap();
    assert_eq!(o.info.spacing, Vec3::new(0.75, 0.5, 3.0));
    assert_eq!(o.volume.grid().spacing, o.info.spacing);
    assert!(o.info.notes.is_empty(), "{:?}", o.info.notes);
}

// ------------------------------------------- hostile headers

/// Overwrites the 32-bit length of the first element with tag `(group,
/// element)` in a file written in `ts`, and returns the patched bytes.
fn with_length(bytes: &[u8], ts: &str, group: u16, element: u16, length: u32) -> Vec<u8> {
    let big = ts == EXPLICIT_BE;
    let tag: Vec<u8> = if big {
        [group.to_be_bytes(), element.to_be_bytes()].concat()
    } else {
        [group.to_le_bytes(), element.to_le_bytes()].concat()
    };
    // Past the file meta group (always little endian), so the search
    // starts at the dataset.
    let at = bytes[132..]
        .windows(4)
        .position(|w| w == tag.as_slice())
        .expect("tag present")
        + 132;
    // Implicit VR: tag, 32-bit length. Explicit VR with a 32-bit length:
    // tag, VR, 2 reserved bytes, length.
    let field = if ts == IMPLICIT_LE { at + 4 } else { at + 8 };
    let mut out = bytes.to_vec();
    let l = if big {
        length.to_be_bytes()
    } else {
        length.to_le_bytes()
    };
    out[field..field + 4].copy_from_slice(&l);
    out
}

/// Elements that claim gigabytes in a file of a few hundred bytes, at the
/// top level (the pixel data) and inside a sequence's item, are refused
/// by the length walk before the parser reserves and zeroes them.
#[test]
fn lengths_beyond_the_file_are_refused_before_parsing() {
    for ts in [EXPLICIT_LE, IMPLICIT_LE, EXPLICIT_BE] {
        let dir = TempDir::new();
        let mut synth = Synth::new(ts, 1, 0.0);
        synth.nested = Some(vec![7; 8]);
        let path = dir.0.join("s.dcm");
        synth.write(&path);
        let good = std::fs::read(&path).unwrap();
        assert!(open(&path).is_ok(), "{ts}: the unpatched file opens");
        for (what, group, element) in [
            ("pixel data", 0x7FE0, 0x0010),
            ("nested LUT data", 0x0028, 0x1201),
        ] {
            let bad = with_length(&good, ts, group, element, 0xF000_0000);
            std::fs::write(&path, &bad).unwrap();
            let start = std::time::Instant::now();
            let e = open(&path).expect_err(what).to_string();
            assert!(
                e.contains("declares 4026531840 bytes but only") && e.contains("s.dcm"),
                "{ts} {what}: {e}"
            );
            assert!(!e.contains('\n'), "{e}");
            // Not a timing test of speed: zeroing 4 GB would take seconds.
            assert!(start.elapsed().as_secs() < 2, "{ts} {what}");
        }
    }
}

/// Rows and Columns of 2^31 − 1 (as UL) in a small file: an error naming
/// the file before anything is allocated for them, not an abort.
#[test]
fn huge_rows_and_columns_are_refused_before_allocating() {
    for ts in [EXPLICIT_LE, IMPLICIT_LE] {
        let dir = TempDir::new();
        let mut synth = Synth::new(ts, 1, 0.0);
        synth.dims_ul = Some((i32::MAX as u32, i32::MAX as u32));
        let path = dir.0.join("s.dcm");
        synth.write(&path);
        let e = open(&path).expect_err("huge image").to_string();
        assert!(e.contains("s.dcm") && !e.contains('\n'), "{ts}: {e}");
        assert!(
            e.contains("cannot hold pixel data") || e.contains("exceed") || e.contains("too large"),
            "{ts}: {e}"
        );
    }
}

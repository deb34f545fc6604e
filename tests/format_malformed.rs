//! Malformed NRRD, NIfTI, `.vol`, UC Davis and raw files: each gives a
//! one-line error that names the file (or its missing data file), never a
//! panic.

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use common::TempDir;
use common::file_bytes::{NiiHeader, gzip, header_end, nrrd_header, vol_header, with_field};
use common::volumes::{SYN_DIMS, SYN_SPACING};
use glam::{UVec3, Vec3};
use raycaster::format::davis::DavisHeader;
use raycaster::format::{self as fmt, Endian, OpenOptions, RawOptions};
use raycaster::prelude::*;

/// A 7×5×9 u8 NRRD header, raw encoding.
const NRRD_U8: &[(&str, &str)] = &[
    ("type", "uchar"),
    ("dimension", "3"),
    ("sizes", "7 5 9"),
    ("spacings", "0.5 1.25 2"),
    ("encoding", "raw"),
];

/// One malformed file: its name, bytes, extra files next to it, raw options,
/// the substrings its error must contain and the file name the error must
/// name (the file itself unless given).
struct Case {
    what: &'static str,
    file: &'static str,
    bytes: Vec<u8>,
    extra: Vec<(&'static str, Vec<u8>)>,
    raw: Option<RawOptions>,
    expect: Vec<String>,
    names: Option<&'static str>,
}

fn case(what: &'static str, file: &'static str, bytes: Vec<u8>, expect: &[&str]) -> Case {
    Case {
        what,
        file,
        bytes,
        extra: Vec::new(),
        raw: None,
        expect: expect.iter().map(|s| s.to_string()).collect(),
        names: None,
    }
}

fn raw_case(what: &'static str, bytes: Vec<u8>, raw: RawOptions, expect: &[&str]) -> Case {
    Case {
        raw: Some(raw),
        ..case(what, "bad.raw", bytes, expect)
    }
}

/// Opens `path` (with `raw` options if given) expecting an error; returns
/// the message, or a description of what went wrong instead.
fn error_of(path: &Path, raw: Option<RawOptions>) -> Result<String, String> {
    let options = OpenOptions {
        raw,
        ..OpenOptions::default()
    };
    match catch_unwind(AssertUnwindSafe(|| fmt::open_file(path, &options))) {
        Err(p) => Err(format!(
            "PANIC: {}",
            p.downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| p.downcast_ref::<&str>().copied())
                .unwrap_or("?")
        )),
        Ok(Ok(o)) => Err(format!(
            "opened as {} {:?} {}",
            o.info.format, o.info.dims, o.info.stored_type
        )),
        Ok(Err(e)) => Ok(e.to_string()),
    }
}

fn malformed_cases(dir: &TempDir) -> Vec<Case> {
    let u8_data = vec![7u8; 315];
    let hdr = nrrd_header(NRRD_U8);
    let h = hdr.len();
    let nrrd = |fields: &[(&str, &str)], data: &[u8]| {
        [nrrd_header(fields).into_bytes(), data.to_vec()].concat()
    };
    let nrrd_with = |key: &'static str, value: Option<&'static str>| {
        nrrd(&with_field(NRRD_U8, key, value), &u8_data)
    };
    let skip_file = nrrd_with("byte skip", Some("100"));
    let skip_h = header_end(&skip_file).expect("header end");
    let gz_fields = with_field(NRRD_U8, "encoding", Some("gzip"));
    let gz_315 = gzip(dir, &u8_data);
    let nii = |f: &dyn Fn(&mut NiiHeader), data_len: usize| {
        let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
        f(&mut h);
        h.file(&vec![1u8; data_len])
    };
    let nii_ok = nii(&|_| {}, 630);
    let vol = |dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8, data: usize| {
        [vol_header(dims, spacing, layout, extra), vec![9u8; data]].concat()
    };
    let raw = |dims: [u32; 3], ty: SampleType| {
        RawOptions::new(UVec3::from_array(dims), ty, Endian::Little)
    };
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };

    let mut cases = vec![
        // ---- NRRD
        case(
            "nrrd: empty file",
            "bad.nrrd",
            vec![],
            &["not an NRRD file"],
        ),
        case(
            "nhdr: empty file",
            "bad.nhdr",
            vec![],
            &["not an NRRD file"],
        ),
        case(
            "nrrd: truncated data",
            "bad.nrrd",
            [hdr.as_bytes(), &u8_data[..100]].concat(),
            &[
                leak(format!("expected {} bytes", h + 315)),
                leak(format!("found {}", h + 100)),
            ],
        ),
        case(
            "nrrd: truncated header, mid-line",
            "bad.nrrd",
            b"NRRD0004\ntype: uchar\ndimensi".to_vec(),
            &["malformed header line", "dimensi"],
        ),
        case(
            "nrrd: truncated header, at a line end",
            "bad.nrrd",
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 7 5 9\n".to_vec(),
            &["missing field \"encoding\""],
        ),
        case(
            "nrrd: missing sizes",
            "bad.nrrd",
            nrrd_with("sizes", None),
            &["missing field \"sizes\""],
        ),
        case(
            "nrrd: missing type",
            "bad.nrrd",
            nrrd_with("type", None),
            &["missing field \"type\""],
        ),
        case(
            "nrrd: sizes do not match dimension",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 5")),
            &["dimension is 3 but sizes has 2 entries"],
        ),
        case(
            "nrrd: zero size",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 0 9")),
            &["sizes must be positive"],
        ),
        case(
            "nrrd: negative size",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 -5 9")),
            &["sizes must be positive"],
        ),
        case(
            "nrrd: 5-D",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "dimension", Some("5")),
                    "sizes",
                    Some("7 5 9 1 1"),
                ),
                &u8_data,
            ),
            &["unsupported", "5-dimensional"],
        ),
        case(
            "nrrd: type double",
            "bad.nrrd",
            nrrd_with("type", Some("double")),
            &["unsupported", "\"double\""],
        ),
        case(
            "nrrd: type int",
            "bad.nrrd",
            nrrd_with("type", Some("int")),
            &["unsupported", "\"int\""],
        ),
        case(
            "nrrd: encoding ascii",
            "bad.nrrd",
            nrrd_with("encoding", Some("ascii")),
            &["unsupported", "\"ascii\""],
        ),
        case(
            "nrrd: encoding bzip2",
            "bad.nrrd",
            nrrd_with("encoding", Some("bzip2")),
            &["unsupported", "\"bzip2\""],
        ),
        case(
            "nrrd: no endian for a 2-byte type",
            "bad.nrrd",
            nrrd(&with_field(NRRD_U8, "type", Some("short")), &[0; 630]),
            &["endian"],
        ),
        case(
            "nrrd: corrupt gzip stream",
            "bad.nrrd",
            nrrd(
                &gz_fields,
                b"\x1f\x8b\x08\x00 this is not deflate data at all",
            ),
            &["gzip"],
        ),
        case(
            "nrrd: not gzip at all",
            "bad.nrrd",
            nrrd(&gz_fields, b"plain text where gzip should be"),
            &["gzip"],
        ),
        case(
            "nrrd: truncated gzip stream",
            "bad.nrrd",
            nrrd(&gz_fields, &gz_315[..gz_315.len() / 2]),
            &["gzip"],
        ),
        case(
            "nrrd: gzip decodes to too few bytes",
            "bad.nrrd",
            nrrd(&gz_fields, &gzip(dir, &u8_data[..100])),
            &["expected 315 bytes", "found 100"],
        ),
        case(
            "nrrd: NaN in space directions",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(NaN,0,0) (0,1,0) (0,0,1)"),
                ),
                &u8_data,
            ),
            &["spacing X is NaN"],
        ),
        case(
            "nrrd: zero space direction",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(1,0,0) (0,1,0) (0,0,0)"),
                ),
                &u8_data,
            ),
            &["spacing Z is 0"],
        ),
        case(
            "nrrd: malformed space directions",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(1,0,0) (0,1,0)"),
                ),
                &u8_data,
            ),
            &["space directions"],
        ),
        case(
            "nrrd: byte skip past the data",
            "bad.nrrd",
            skip_file.clone(),
            &[
                leak(format!("expected {} bytes", skip_h + 100 + 315)),
                leak(format!("found {}", skip_file.len())),
            ],
        ),
        case(
            "nrrd: line skip past the end",
            "bad.nrrd",
            nrrd_with("line skip", Some("1000")),
            &["line skip"],
        ),
        case(
            "nrrd: data split over files",
            "bad.nrrd",
            nrrd_with("data file", Some("LIST")),
            &["unsupported", "several files"],
        ),
        Case {
            names: Some("gone.raw"),
            ..case(
                "nhdr: detached data file missing",
                "bad.nhdr",
                nrrd_header(&with_field(NRRD_U8, "data file", Some("gone.raw"))).into_bytes(),
                &[],
            )
        },
        Case {
            extra: vec![("short.raw", vec![0u8; 200])],
            names: Some("short.raw"),
            ..case(
                "nhdr: detached data file too short",
                "bad.nhdr",
                nrrd_header(&with_field(NRRD_U8, "data file", Some("short.raw"))).into_bytes(),
                &["expected 315 bytes", "found 200"],
            )
        },
        // ---- NIfTI
        case("nii: empty file", "bad.nii", vec![], &["348"]),
        case(
            "nii: truncated header",
            "bad.nii",
            nii_ok[..200].to_vec(),
            &["200 bytes", "348"],
        ),
        case(
            "nii: truncated data",
            "bad.nii",
            nii_ok[..352 + 100].to_vec(),
            &["expected 982 bytes", "found 452"],
        ),
        case(
            "nii: dim[0] = 0",
            "bad.nii",
            nii(&|h| h.dim[0] = 0, 630),
            &["dim[0] is 0"],
        ),
        case(
            "nii: dim[0] = -3",
            "bad.nii",
            nii(&|h| h.dim[0] = -3, 630),
            &["dim[0] is -3"],
        ),
        case(
            "nii: dim[0] = 8",
            "bad.nii",
            nii(&|h| h.dim[0] = 8, 630),
            &["dim[0] is 8"],
        ),
        case(
            "nii: negative dimension",
            "bad.nii",
            nii(&|h| h.dim[2] = -5, 630),
            &["7x-5x9"],
        ),
        case(
            "nii: zero dimension",
            "bad.nii",
            nii(&|h| h.dim[3] = 0, 630),
            &["7x5x0"],
        ),
        case(
            "nii: datatype 64 FLOAT64",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (64, 64), 2520),
            &["unsupported", "FLOAT64"],
        ),
        case(
            "nii: datatype 8 INT32",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (8, 32), 1260),
            &["unsupported", "INT32"],
        ),
        case(
            "nii: datatype 128 RGB24",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (128, 24), 945),
            &["unsupported", "RGB24"],
        ),
        case(
            "nii: unknown datatype",
            "bad.nii",
            nii(&|h| h.datatype = 3, 630),
            &["unsupported", "datatype 3"],
        ),
        case(
            "nii: wrong sizeof_hdr",
            "bad.nii",
            nii(&|h| h.sizeof_hdr = 540, 630),
            &["sizeof_hdr"],
        ),
        case(
            "nii: wrong magic",
            "bad.nii",
            nii(&|h| h.magic = *b"n+2\0", 630),
            &["magic"],
        ),
        case(
            "nii: two-file magic in a .nii",
            "bad.nii",
            nii(&|h| h.magic = *b"ni1\0", 630),
            &[".hdr"],
        ),
        case(
            "nii: vox_offset inside the header",
            "bad.nii",
            nii(&|h| h.vox_offset = 100.0, 630),
            &["vox_offset 100"],
        ),
        case(
            "nii: vox_offset NaN",
            "bad.nii",
            nii(&|h| h.vox_offset = f32::NAN, 630),
            &["vox_offset NaN"],
        ),
        case(
            "nii: vox_offset past the end",
            "bad.nii",
            nii(&|h| h.vox_offset = 4096.0, 630),
            &["expected 4726 bytes", "found 982"],
        ),
        case(
            "nii: vox_offset 1e30",
            "bad.nii",
            nii(&|h| h.vox_offset = 1e30, 630),
            &["expected"],
        ),
        case("nii.gz: empty file", "bad.nii.gz", vec![], &[]),
        case(
            "nii.gz: corrupt gzip stream",
            "bad.nii.gz",
            b"\x1f\x8b\x08\x00 this is not deflate data at all".to_vec(),
            &["header"],
        ),
        case(
            "nii.gz: truncated gzip stream",
            "bad.nii.gz",
            {
                let gz = gzip(dir, &nii(&|_| {}, 630));
                gz[..gz.len() * 2 / 3].to_vec()
            },
            &[],
        ),
        case(
            "nii.gz: truncated data",
            "bad.nii.gz",
            gzip(dir, &nii_ok[..352 + 100]),
            &["expected 982 bytes", "found 452", "decompressed"],
        ),
        case(
            "nii.gz: vox_offset 1e30",
            "bad.nii.gz",
            gzip(dir, &nii(&|h| h.vox_offset = 1e30, 630)),
            &["expected"],
        ),
        case(
            "nii.gz: huge dimensions, tiny stream",
            "bad.nii.gz",
            gzip(
                dir,
                &nii(
                    &|h| {
                        h.dim = [3, 32767, 32767, 32767, 1, 1, 1, 1];
                        (h.datatype, h.bitpix) = (16, 32);
                    },
                    630,
                ),
            ),
            // Rejected before decoding: gzip cannot expand that far.
            &["140724603846652 bytes", "more than"],
        ),
        case(
            "nii: huge dimensions",
            "bad.nii",
            nii(&|h| h.dim = [3, 32767, 32767, 32767, 1, 1, 1, 1], 630),
            &["expected", "found 982"],
        ),
        case(
            "nrrd: gzip, huge sizes, tiny stream",
            "bad.nrrd",
            nrrd(
                &with_field(&gz_fields, "sizes", Some("100000 100000 100000")),
                &gz_315,
            ),
            &["1000000000000000 bytes", "more than"],
        ),
        // ---- .vol
        case(
            "vol: empty file",
            "bad.vol",
            vec![],
            &["0 bytes", "26-byte header"],
        ),
        case(
            "vol: truncated header",
            "bad.vol",
            vol_header([7, 5, 9], [1.0; 3], 1, 0)[..10].to_vec(),
            &["10 bytes", "26-byte header"],
        ),
        case(
            "vol: truncated data",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 1, 0, 100),
            &["expected 341 bytes", "found 126"],
        ),
        case(
            "vol: one byte too many",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 1, 0, 316),
            &["expected 341 bytes", "found 342"],
        ),
        case(
            "vol: zero dimension",
            "bad.vol",
            vol([7, 0, 9], [1.0; 3], 1, 0, 0),
            &["dimension Y is 0"],
        ),
        case(
            "vol: NaN spacing",
            "bad.vol",
            vol([7, 5, 9], [f32::NAN, 1.0, 1.0], 1, 0, 315),
            &["spacing X is NaN"],
        ),
        case(
            "vol: negative spacing",
            "bad.vol",
            vol([7, 5, 9], [1.0, 1.0, -1.0], 1, 0, 315),
            &["spacing Z is -1"],
        ),
        case(
            "vol: unknown layout",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 3, 0, 315),
            &["unknown layout byte 3"],
        ),
        case(
            "vol: brick side 1",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 2, 1, 315),
            &["brick side 1"],
        ),
        case(
            "vol: bricked, truncated",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 2, 4, 100),
            &["expected", "bricks of 4^3", "found 126"],
        ),
        case(
            "vol: dimensions overflow",
            "bad.vol",
            vol([u32::MAX; 3], [1.0; 3], 1, 0, 0),
            &["overflow"],
        ),
        case(
            "vol: UC Davis header, truncated",
            "bad.vol",
            {
                let mut b = DavisHeader {
                    dims: SYN_DIMS,
                    border: 0,
                    spacing: Vec3::ONE,
                }
                .to_bytes()
                .to_vec();
                b.extend_from_slice(&[1u8; 100]);
                b
            },
            &[],
        ),
        // ---- raw
        raw_case(
            "raw: dims larger than the file",
            vec![0; 315],
            raw([7, 5, 10], SampleType::U8),
            &["expected 350 bytes", "found 315"],
        ),
        raw_case(
            "raw: dims smaller than the file",
            vec![0; 315],
            raw([7, 5, 8], SampleType::U8),
            &["expected 280 bytes", "found 315"],
        ),
        raw_case(
            "raw: 2-byte type, half the bytes",
            vec![0; 315],
            raw([7, 5, 9], SampleType::U16),
            &["expected 630 bytes", "found 315"],
        ),
        raw_case(
            "raw: empty file",
            vec![],
            raw([7, 5, 9], SampleType::U8),
            &["expected 315 bytes", "found 0"],
        ),
        raw_case(
            "raw: zero dimension",
            vec![0; 315],
            raw([7, 5, 0], SampleType::U8),
            &["dimension Z is 0"],
        ),
        raw_case(
            "raw: NaN spacing",
            vec![0; 315],
            RawOptions {
                spacing: Vec3::new(1.0, f32::NAN, 1.0),
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["spacing Y is NaN"],
        ),
        raw_case(
            "raw: infinite spacing",
            vec![0; 315],
            RawOptions {
                spacing: Vec3::new(1.0, 1.0, f32::INFINITY),
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["spacing Z is inf"],
        ),
        raw_case(
            "raw: offset past the end",
            vec![0; 315],
            RawOptions {
                offset: 1000,
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["expected 1315 bytes", "found 315"],
        ),
        raw_case(
            "raw: offset near u64::MAX",
            vec![0; 315],
            RawOptions {
                offset: u64::MAX - 5,
                ..raw([7, 5, 9], SampleType::U8)
            },
            &[],
        ),
        raw_case(
            "raw: sizes overflow",
            vec![0; 315],
            raw([1 << 30, 1 << 30, 1 << 30], SampleType::F32),
            &["overflow"],
        ),
        case(
            "raw: no description",
            "bad.raw",
            vec![0; 315],
            &["--raw-dims"],
        ),
        case(
            "unknown extension",
            "bad.xyz",
            vec![0; 315],
            &["unrecognised", ".xyz"],
        ),
    ];
    // UC Davis bytes that cannot be any format under the .vol extension.
    cases.push(case(
        "vol: random 27 bytes",
        "bad.vol",
        (0..27u8).collect(),
        &["unknown layout byte 24"],
    ));
    cases
}

#[test]
fn malformed_files_give_one_line_errors_naming_the_file() {
    let dir = TempDir::new("malformed");
    let mut failures = Vec::new();
    for (i, c) in malformed_cases(&dir).into_iter().enumerate() {
        // Each case in its own directory: extra files don't leak between cases.
        let sub = dir.join(&format!("case{i}"));
        std::fs::create_dir_all(&sub).unwrap();
        let path = sub.join(c.file);
        std::fs::write(&path, &c.bytes).unwrap();
        for (name, bytes) in &c.extra {
            std::fs::write(sub.join(name), bytes).unwrap();
        }
        let msg = match error_of(&path, c.raw.clone()) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{}: {e}", c.what));
                continue;
            }
        };
        let name = c.names.unwrap_or(c.file);
        let mut problems = Vec::new();
        if msg.contains('\n') || msg.trim().is_empty() {
            problems.push("not one line".to_string());
        }
        if !msg.contains(name) {
            problems.push(format!("does not name {name}"));
        }
        for e in &c.expect {
            if !msg.contains(e.as_str()) {
                problems.push(format!("lacks \"{e}\""));
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {} — error was: {msg}",
                c.what,
                problems.join(", ")
            ));
        }
    }
    // A missing file, and a directory given as a raw file.
    let missing = dir.join("missing.nrrd");
    match error_of(&missing, None) {
        Ok(m) if m.contains("missing.nrrd") && !m.contains('\n') => {}
        other => failures.push(format!("missing file: {other:?}")),
    }
    let raw = RawOptions::new(SYN_DIMS, SampleType::U8, Endian::Little);
    match error_of(&dir.0, Some(raw)) {
        Ok(m) if m.contains("directory") && !m.contains('\n') => {}
        other => failures.push(format!("directory as raw: {other:?}")),
    }
    assert!(
        failures.is_empty(),
        "{} case(s) failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

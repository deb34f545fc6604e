//! NRRD variants: detached headers, line and byte skips, spacings
//! and space directions, CRLF line endings, big-endian data and 4-D files.

mod common;

use std::path::Path;

use common::TempDir;
use common::file_bytes::{gzip, nrrd_header, with_field};
use common::volumes::{
    SYN_DIMS, SYN_SPACING, assert_same_volume, check_opened, has_note, le_bytes, open, synthetic,
};
use raycaster::format::samples;
use raycaster::format::{Endian, FileFormat, Opened};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

#[test]
fn nrrd_detached_headers_skips_spacings_and_4d() {
    let dir = TempDir::new("nrrd-variants");
    let want = synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 21);
    let le = le_bytes(&want);
    let base: &[(&str, &str)] = &[
        ("type", "unsigned short"),
        ("dimension", "3"),
        ("sizes", "7 5 9"),
        ("spacings", "0.5 1.25 2"),
        ("endian", "little"),
        ("encoding", "raw"),
    ];
    let check = |what: &str, path: &Path, want: &AnyVolume| -> Opened {
        let opened = open(path);
        check_opened(what, &opened, want, FileFormat::Nrrd, want.sample_type());
        opened
    };

    // Detached .nhdr + .raw.
    dir.file("vol.raw", &le);
    let p = dir.file(
        "detached.nhdr",
        nrrd_header(&with_field(base, "data file", Some("vol.raw"))).as_bytes(),
    );
    let opened = check("detached .nhdr", &p, &want);
    assert!(
        has_note(&opened, &["vol.raw"]),
        "notes: {:?}",
        opened.info.notes
    );
    assert_eq!(
        opened.info.file_bytes,
        std::fs::metadata(&p).unwrap().len() + le.len() as u64
    );
    // A detached header without the final blank line, and the old spelling.
    let mut text = nrrd_header(&with_field(base, "datafile", Some("vol.raw")));
    text.pop();
    let p = dir.file("no-blank-line.nhdr", text.as_bytes());
    check("detached .nhdr without blank line", &p, &want);

    // Detached with line skip and byte skip.
    let mut data = b"first line\nsecond line\n".to_vec();
    data.extend_from_slice(b"12345");
    data.extend_from_slice(&le);
    data.extend_from_slice(b"trailing bytes are allowed");
    dir.file("skips.dat", &data);
    let fields = with_field(base, "data file", Some("skips.dat"));
    let fields = with_field(&fields, "line skip", Some("2"));
    let fields = with_field(&fields, "byte skip", Some("5"));
    let p = dir.file("skips.nhdr", nrrd_header(&fields).as_bytes());
    check("line skip 2 + byte skip 5", &p, &want);

    // Attached, byte skip after the header.
    let mut file = nrrd_header(&with_field(base, "byte skip", Some("3"))).into_bytes();
    file.extend_from_slice(b"abc");
    file.extend_from_slice(&le);
    let p = dir.file("byteskip.nrrd", &file);
    check("attached byte skip 3", &p, &want);

    // Attached, byte skip -1: the samples are the file's last bytes.
    let mut file = nrrd_header(&with_field(base, "byte skip", Some("-1"))).into_bytes();
    file.extend_from_slice(b"junk between header and data");
    file.extend_from_slice(&le);
    let p = dir.file("byteskip-1.nrrd", &file);
    check("attached byte skip -1", &p, &want);

    // Detached gzip data.
    dir.file("vol.raw.gz", &gzip(&dir, &le));
    let fields = with_field(base, "data file", Some("vol.raw.gz"));
    let fields = with_field(&fields, "encoding", Some("gzip"));
    let p = dir.file("detached-gz.nhdr", nrrd_header(&fields).as_bytes());
    check("detached gzip", &p, &want);

    // Spacing from spacings (no orientation) and from oblique space
    // directions (their lengths), with `space origin`.
    let p = dir.file(
        "spacings.nrrd",
        &[nrrd_header(base).into_bytes(), le.clone()].concat(),
    );
    let opened = check("spacings", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);
    assert_eq!(opened.info.orientation, None);
    let fields = with_field(base, "spacings", None);
    let fields = with_field(&fields, "space", Some("right-anterior-superior"));
    let fields = with_field(
        &fields,
        "space directions",
        Some("(0.3,0.4,0) (0,0,1.25) (-2,0,0)"),
    );
    let fields = with_field(&fields, "space origin", Some("(1,2,3)"));
    let p = dir.file(
        "directions.nrrd",
        &[nrrd_header(&fields).into_bytes(), le.clone()].concat(),
    );
    let opened = check("space directions", &p, &want);
    assert!((opened.info.spacing - SYN_SPACING).abs().max_element() < 1e-6);
    let o = opened.info.orientation.as_deref().unwrap_or("");
    assert!(
        o.contains("(0.3,0.4,0)") && o.contains("(1,2,3)"),
        "orientation: {o}"
    );

    // CRLF line endings.
    let crlf = nrrd_header(base).replace('\n', "\r\n");
    let p = dir.file("crlf.nrrd", &[crlf.into_bytes(), le.clone()].concat());
    check("CRLF header", &p, &want);

    // Big-endian short.
    let signed = synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 22);
    let fields = with_field(base, "type", Some("short"));
    let fields = with_field(&fields, "endian", Some("big"));
    let be = samples::encode_volume(&signed, AxisOrder::XFast, Endian::Big);
    let p = dir.file(
        "big.nrrd",
        &[nrrd_header(&fields).into_bytes(), be].concat(),
    );
    let opened = check("big-endian short", &p, &signed);
    assert_eq!(opened.info.byte_order, Some(Endian::Big));

    // 4-D with a size-1 first axis (spacing `nan` there; `none` direction).
    let fields = with_field(base, "dimension", Some("4"));
    let fields = with_field(&fields, "sizes", Some("1 7 5 9"));
    let fields4 = with_field(&fields, "spacings", Some("nan 0.5 1.25 2"));
    let p = dir.file(
        "4d-first.nrrd",
        &[nrrd_header(&fields4).into_bytes(), le.clone()].concat(),
    );
    let opened = check("4-D, size-1 first axis, spacings", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);
    let fields4 = with_field(&fields, "spacings", None);
    let fields4 = with_field(
        &fields4,
        "space directions",
        Some("none (0.5,0,0) (0,1.25,0) (0,0,2)"),
    );
    let p = dir.file(
        "4d-none.nrrd",
        &[nrrd_header(&fields4).into_bytes(), le.clone()].concat(),
    );
    let opened = check("4-D, size-1 first axis, space directions", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);

    // 4-D with three volumes along the slowest axis: the first opens.
    let others = [
        synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 23),
        synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 24),
    ];
    let fields = with_field(base, "dimension", Some("4"));
    let fields = with_field(&fields, "sizes", Some("7 5 9 3"));
    let fields = with_field(&fields, "spacings", Some("0.5 1.25 2 nan"));
    let mut file = nrrd_header(&fields).into_bytes();
    file.extend_from_slice(&le);
    file.extend(le_bytes(&others[0]));
    file.extend(le_bytes(&others[1]));
    let p = dir.file("4d-slowest.nrrd", &file);
    let opened = check("4-D, 3 volumes", &p, &want);
    assert!(
        has_note(&opened, &["3 volumes", "opened volume 0"]),
        "notes: {:?}",
        opened.info.notes
    );
    assert_eq!(opened.info.volumes, 3);
    // The others by their index.
    for (k, other) in others.iter().enumerate() {
        let options = raycaster::format::OpenOptions {
            volume: k as u64 + 1,
            ..Default::default()
        };
        let v = raycaster::format::open_file(&p, &options).expect("volume k");
        assert_same_volume(&format!("4-D volume {}", k + 1), &v.volume, other);
    }
}

//! Round trips through the project's writers: synthetic
//! volumes of every sample type through NRRD (raw and gzip), NIfTI (`.nii`,
//! `.nii.gz`) and raw files in both axis orders and byte orders, and u8
//! volumes through `.vol` (both layouts) and the UC Davis `.vol`, give the
//! same voxels.

mod common;

use common::TempDir;
use common::volumes::{
    ALL_TYPES, SYN_DIMS, SYN_SPACING, all_f32, check_opened, has_note, le_bytes, min_max, open,
    open_raw, raw_options, synthetic,
};
use raycaster::format::davis::DavisHeader;
use raycaster::format::nrrd::{self, Encoding};
use raycaster::format::samples;
use raycaster::format::vol::{self, VolLayout};
use raycaster::format::{self as fmt, Endian, FileFormat, Opened, nifti, raw};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

#[test]
fn synthetic_volumes_of_every_type_round_trip_through_every_writer() {
    let dir = TempDir::new("synthetic");
    for (i, ty) in ALL_TYPES.into_iter().enumerate() {
        let want = synthetic(ty, SYN_DIMS, SYN_SPACING, 11 + i as u64);
        let le = le_bytes(&want);
        let range = min_max(&all_f32(&want));
        let check_range = |what: &str, opened: Opened| {
            assert_eq!(
                Scene::new(opened.volume).value_range(),
                range,
                "{what}: value range"
            );
        };

        for (enc, ext, name) in [
            (Encoding::Raw, "nrrd", "raw"),
            (Encoding::Gzip, "nrrd", "gzip"),
        ] {
            let what = format!("{ty} NRRD {name}");
            let p = dir.join(&format!("{ty}-{name}.{ext}"));
            nrrd::write(&p, SYN_DIMS, SYN_SPACING, ty, enc, samples::bytes(&le))
                .expect("nrrd write");
            let opened = open(&p);
            check_opened(&what, &opened, &want, FileFormat::Nrrd, ty);
            assert_eq!(opened.info.encoding, name, "{what}");
            assert!(opened.info.orientation.is_some(), "{what}: orientation");
            check_range(&what, opened);
        }

        for (name, encoding) in [("nii", "raw"), ("nii.gz", "gzip")] {
            let what = format!("{ty} .{name}");
            let p = dir.join(&format!("{ty}.{name}"));
            nifti::write(&p, SYN_DIMS, SYN_SPACING, ty, None, samples::bytes(&le))
                .expect("nifti write");
            let opened = open(&p);
            check_opened(&what, &opened, &want, FileFormat::Nifti, ty);
            assert_eq!(opened.info.encoding, encoding, "{what}");
            assert_eq!(opened.info.rescale, None, "{what}");
            check_range(&what, opened);
        }

        for order in [AxisOrder::XFast, AxisOrder::ZFast] {
            for endian in [Endian::Little, Endian::Big] {
                let what = format!("{ty} raw {order:?} {}", endian.name());
                let p = dir.join(&format!("{ty}-{order:?}-{}.raw", endian.name()));
                raw::write(&p, &want, order, endian).expect("raw write");
                let bytes = std::fs::read(&p).unwrap();
                assert_eq!(
                    bytes,
                    samples::encode_volume(&want, order, endian),
                    "{what}: file bytes"
                );
                if order == AxisOrder::XFast && endian == Endian::Little {
                    assert_eq!(
                        bytes, le,
                        "{what}: x-fast little-endian is the NRRD payload"
                    );
                }
                let mut options = raw_options(SYN_DIMS, ty, endian, order);
                options.spacing = SYN_SPACING;
                let opened = open_raw(&p, options.clone());
                check_opened(&what, &opened, &want, FileFormat::Raw, ty);
                check_range(&what, opened);

                // The same samples behind a 37-byte foreign header.
                let mut with_header = vec![0xA5u8; 37];
                with_header.extend_from_slice(&bytes);
                let p = dir.file(
                    &format!("{ty}-{order:?}-{}-offset.bin", endian.name()),
                    &with_header,
                );
                options.offset = 37;
                let opened = open_raw(&p, options);
                check_opened(
                    &format!("{what} offset 37"),
                    &opened,
                    &want,
                    FileFormat::Raw,
                    ty,
                );
            }
        }
    }
}

#[test]
fn u8_volumes_round_trip_through_vol_and_uc_davis() {
    let dir = TempDir::new("vol-davis");
    let want = synthetic(SampleType::U8, SYN_DIMS, SYN_SPACING, 5);

    // This project's .vol, both layouts.
    for (name, layout) in [
        ("linear.vol", VolLayout::Linear),
        ("bricked.vol", VolLayout::Bricked { side: 3 }),
    ] {
        let p = dir.join(name);
        vol::write(&p, &want, layout).unwrap();
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Vol, "{name}");
        check_opened(name, &open(&p), &want, FileFormat::Vol, SampleType::U8);
    }

    // UC Davis: 28-byte big-endian header, u8 samples z fastest.
    let davis = |border: u32| {
        let mut b = DavisHeader {
            dims: SYN_DIMS,
            border,
            spacing: SYN_SPACING,
        }
        .to_bytes()
        .to_vec();
        b.extend(samples::encode_volume(&want, AxisOrder::ZFast, Endian::Big));
        b
    };
    for name in ["davis.vol", "DAVIS.VOL", "davis"] {
        let p = dir.file(name, &davis(0));
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::DavisVol, "{name}");
        let opened = open(&p);
        check_opened(name, &opened, &want, FileFormat::DavisVol, SampleType::U8);
        assert!(
            opened.info.notes.is_empty(),
            "{name}: {:?}",
            opened.info.notes
        );
    }
    let p = dir.file("border.vol", &davis(2));
    let opened = open(&p);
    check_opened(
        "border.vol",
        &opened,
        &want,
        FileFormat::DavisVol,
        SampleType::U8,
    );
    assert!(
        has_note(&opened, &["border of 2"]),
        "notes: {:?}",
        opened.info.notes
    );

    // The same bytes: a .vol without extension is still this project's .vol.
    let spec = std::fs::read(dir.join("linear.vol")).unwrap();
    let p = dir.file("spec-no-extension", &spec);
    assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Vol);
}

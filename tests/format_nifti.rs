//! NIfTI-1 variants: rescaling to data units, big-endian files,
//! and 4-D files, of which the first volume opens.

mod common;

use common::TempDir;
use common::file_bytes::{NiiHeader, gzip};
use common::volumes::{
    ALL_TYPES, SYN_DIMS, SYN_SPACING, all_f32, assert_same_volume, check_opened, has_note,
    le_bytes, min_max, open, synthetic,
};
use glam::{UVec3, Vec3};
use raycaster::format::samples;
use raycaster::format::{self as fmt, Endian, FileFormat, Rescale, nifti};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

/// A synthetic volume with values that a rescale keeps inside i16 (or not,
/// with `wide`).
fn small_range(ty: SampleType, dims: UVec3, spacing: Vec3) -> AnyVolume {
    let grid = Grid::new(dims, spacing);
    let n = |p: UVec3| ((p.z * dims.y + p.y) * dims.x + p.x) as i32;
    match ty {
        SampleType::U8 => AnyVolume::from_fn(grid, |p| (n(p) * 7 % 256) as u8),
        SampleType::I8 => AnyVolume::from_fn(grid, |p| (n(p) * 7 % 256 - 128) as i8),
        SampleType::U16 => AnyVolume::from_fn(grid, |p| (n(p) * 211 % 4000) as u16),
        SampleType::I16 => AnyVolume::from_fn(grid, |p| (n(p) * 211 % 4000 - 2000) as i16),
        SampleType::F32 => AnyVolume::from_fn(grid, |p| (n(p) * 211 % 4000 - 2000) as f32 * 0.25),
    }
}

#[test]
fn nifti_rescale_gives_data_units() {
    let dir = TempDir::new("rescale");
    // (stored type, slope, intercept, type after rescaling)
    let cases: &[(SampleType, f32, f32, SampleType)] = &[
        (SampleType::U8, 2.0, -100.0, SampleType::I16),
        (SampleType::U8, 1.0, -128.0, SampleType::I16),
        (SampleType::I8, -1.0, 0.0, SampleType::I16),
        (SampleType::I16, 3.0, -1024.0, SampleType::I16),
        (SampleType::U16, 1.0, -1024.0, SampleType::I16),
        (SampleType::U16, 0.5, 0.0, SampleType::F32),
        (SampleType::U8, 1.0, 0.25, SampleType::F32),
        (SampleType::I16, 20.0, 0.0, SampleType::F32), // 2000·20 leaves i16
        (SampleType::I16, 1.0, 32000.0, SampleType::F32),
        (SampleType::F32, 2.0, 1.0, SampleType::F32),
        (SampleType::I16, -0.125, 10.5, SampleType::F32),
    ];
    for &(ty, slope, inter, result) in cases {
        let stored = small_range(ty, SYN_DIMS, SYN_SPACING);
        let le = le_bytes(&stored);
        let expected: Vec<f32> = all_f32(&stored)
            .iter()
            .map(|&s| (s as f64 * slope as f64 + inter as f64) as f32)
            .collect();
        let rescale = Rescale {
            slope: slope as f64,
            intercept: inter as f64,
        };
        for ext in ["nii", "nii.gz"] {
            let what = format!("{ty} × {slope} + {inter} .{ext}");
            let p = dir.join(&format!("{ty}-{slope}-{inter}.{ext}"));
            nifti::write(
                &p,
                SYN_DIMS,
                SYN_SPACING,
                ty,
                Some(rescale),
                samples::bytes(&le),
            )
            .unwrap();
            let opened = open(&p);
            assert_eq!(opened.info.stored_type, ty, "{what}: stored type");
            assert_eq!(opened.info.rescale, Some(rescale), "{what}: info.rescale");
            assert_eq!(
                opened.volume.sample_type(),
                result,
                "{what}: type after rescaling"
            );
            let got = all_f32(&opened.volume);
            for (i, (&g, &e)) in got.iter().zip(&expected).enumerate() {
                assert!(
                    (g - e).abs() <= 1e-6 * e.abs().max(1.0),
                    "{what}: voxel {i} is {g}, expected {e}"
                );
            }
            let scene = Scene::new(opened.volume);
            let (lo, hi) = min_max(&expected);
            let (rlo, rhi) = scene.value_range();
            assert!(
                (rlo - lo).abs() <= 1e-6 * lo.abs().max(1.0)
                    && (rhi - hi).abs() <= 1e-6 * hi.abs().max(1.0),
                "{what}: value range ({rlo}, {rhi}), expected ({lo}, {hi})"
            );
        }
    }
    // Slope 1 and intercept 0 (and slope 0, "not set") are no rescale.
    for (slope, inter) in [(1.0, 0.0), (0.0, 0.0), (0.0, 5.0)] {
        let stored = small_range(SampleType::I16, SYN_DIMS, SYN_SPACING);
        let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
        h.slope = slope;
        h.inter = inter;
        let p = dir.file("identity.nii", &h.file(&le_bytes(&stored)));
        let opened = open(&p);
        assert_eq!(opened.info.rescale, None, "slope {slope} intercept {inter}");
        assert_same_volume("identity rescale", &opened.volume, &stored);
    }
}

#[test]
fn big_endian_nifti_opens_with_the_same_values() {
    let dir = TempDir::new("nifti-be");
    for (i, ty) in ALL_TYPES.into_iter().enumerate() {
        let want = synthetic(ty, SYN_DIMS, SYN_SPACING, 40 + i as u64);
        let be = samples::encode_volume(&want, AxisOrder::XFast, Endian::Big);
        let h = NiiHeader::new(SYN_DIMS, SYN_SPACING, ty, Endian::Big);
        let file = h.file(&be);
        let p = dir.file(&format!("{ty}-be.nii"), &file);
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Nifti);
        let opened = open(&p);
        check_opened(
            &format!("{ty} big-endian .nii"),
            &opened,
            &want,
            FileFormat::Nifti,
            ty,
        );
        if ty.size() > 1 {
            assert_eq!(opened.info.byte_order, Some(Endian::Big), "{ty}");
        }
        let p = dir.file(&format!("{ty}-be.nii.gz"), &gzip(&dir, &file));
        let opened = open(&p);
        check_opened(
            &format!("{ty} big-endian .nii.gz"),
            &opened,
            &want,
            FileFormat::Nifti,
            ty,
        );
        assert_eq!(opened.info.encoding, "gzip");
    }

    // Big-endian rescale fields: the same values as the project's writer's
    // little-endian file.
    let stored = small_range(SampleType::I16, SYN_DIMS, SYN_SPACING);
    let rescale = Rescale {
        slope: 2.0,
        intercept: -3.0,
    };
    let le_path = dir.join("rescaled-le.nii");
    nifti::write(
        &le_path,
        SYN_DIMS,
        SYN_SPACING,
        SampleType::I16,
        Some(rescale),
        samples::bytes(&le_bytes(&stored)),
    )
    .unwrap();
    let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Big);
    h.slope = 2.0;
    h.inter = -3.0;
    let be_path = dir.file(
        "rescaled-be.nii",
        &h.file(&samples::encode_volume(
            &stored,
            AxisOrder::XFast,
            Endian::Big,
        )),
    );
    let (a, b) = (open(&le_path), open(&be_path));
    assert_eq!(b.info.rescale, Some(rescale));
    assert_same_volume("big-endian rescaled", &b.volume, &a.volume);
}

#[test]
fn nifti_4d_opens_the_first_volume() {
    let dir = TempDir::new("nifti-4d");
    let vols: Vec<AnyVolume> = (0..3)
        .map(|k| synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 60 + k))
        .collect();
    let data: Vec<u8> = vols.iter().flat_map(le_bytes).collect();
    let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
    h.dim[0] = 4;
    h.dim[4] = 3;
    h.pixdim[4] = 2.5; // repetition time
    let file = h.file(&data);
    for (name, bytes) in [("4d.nii", file.clone()), ("4d.nii.gz", gzip(&dir, &file))] {
        let p = dir.file(name, &bytes);
        let opened = open(&p);
        check_opened(name, &opened, &vols[0], FileFormat::Nifti, SampleType::I16);
        assert!(
            has_note(&opened, &["3 volumes", "opened volume 0"]),
            "{name}: notes {:?}",
            opened.info.notes
        );
        assert_eq!(opened.info.volumes, 3);
        // Every volume, raw and through gzip, by its index.
        for (k, want) in vols.iter().enumerate() {
            let options = raycaster::format::OpenOptions {
                volume: k as u64,
                ..Default::default()
            };
            let v = raycaster::format::open_file(&p, &options).expect("volume k");
            check_opened(name, &v, want, FileFormat::Nifti, SampleType::I16);
        }
        let options = raycaster::format::OpenOptions {
            volume: 3,
            ..Default::default()
        };
        let e = raycaster::format::open_file(&p, &options).unwrap_err();
        assert!(e.to_string().contains("the file holds 3"), "{e}");
    }
    // dim[0] = 3 ignores dim[4..]: one volume, no note.
    let mut h3 = h.clone();
    h3.dim[0] = 3;
    let p = dir.file("3d-with-dim4.nii", &h3.file(&data));
    let opened = open(&p);
    assert_same_volume("dim[0] = 3", &opened.volume, &vols[0]);
    assert!(
        opened.info.notes.is_empty(),
        "notes {:?}",
        opened.info.notes
    );
    // Non-finite or zero pixdim: spacing 1 there, with a note.
    let mut hn = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
    hn.pixdim[2] = f32::NAN;
    hn.pixdim[3] = 0.0;
    let p = dir.file("nan-pixdim.nii", &hn.file(&le_bytes(&vols[0])));
    let opened = open(&p);
    assert_eq!(opened.info.spacing, Vec3::new(0.5, 1.0, 1.0));
    assert!(
        !opened.info.notes.is_empty(),
        "a note on the replaced spacing"
    );
}

/// A two-file NIfTI (`ni1` magic): the `.hdr` names its `.img`, which is
/// read raw or, as `.img.gz`, decoded, whatever the header file is; the
/// file size counts both files.
#[test]
fn nifti_header_and_image_pairs_open() {
    let dir = TempDir::new("nifti-pair");
    let want = synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 70);
    let data = le_bytes(&want);
    let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
    h.magic = *b"ni1\0";
    h.vox_offset = 0.0;
    let header = h.bytes();
    for (stem, image, bytes, encoding) in [
        ("plain", "plain.img", data.clone(), "raw"),
        ("packed", "packed.img.gz", gzip(&dir, &data), "gzip"),
    ] {
        let hdr = dir.file(&format!("{stem}.hdr"), &header);
        dir.file(image, &bytes);
        assert_eq!(fmt::detect(&hdr).unwrap(), FileFormat::Nifti);
        let opened = open(&hdr);
        check_opened(stem, &opened, &want, FileFormat::Nifti, SampleType::I16);
        assert_eq!(opened.info.encoding, encoding, "{stem}");
        assert_eq!(
            opened.info.file_bytes,
            (header.len() + bytes.len()) as u64,
            "{stem}"
        );
    }
    // Without its image file, the error names the missing file.
    let lone = dir.file("lone.hdr", &header);
    let e = fmt::open_file(&lone, &Default::default()).unwrap_err();
    assert!(e.to_string().contains("lone.img is missing"), "{e}");
}

//! Real CT volumes fetched by `volumes/fetch_ct_examples.sh` (not in the
//! repository): what they hold, read through NIfTI with a rescale, raw
//! int16 and a DICOM series with a rescale intercept, and that the CT
//! presets show bone. Ignored by default; run with
//! `volumes/fetch_ct_examples.sh && cargo test --test ct_examples -- --ignored`.

use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};
use raycaster::format::{Endian, FileFormat, OpenOptions, RawOptions, open_file};
use raycaster::prelude::*;

/// `volumes/ct/NAME`, or `None` (the test is skipped) after saying how to
/// fetch it when it is not there.
fn example(name: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("volumes/ct")
        .join(name);
    if path.exists() {
        return Some(path);
    }
    // Written to the stderr handle, not with `eprintln!`, which the test
    // harness captures: the note shows without `--nocapture`.
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED: {} is missing; run volumes/fetch_ct_examples.sh to fetch the CT examples",
        path.display()
    );
    None
}

/// Fraction of pixels that are not background in a framing view with `preset`.
fn coverage(scene: &Scene, preset: &str) -> f64 {
    let t = scene.volume().sample_type();
    let tf = TransferFunction::preset_for_data(preset, t, scene.value_range()).unwrap();
    let camera = Camera::framing(&scene.grid().bounds(), 96, 96, 45.0);
    let frame = SerialRenderer::new()
        .render(scene, &camera, &tf, &RenderOptions::default())
        .unwrap();
    let lit = (0..96)
        .flat_map(|y| (0..96).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.pixel(x, y) != [0, 0, 0])
        .count();
    lit as f64 / (96.0 * 96.0)
}

#[test]
#[ignore = "needs volumes/fetch_ct_examples.sh"]
fn chest_ct_nifti_is_in_hounsfield_units() {
    let Some(path) = example("chest_ct.nii.gz") else {
        return;
    };
    let o = open_file(&path, &OpenOptions::default()).unwrap();
    assert_eq!(o.info.format, FileFormat::Nifti);
    assert_eq!(o.info.dims, UVec3::new(512, 512, 133));
    assert!(
        (o.info.spacing - Vec3::new(0.703125, 0.703125, 2.5))
            .abs()
            .max_element()
            < 1e-6
    );
    let r = o.info.rescale.expect("the file has scl_inter -1024");
    assert_eq!((r.slope, r.intercept), (1.0, -1024.0));
    assert_eq!(o.volume.sample_type(), SampleType::I16);
    let scene = Scene::new(o.volume);
    assert_eq!(scene.value_range(), (-2048.0, 3071.0));
    let c = coverage(&scene, "ct-bone");
    assert!((0.08..0.6).contains(&c), "ct-bone coverage {c}");
}

#[test]
#[ignore = "needs volumes/fetch_ct_examples.sh"]
fn head_ct_raw_int16() {
    let Some(path) = example("head_ct_i16le.raw") else {
        return;
    };
    let mut raw = RawOptions::new(UVec3::new(256, 256, 108), SampleType::I16, Endian::Little);
    raw.spacing = Vec3::new(0.957, 0.957, 1.5);
    let options = OpenOptions {
        raw: Some(raw),
        ..OpenOptions::default()
    };
    let o = open_file(&path, &options).unwrap();
    assert_eq!(o.info.format, FileFormat::Raw);
    let scene = Scene::new(o.volume);
    assert_eq!(scene.value_range(), (-1024.0, 2986.0));
    let c = coverage(&scene, "ct-bone");
    assert!((0.1..0.7).contains(&c), "ct-bone coverage {c}");
}

#[test]
#[ignore = "needs volumes/fetch_ct_examples.sh"]
fn catphan_dicom_series_applies_the_rescale_intercept() {
    let Some(path) = example("catphan") else {
        return;
    };
    let o = open_file(&path, &OpenOptions::default()).unwrap();
    assert_eq!(o.info.format, FileFormat::Dicom);
    assert_eq!(o.info.dims, UVec3::new(512, 512, 64));
    assert_eq!(o.info.stored_type, SampleType::U16);
    assert_eq!(o.info.modality.as_deref(), Some("CT"));
    let r = o.info.rescale.expect("intercept -1000");
    assert_eq!((r.slope, r.intercept), (1.0, -1000.0));
    // Whole-number rescale that fits: held as i16 Hounsfield units.
    assert_eq!(o.volume.sample_type(), SampleType::I16);
    assert_eq!(Scene::new(o.volume).value_range(), (-1000.0, 1810.0));
}

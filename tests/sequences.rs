//! Time series end to end: the real 4-D fMRI NIfTI and a longer sequence
//! written here, opened as sequences, packed into `.vseq` with every codec
//! and read back frame by frame; rendering frame K from the packed file
//! gives the image of frame K from its source (SPEC §8, "Time series").

mod common;

use std::path::Path;

use common::TempDir;
use glam::{UVec3, Vec3};
use raycaster::format::vseq::{Codec, PackOptions, pack};
use raycaster::format::{OpenOptions, samples};
use raycaster::prelude::*;
use raycaster::sequence::Sequence;

const FMRI: &str = "/work/shared/data/fmri_example4d/example4d.nii.gz";

fn values(v: &AnyVolume) -> Vec<f32> {
    let d = v.grid().dims;
    let mut out = Vec::with_capacity((d.x * d.y * d.z) as usize);
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                out.push(v.value(UVec3::new(x, y, z)));
            }
        }
    }
    out
}

fn render(volume: AnyVolume) -> Frame {
    let scene = Scene::new(volume);
    let camera = Camera::framing(&scene.grid().bounds(), 48, 40, 45.0);
    let (lo, hi) = scene.value_range();
    let tf = TransferFunction::preset_for_data("ramp", scene.volume().sample_type(), (lo, hi))
        .expect("ramp preset");
    SerialRenderer::new()
        .render(&scene, &camera, &tf, &RenderOptions::default())
        .expect("render")
}

/// Every codec, with and without difference frames, gives back every frame
/// of `source` exactly; rendering frame `k` of the packed file gives the
/// source's image.
fn packs_losslessly(dir: &TempDir, source: &Sequence, render_frame: u32) {
    for codec in [Codec::None, Codec::Lz4, Codec::Zstd] {
        for key_interval in [1, 3] {
            let out = dir.join(&format!("seq-{codec}-{key_interval}.vseq"));
            let options = PackOptions {
                codec,
                key_interval,
                ..PackOptions::default()
            };
            let report =
                pack(&out, source.frames(), |k| source.frame(k), &options, None).expect("pack");
            assert_eq!(report.frames, source.frames());
            let packed = Sequence::open(&out, &OpenOptions::default()).expect("open packed");
            assert_eq!(packed.frames(), source.frames());
            assert_eq!(packed.sample_type(), source.sample_type());
            for k in 0..source.frames() {
                let (a, b) = (source.frame(k).unwrap(), packed.frame(k).unwrap());
                assert_eq!(a.grid().dims, b.grid().dims);
                assert_eq!(a.grid().spacing, b.grid().spacing);
                assert!(
                    values(&a) == values(&b),
                    "{codec} K={key_interval} frame {k}"
                );
            }
            let a = render(source.frame(render_frame).unwrap());
            let b = render(packed.frame(render_frame).unwrap());
            assert!(a.rgb == b.rgb, "{codec}: frame {render_frame} image");
        }
    }
}

#[test]
fn the_fmri_file_is_a_sequence_of_its_two_volumes() {
    if !Path::new(FMRI).exists() {
        eprintln!("skipped: {FMRI} is not on this machine");
        return;
    }
    let seq = Sequence::open(FMRI.as_ref(), &OpenOptions::default()).unwrap();
    assert_eq!(seq.frames(), 2);
    assert_eq!(seq.info().dims, UVec3::new(128, 96, 24));
    let (a, b) = (
        values(&seq.frame(0).unwrap()),
        values(&seq.frame(1).unwrap()),
    );
    // Two time points of one brain: close, not equal.
    assert_ne!(a, b);
    let mean_diff = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32;
    let mean = a.iter().sum::<f32>() / a.len() as f32;
    assert!(mean_diff < 0.1 * mean, "{mean_diff} vs {mean}");
    // Volume 1 through the reader equals frame 1 of the sequence.
    let opened = raycaster::format::open_file(
        FMRI.as_ref(),
        &OpenOptions {
            volume: 1,
            ..OpenOptions::default()
        },
    )
    .unwrap();
    assert_eq!(opened.info.volumes, 2);
    assert_eq!(values(&opened.volume), b);
    let dir = TempDir::new("seq-fmri");
    packs_losslessly(&dir, &seq, 1);
}

/// A 12-frame f32 sequence of a blob drifting through a 20×18×16 grid,
/// written as one 4-D NIfTI.
fn drifting_blob(dir: &TempDir) -> std::path::PathBuf {
    let dims = UVec3::new(20, 18, 16);
    let frames = 12;
    let mut data = Vec::new();
    for k in 0..frames {
        let c = Vec3::new(5.0 + k as f32, 9.0, 8.0 - 0.3 * k as f32);
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let d = (Vec3::new(x as f32, y as f32, z as f32) - c).length();
                    let v = 0.99 + 0.5 * (-d * d / 18.0).exp();
                    data.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
    let path = dir.join("blob.nii");
    raycaster::format::nifti::write(
        &path,
        dims,
        Vec3::new(1.0, 1.0, 1.5),
        SampleType::F32,
        None,
        samples::bytes(&data),
    )
    .unwrap();
    // The writer writes 3-D files: make it 4-D (dim[0] = 4, dim[4] = 12).
    let mut b = std::fs::read(&path).unwrap();
    b[40..42].copy_from_slice(&4i16.to_le_bytes());
    b[48..50].copy_from_slice(&(frames as i16).to_le_bytes());
    std::fs::write(&path, b).unwrap();
    path
}

#[test]
fn a_longer_sequence_packs_losslessly_and_within_f16_precision() {
    let dir = TempDir::new("seq-blob");
    let path = drifting_blob(&dir);
    let seq = Sequence::open(&path, &OpenOptions::default()).unwrap();
    assert_eq!(seq.frames(), 12);
    packs_losslessly(&dir, &seq, 7);

    // Half floats: every sample within f16's spacing near its value
    // (9.8e-4 at 1.0, 2^-11 relative), and half the size or less.
    let out = dir.join("blob16.vseq");
    let options = PackOptions {
        codec: Codec::Zstd,
        f16: true,
        key_interval: 4,
        ..PackOptions::default()
    };
    let report = pack(&out, 12, |k| seq.frame(k), &options, None).unwrap();
    assert!(report.percent() < 50.0, "{}", report.percent());
    let packed = Sequence::open(&out, &OpenOptions::default()).unwrap();
    for k in 0..12 {
        let (a, b) = (
            values(&seq.frame(k).unwrap()),
            values(&packed.frame(k).unwrap()),
        );
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs() / x.abs())
            .fold(0.0f32, f32::max);
        assert!(worst <= 1.0 / 2048.0, "frame {k}: {worst}");
        assert!(worst > 0.0, "f16 must round something");
    }
}

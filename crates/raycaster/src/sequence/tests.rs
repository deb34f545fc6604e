use std::sync::Arc;

use glam::{UVec3, Vec3};

use super::*;
use crate::format::vseq::{Codec, PackOptions, pack};
use crate::scene::SceneOptions;

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rc-seq-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const DIMS: UVec3 = UVec3::new(5, 4, 3);

/// Sample `i` (x fastest) of frame `k`.
fn value(k: u32, i: usize) -> f32 {
    (k * 1000) as f32 + i as f32 * 0.5
}

fn frame_bytes(k: u32) -> Vec<u8> {
    let n = (DIMS.x * DIMS.y * DIMS.z) as usize;
    (0..n).flat_map(|i| value(k, i).to_le_bytes()).collect()
}

fn values(v: &AnyVolume) -> Vec<f32> {
    v.all_values()
}

fn expected(k: u32) -> Vec<f32> {
    (0..(DIMS.x * DIMS.y * DIMS.z) as usize)
        .map(|i| value(k, i))
        .collect()
}

/// A 4-D NIfTI of `n` frames: the writer's 3-D file with dim[0] = 4 and
/// dim[4] = n patched in.
fn nifti_4d(path: &Path, n: u32) {
    let data: Vec<u8> = (0..n).flat_map(frame_bytes).collect();
    crate::format::nifti::write(
        path,
        DIMS,
        Vec3::ONE,
        crate::sample::SampleType::F32,
        None,
        crate::format::samples::bytes(&data),
    )
    .unwrap();
    let mut b = std::fs::read(path).unwrap();
    b[40..42].copy_from_slice(&4i16.to_le_bytes());
    b[48..50].copy_from_slice(&(n as i16).to_le_bytes());
    std::fs::write(path, b).unwrap();
}

fn nrrd_4d(path: &Path, n: u32, gzip: bool) {
    let data: Vec<u8> = (0..n).flat_map(frame_bytes).collect();
    let mut out = format!(
        "NRRD0004\ntype: float\ndimension: 4\nsizes: {} {} {} {n}\nencoding: {}\nendian: little\n\n",
        DIMS.x,
        DIMS.y,
        DIMS.z,
        if gzip { "gzip" } else { "raw" }
    )
    .into_bytes();
    if gzip {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(&data).unwrap();
        out.extend(e.finish().unwrap());
    } else {
        out.extend(data);
    }
    std::fs::write(path, out).unwrap();
}

fn check_frames(seq: &Sequence, n: u32) {
    assert_eq!(seq.frames(), n);
    // Out of order, twice each: every frame is what was written.
    for k in (0..n).rev().chain(0..n) {
        assert_eq!(values(&seq.frame(k).unwrap()), expected(k), "frame {k}");
    }
    let e = seq.frame(n).unwrap_err().to_string();
    assert!(e.contains(&format!("the sequence has {n}")), "{e}");
}

#[test]
fn four_d_files_open_as_every_volume() {
    let dir = temp("4d");
    let nii = dir.join("a.nii");
    nifti_4d(&nii, 4);
    check_frames(&Sequence::open(&nii, &OpenOptions::default()).unwrap(), 4);
    let nrrd = dir.join("a.nrrd");
    nrrd_4d(&nrrd, 3, false);
    check_frames(&Sequence::open(&nrrd, &OpenOptions::default()).unwrap(), 3);
    if cfg!(feature = "gzip") {
        let gz = dir.join("b.nrrd");
        nrrd_4d(&gz, 3, true);
        check_frames(&Sequence::open(&gz, &OpenOptions::default()).unwrap(), 3);
    }
    // In RAM as well as mapped.
    let ram = OpenOptions {
        mode: crate::storage::LoadMode::Ram,
        ..OpenOptions::default()
    };
    check_frames(&Sequence::open(&nii, &ram).unwrap(), 4);
    // A 3-D file is a sequence of one frame.
    let one = dir.join("one.nrrd");
    nrrd_4d(&one, 1, false);
    check_frames(&Sequence::open(&one, &OpenOptions::default()).unwrap(), 1);
}

#[test]
fn a_directory_of_frames_opens_in_name_order_and_names_an_odd_file() {
    let dir = temp("dir");
    // Written out of order, and in two formats; a stray file is ignored.
    for k in [2u32, 0, 1] {
        let name = dir.join(format!("f{k:03}.{}", if k == 1 { "nii" } else { "nrrd" }));
        let data = frame_bytes(k);
        if k == 1 {
            crate::format::nifti::write(
                &name,
                DIMS,
                Vec3::ONE,
                crate::sample::SampleType::F32,
                None,
                crate::format::samples::bytes(&data),
            )
            .unwrap();
        } else {
            crate::format::nrrd::write(
                &name,
                DIMS,
                Vec3::ONE,
                crate::sample::SampleType::F32,
                crate::format::nrrd::Encoding::Raw,
                crate::format::samples::bytes(&data),
            )
            .unwrap();
        }
    }
    std::fs::write(dir.join("notes.txt"), "not a frame").unwrap();
    let seq = Sequence::open(&dir, &OpenOptions::default()).unwrap();
    check_frames(&seq, 3);
    assert!(
        seq.frame_name(1).ends_with("f001.nii"),
        "{}",
        seq.frame_name(1)
    );
    seq.check_all(None).unwrap();

    // A frame of other dimensions: its file is named.
    let odd = dir.join("f003.nrrd");
    crate::format::nrrd::write(
        &odd,
        UVec3::new(5, 4, 2),
        Vec3::ONE,
        crate::sample::SampleType::F32,
        crate::format::nrrd::Encoding::Raw,
        crate::format::samples::bytes(&frame_bytes(0)[..5 * 4 * 2 * 4]),
    )
    .unwrap();
    let seq = Sequence::open(&dir, &OpenOptions::default()).unwrap();
    assert_eq!(seq.frames(), 4);
    let e = seq.check_all(None).unwrap_err().to_string();
    assert!(e.starts_with(&odd.display().to_string()), "{e}");
    assert!(e.contains("frame 3 is 5x4x2 f32"), "{e}");
}

#[test]
fn a_licence_is_not_a_frame_and_a_folder_with_one_scan_is_that_scan() {
    let write_nrrd = |path: &Path, k: u32| {
        crate::format::nrrd::write(
            path,
            DIMS,
            Vec3::ONE,
            crate::sample::SampleType::F32,
            crate::format::nrrd::Encoding::Raw,
            crate::format::samples::bytes(&frame_bytes(k)),
        )
        .unwrap();
    };
    // Files without an extension or a known header, named to sort first.
    let extras = |dir: &Path| {
        std::fs::write(dir.join("LICENSE"), "Permission is hereby granted").unwrap();
        std::fs::write(dir.join("README"), "a scan").unwrap();
    };

    // One 4-D scan beside its licence: the folder is the file, all its
    // volumes the frames.
    let dir = temp("one-4d");
    extras(&dir);
    let scan = dir.join("scan.nii");
    nifti_4d(&scan, 3);
    assert_eq!(resolve_dir(&dir), scan.as_path());
    assert!(frame_files(&dir).is_empty());
    check_frames(&Sequence::open(&dir, &OpenOptions::default()).unwrap(), 3);

    // One 3-D scan: a sequence of one frame, and `resolve_dir` names it.
    let dir = temp("one-3d");
    extras(&dir);
    let scan = dir.join("scan.nrrd");
    write_nrrd(&scan, 0);
    assert_eq!(resolve_dir(&dir), scan.as_path());
    let seq = Sequence::open(&dir, &OpenOptions::default()).unwrap();
    check_frames(&seq, 1);
    // The library's other ways in take the folder too.
    let opened = crate::format::open_file(&dir, &OpenOptions::default()).unwrap();
    assert_eq!(values(&opened.volume), expected(0));
    let scene = crate::scene::Scene::open(&dir, &OpenOptions::default(), &SceneOptions::default());
    assert_eq!(scene.unwrap().scene.grid().dims, DIMS);

    // Two frames and the licence: two frames, in name order.
    let dir = temp("two");
    extras(&dir);
    write_nrrd(&dir.join("f1.nrrd"), 1);
    write_nrrd(&dir.join("f0.nrrd"), 0);
    assert_eq!(
        frame_files(&dir),
        [dir.join("f0.nrrd"), dir.join("f1.nrrd")]
    );
    assert_eq!(resolve_dir(&dir), dir.as_path());
    check_frames(&Sequence::open(&dir, &OpenOptions::default()).unwrap(), 2);

    // A file that is not a folder is itself.
    assert_eq!(resolve_dir(&scan), scan.as_path());
    for name in ["one-4d", "one-3d", "two"] {
        let _ = std::fs::remove_dir_all(temp(name));
    }
}

#[test]
fn a_packed_sequence_plays_the_same_frames_as_its_source() {
    let dir = temp("packed");
    let nii = dir.join("a.nii");
    nifti_4d(&nii, 6);
    let seq = Sequence::open(&nii, &OpenOptions::default()).unwrap();
    let out = dir.join("a.vseq");
    let options = PackOptions {
        codec: Codec::Lz4,
        key_interval: 3,
        ..PackOptions::default()
    };
    pack(&out, seq.frames(), |k| seq.frame(k), &options, None).unwrap();
    let packed = Sequence::open(&out, &OpenOptions::default()).unwrap();
    assert!(packed.packed().is_some());
    check_frames(&packed, 6);

    // Playback hands out the same frames, ahead of the player, in any order.
    let playback = Playback::new(Arc::new(packed), 3, true, SceneOptions::default()).unwrap();
    for k in [0, 1, 2, 5, 0, 4, 4, 3] {
        let f = playback.get(k).unwrap();
        assert_eq!(f.index, k);
        assert_eq!(values(f.scene.volume()), expected(k), "frame {k}");
    }
    // The window after frame 3 (3, 4, 5) fills without being asked.
    for _ in 0..200 {
        if playback.ready() == [3, 4, 5] {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert_eq!(playback.ready(), [3, 4, 5]);
    // Looping wraps the window: after 5 come 0 and 1.
    playback.get(5).unwrap();
    for _ in 0..200 {
        if playback.ready() == [0, 1, 5] {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert_eq!(playback.ready(), [0, 1, 5]);
    let e = playback.get(6).unwrap_err().to_string();
    assert!(e.contains("the sequence has 6"), "{e}");
}

#[test]
fn playback_reports_a_bad_frame_once_and_goes_on() {
    let dir = temp("badframe");
    let nii = dir.join("a.nii");
    nifti_4d(&nii, 3);
    let seq = Sequence::open(&nii, &OpenOptions::default()).unwrap();
    let out = dir.join("a.vseq");
    pack(&out, 3, |k| seq.frame(k), &PackOptions::default(), None).unwrap();
    // Corrupt frame 1's bytes.
    let file = crate::format::vseq::VseqFile::open(&out).unwrap();
    let e = file.index()[1];
    drop(file);
    let mut b = std::fs::read(&out).unwrap();
    b[(e.offset + e.len - 1) as usize] ^= 0xff;
    std::fs::write(&out, b).unwrap();
    let packed = Arc::new(Sequence::open(&out, &OpenOptions::default()).unwrap());
    let playback = Playback::new(packed, 2, false, SceneOptions::default()).unwrap();
    assert!(playback.get(0).is_ok());
    let e = playback.get(1).unwrap_err().to_string();
    assert!(e.contains("frame 1: checksum mismatch"), "{e}");
    assert!(playback.get(2).is_ok());
}

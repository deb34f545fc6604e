use super::*;
use crate::sample::SampleType;

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rc-vseq-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Frame `k` of a smooth field that drifts with time, as type `S`.
fn field<S: Sample>(k: u32, dims: UVec3, to: impl Fn(f32) -> S) -> AnyVolume {
    AnyVolume::from_fn(Grid::new(dims, Vec3::new(1.0, 0.5, 2.0)), |v| {
        let p = v.as_vec3() * 0.21 + Vec3::splat(k as f32 * 0.13);
        to(0.5 + 0.25 * (p.x.sin() + (p.y * 1.3).cos() * p.z.sin()))
    })
}

fn frames_of(ty: SampleType, n: u32, dims: UVec3) -> Vec<AnyVolume> {
    (0..n)
        .map(|k| match ty {
            SampleType::U8 => field(k, dims, |x| (x * 255.0) as u8),
            SampleType::I8 => field(k, dims, |x| (x * 200.0 - 100.0) as i8),
            SampleType::U16 => field(k, dims, |x| (x * 60000.0) as u16),
            SampleType::I16 => field(k, dims, |x| (x * 4000.0 - 2000.0) as i16),
            SampleType::F32 => field(k, dims, |x| 0.99 + x * 0.5),
        })
        .collect()
}

fn values(v: &AnyVolume) -> Vec<f32> {
    v.all_values()
}

fn write(path: &Path, frames: &[AnyVolume], options: &PackOptions) -> PackReport {
    pack(
        path,
        frames.len() as u32,
        |k| Ok(copy(&frames[k as usize])),
        options,
        None,
    )
    .unwrap()
}

#[test]
fn every_codec_and_type_round_trips_frame_by_frame() {
    let dims = UVec3::new(13, 7, 5);
    for ty in [
        SampleType::U8,
        SampleType::I8,
        SampleType::U16,
        SampleType::I16,
        SampleType::F32,
    ] {
        let frames = frames_of(ty, 5, dims);
        for codec in [Codec::None, Codec::Lz4, Codec::Zstd] {
            for (key_interval, shuffle, delta) in [
                (1, true, true),
                (3, true, false),
                (2, false, true),
                (1, false, false),
            ] {
                let path = temp(&format!("rt-{ty}-{codec}-{key_interval}-{delta}.vseq"));
                let options = PackOptions {
                    codec,
                    key_interval,
                    shuffle,
                    delta,
                    // Several chunks per frame, the last one short.
                    chunk_bytes: 97 * ty.size(),
                    ..PackOptions::default()
                };
                let report = write(&path, &frames, &options);
                assert_eq!(report.frames, 5);
                let file = VseqFile::open(&path).unwrap();
                assert_eq!(file.frames(), 5);
                assert_eq!(file.header().sample, ty);
                assert_eq!(file.grid(), *frames[0].grid());
                for (k, f) in frames.iter().enumerate() {
                    let got = file.frame(k as u32).unwrap();
                    assert_eq!(got.sample_type(), ty);
                    let want = values(f);
                    assert_eq!(
                        values(&got),
                        want,
                        "{ty} {codec} K={key_interval} frame {k}"
                    );
                    let e = file.index()[k];
                    let lo = want.iter().cloned().fold(f32::MAX, f32::min);
                    let hi = want.iter().cloned().fold(f32::MIN, f32::max);
                    assert_eq!((e.min, e.max), (lo, hi));
                }
                std::fs::remove_file(&path).unwrap();
            }
        }
    }
}

#[test]
fn half_floats_keep_three_digits_and_halve_the_size() {
    let dims = UVec3::new(24, 20, 16);
    let frames = frames_of(SampleType::F32, 3, dims);
    let path = temp("f16.vseq");
    let options = PackOptions {
        codec: Codec::None,
        f16: true,
        ..PackOptions::default()
    };
    let report = write(&path, &frames, &options);
    // Half the samples' bytes plus the header, table and index.
    assert!(report.percent() < 51.0, "{}", report.percent());
    let file = VseqFile::open(&path).unwrap();
    assert_eq!(file.header().stored, StoredAs::F16);
    for (k, f) in frames.iter().enumerate() {
        let got = values(&file.frame(k as u32).unwrap());
        for (g, w) in got.iter().zip(values(f)) {
            // f16 has an 11-bit significand: relative error ≤ 2^-11.
            assert!((g - w).abs() <= w.abs() * 4.9e-4, "{g} vs {w}");
        }
    }
    // Integer frames cannot be stored as half floats.
    let bytes = frames_of(SampleType::U8, 1, dims);
    let e = pack(
        &path,
        1,
        |_| Ok(copy(&bytes[0])),
        &PackOptions {
            f16: true,
            ..PackOptions::default()
        },
        None,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("half-float storage is for f32"),
        "{e}"
    );
}

#[test]
fn random_access_equals_sequential_access_with_difference_frames() {
    let dims = UVec3::new(16, 9, 11);
    let frames = frames_of(SampleType::F32, 10, dims);
    let path = temp("random.vseq");
    let options = PackOptions {
        codec: Codec::Lz4,
        key_interval: 4,
        ..PackOptions::default()
    };
    write(&path, &frames, &options);
    let file = VseqFile::open(&path).unwrap();
    let kinds: Vec<bool> = file.index().iter().map(|e| e.difference).collect();
    assert_eq!(
        kinds,
        [
            false, true, true, true, false, true, true, true, false, true
        ]
    );
    let mut rng = fastrand::Rng::with_seed(3);
    let sequential: Vec<Vec<f32>> = (0..10).map(|k| values(&file.frame(k).unwrap())).collect();
    for _ in 0..40 {
        let k = rng.u32(0..10);
        assert_eq!(
            values(&file.frame(k).unwrap()),
            sequential[k as usize],
            "{k}"
        );
    }
    // Backwards, each from a fresh file (no frame kept).
    for k in (0..10).rev() {
        let fresh = VseqFile::open(&path).unwrap();
        assert_eq!(
            values(&fresh.frame(k).unwrap()),
            values(&frames[k as usize])
        );
    }
}

#[test]
fn difference_frames_of_a_still_sequence_cost_next_to_nothing() {
    let dims = UVec3::new(32, 32, 32);
    let first = field(0, dims, |x| (x * 1000.0) as u16);
    let still: Vec<AnyVolume> = (0..6).map(|_| copy(&first)).collect();
    let keys = write(
        &temp("keys.vseq"),
        &still,
        &PackOptions {
            codec: Codec::Lz4,
            ..PackOptions::default()
        },
    );
    let diffs = write(
        &temp("diffs.vseq"),
        &still,
        &PackOptions {
            codec: Codec::Lz4,
            key_interval: 6,
            ..PackOptions::default()
        },
    );
    // Five difference frames of zeros cost next to nothing.
    assert!(
        diffs.file_bytes * 3 < keys.file_bytes,
        "{} vs {}",
        diffs.file_bytes,
        keys.file_bytes
    );
}

#[test]
fn frames_that_disagree_are_refused_naming_the_frame() {
    let a = frames_of(SampleType::U8, 1, UVec3::new(4, 4, 4));
    let b = frames_of(SampleType::U8, 1, UVec3::new(4, 4, 5));
    let path = temp("mismatch.vseq");
    let e = pack(
        &path,
        2,
        |k| Ok(copy(if k == 0 { &a[0] } else { &b[0] })),
        &PackOptions::default(),
        None,
    )
    .unwrap_err();
    assert!(e.to_string().contains("frame 1 is 4x4x5"), "{e}");
    assert!(!path.exists(), "no partial file");
}

#[test]
fn corrupt_and_truncated_files_are_errors_naming_the_problem() {
    let frames = frames_of(SampleType::I16, 3, UVec3::new(10, 10, 10));
    let path = temp("good.vseq");
    write(
        &path,
        &frames,
        &PackOptions {
            codec: Codec::Zstd,
            key_interval: 2,
            ..PackOptions::default()
        },
    );
    let good = std::fs::read(&path).unwrap();
    let file = VseqFile::open(&path).unwrap();
    let frame1 = file.index()[1];
    let bad = temp("bad.vseq");
    let open_err = |bytes: &[u8]| {
        std::fs::write(&bad, bytes).unwrap();
        VseqFile::open(&bad).unwrap_err().to_string()
    };
    // Truncated anywhere: the index is not where the header says.
    for cut in [0, 10, 63, 64, 200, good.len() - 1] {
        let e = open_err(&good[..cut]);
        assert!(
            e.contains("shorter than") || e.contains("truncated"),
            "cut {cut}: {e}"
        );
    }
    // A flipped header byte.
    let mut b = good.clone();
    b[20] ^= 1;
    assert!(open_err(&b).contains("header checksum"));
    // A flipped index byte.
    let mut b = good.clone();
    let at = b.len() - 10;
    b[at] ^= 1;
    assert!(open_err(&b).contains("index checksum"));
    // A flipped byte in frame 1: opening works, frame 1 fails naming
    // itself, frame 2 (a key frame) is unharmed.
    let mut b = good.clone();
    b[frame1.offset as usize + frame1.len as usize / 2] ^= 0x40;
    std::fs::write(&bad, &b).unwrap();
    let file = VseqFile::open(&bad).unwrap();
    assert!(file.frame(0).is_ok());
    let e = file.frame(1).unwrap_err().to_string();
    assert!(e.contains("frame 1: checksum mismatch"), "{e}");
    assert!(e.contains("bad.vseq"), "{e}");
    assert!(file.frame(2).is_ok());
    // Out of range.
    let e = file.frame(3).unwrap_err().to_string();
    assert!(e.contains("frame 3: there are 3 frames"), "{e}");
    // Random garbage of every length below the good one never panics.
    let mut rng = fastrand::Rng::with_seed(9);
    for _ in 0..200 {
        let mut b = good.clone();
        for _ in 0..rng.usize(1..4) {
            let i = rng.usize(..b.len());
            b[i] = rng.u8(..);
        }
        std::fs::write(&bad, &b).unwrap();
        if let Ok(f) = VseqFile::open(&bad) {
            for k in 0..3 {
                let _ = f.frame(k);
            }
        }
    }
}

#[test]
fn open_file_reads_the_asked_frame_and_detects_by_content() {
    let frames = frames_of(SampleType::U16, 3, UVec3::new(6, 5, 4));
    // Not named .vseq: the magic claims it.
    let path = temp("sequence.bin");
    write(&path, &frames, &PackOptions::default());
    assert_eq!(crate::format::detect(&path).unwrap(), FileFormat::Vseq);
    for k in 0..3 {
        let opened = crate::format::open_file(
            &path,
            &crate::format::OpenOptions {
                volume: k,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(opened.info.volumes, 3);
        assert_eq!(values(&opened.volume), values(&frames[k as usize]));
    }
    let e = crate::format::open_file(
        &path,
        &crate::format::OpenOptions {
            volume: 3,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("volume 3 asked for, but the file holds 3"),
        "{e}"
    );
}

/// A copy of `v` in RAM (volumes are not `Clone`: they may be mapped files).
fn copy(v: &AnyVolume) -> AnyVolume {
    v.with_layout(v.layout()).unwrap()
}

//! Random and mutated files of every format never panic the readers: what
//! opens is readable throughout, and every error is one line naming the
//! file.

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use common::TempDir;
use common::file_bytes::{NiiHeader, header_end, nrrd_header};
use common::volumes::{SYN_DIMS, SYN_SPACING, le_bytes, synthetic};
use raycaster::format::davis::DavisHeader;
use raycaster::format::nrrd::{self, Encoding};
use raycaster::format::samples;
use raycaster::format::vol::{self, VolLayout};
use raycaster::format::{self as fmt, Endian, OpenOptions, RawOptions, Rescale, nifti};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

/// Valid small files of every format, to mutate: (file name, bytes, raw
/// options, whether the header is text).
fn fuzz_seeds(dir: &TempDir) -> Vec<(&'static str, Vec<u8>, Option<RawOptions>, bool)> {
    let u8v = synthetic(SampleType::U8, SYN_DIMS, SYN_SPACING, 90);
    let i16v = synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 91);
    let f32v = synthetic(SampleType::F32, SYN_DIMS, SYN_SPACING, 92);
    let written = |name: &str, f: &dyn Fn(&Path)| {
        let p = dir.join(name);
        f(&p);
        std::fs::read(&p).unwrap()
    };
    let nrrd_raw = written("seed.nrrd", &|p| {
        nrrd::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::I16,
            Encoding::Raw,
            samples::bytes(&le_bytes(&i16v)),
        )
        .unwrap()
    });
    let nrrd_gz = written("seed-gz.nrrd", &|p| {
        nrrd::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::U8,
            Encoding::Gzip,
            samples::bytes(&le_bytes(&u8v)),
        )
        .unwrap()
    });
    let nii = written("seed.nii", &|p| {
        nifti::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::I16,
            None,
            samples::bytes(&le_bytes(&i16v)),
        )
        .unwrap()
    });
    let mut be = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::F32, Endian::Big);
    be.slope = 2.0;
    let nii_be = be.file(&samples::encode_volume(
        &f32v,
        AxisOrder::XFast,
        Endian::Big,
    ));
    let nii_gz = written("seed.nii.gz", &|p| {
        let r = Rescale {
            slope: 2.0,
            intercept: 1.0,
        };
        nifti::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::F32,
            Some(r),
            samples::bytes(&le_bytes(&f32v)),
        )
        .unwrap()
    });
    let vol_linear = written("seed.vol", &|p| {
        vol::write(p, &u8v, VolLayout::Linear).unwrap()
    });
    let vol_bricked = written("seed-b.vol", &|p| {
        vol::write(p, &u8v, VolLayout::Bricked { side: 4 }).unwrap()
    });
    let mut davis = DavisHeader {
        dims: SYN_DIMS,
        border: 1,
        spacing: SYN_SPACING,
    }
    .to_bytes()
    .to_vec();
    davis.extend(samples::encode_volume(&u8v, AxisOrder::ZFast, Endian::Big));
    // A detached header whose data file sits next to it.
    dir.file("fuzz-data.raw", &le_bytes(&i16v));
    let nhdr = nrrd_header(&[
        ("type", "short"),
        ("dimension", "3"),
        ("sizes", "7 5 9"),
        ("space directions", "(0.5,0,0) (0,1.25,0) (0,0,2)"),
        ("endian", "little"),
        ("encoding", "raw"),
        ("data file", "fuzz-data.raw"),
        ("byte skip", "0"),
    ])
    .into_bytes();
    let raw = RawOptions::new(SYN_DIMS, SampleType::I16, Endian::Big);
    vec![
        ("fuzz.nrrd", nrrd_raw, None, true),
        ("fuzz.nrrd", nrrd_gz, None, true),
        ("fuzz.nhdr", nhdr, None, true),
        ("fuzz.nii", nii, None, false),
        ("fuzz.nii", nii_be, None, false),
        ("fuzz.nii.gz", nii_gz, None, false),
        ("fuzz.vol", vol_linear, None, false),
        ("fuzz.vol", vol_bricked, None, false),
        ("fuzz.vol", davis, None, false),
        ("fuzz.raw", le_bytes(&i16v), Some(raw), false),
    ]
}

/// Values that break naive header parsing.
const TRICKY: &[&str] = &[
    "0",
    "-1",
    "1",
    "2147483648",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e40",
    "-0",
    "",
    " ",
    "(1,0,0)",
    "none",
    "LIST",
    "gzip",
    "big",
    "double",
    "7 5",
    "7 5 9 3",
    "1 7 5 9",
    "0.5 1.25 2",
    "(nan,0,0) (0,1,0) (0,0,1)",
    "..",
    "/",
    "fuzz-data.raw",
];

/// A random mutation of `seed`.
fn mutate(rng: &mut fastrand::Rng, seed: &[u8], text: bool) -> Vec<u8> {
    let mut b = seed.to_vec();
    match rng.u8(0..6) {
        // Random bytes of a random length.
        0 => (0..rng.usize(0..600)).map(|_| rng.u8(..)).collect(),
        // Truncated.
        1 => {
            b.truncate(rng.usize(0..=b.len()));
            b
        }
        // A few random bytes flipped, mostly in the header.
        2 => {
            for _ in 0..rng.usize(1..6) {
                let end = if rng.bool() {
                    b.len().min(360)
                } else {
                    b.len()
                };
                if end > 0 {
                    let i = rng.usize(0..end);
                    b[i] = rng.u8(..);
                }
            }
            b
        }
        // A header field's value replaced by a tricky one (text), or an
        // aligned 2- or 4-byte header word set to an extreme (binary).
        3 | 4 if text => {
            let Some(end) = header_end(&b) else { return b };
            let head = String::from_utf8_lossy(&b[..end]).into_owned();
            let mut lines: Vec<String> = head.lines().map(str::to_string).collect();
            let n = lines.len().saturating_sub(1).max(1);
            let i = 1 + rng.usize(0..n);
            if let Some(line) = lines.get_mut(i)
                && let Some((k, _)) = line.split_once(": ")
            {
                *line = format!("{k}: {}", TRICKY[rng.usize(0..TRICKY.len())]);
            }
            if rng.u8(0..4) == 0 {
                // Sometimes an extra field.
                let keys = [
                    "byte skip",
                    "line skip",
                    "dimension",
                    "sizes",
                    "endian",
                    "data file",
                    "spacings",
                    "encoding",
                ];
                let k = keys[rng.usize(0..keys.len())];
                lines.insert(1, format!("{k}: {}", TRICKY[rng.usize(0..TRICKY.len())]));
            }
            let mut out = lines.join("\n").into_bytes();
            out.extend_from_slice(b"\n\n");
            out.extend_from_slice(&b[end..]);
            out
        }
        3 | 4 => {
            let words: [u32; 8] = [
                0,
                1,
                u32::MAX,
                0x7fff_ffff,
                0x8000_0000,
                0x7fc0_0000, // NaN
                0x7f80_0000, // inf
                0x4f80_0000, // 2^32 as f32
            ];
            let w = words[rng.usize(0..words.len())].to_le_bytes();
            let limit = b.len().min(352);
            if limit >= 4 {
                let i = rng.usize(0..limit / 2) * 2;
                let k = (if rng.bool() { 2 } else { 4 }).min(limit - i);
                let from = if rng.bool() { 0 } else { 4 - k };
                b[i..i + k].copy_from_slice(&w[from..from + k]);
            }
            b
        }
        // Garbage appended.
        _ => {
            b.extend((0..rng.usize(1..64)).map(|_| rng.u8(..)));
            b
        }
    }
}

#[test]
fn random_and_mutated_files_never_panic() {
    let dir = TempDir::new("fuzz");
    let mut rng = fastrand::Rng::with_seed(0x5EED_F11E);
    let mut failures = Vec::new();
    let mut opened = 0;
    let dir_name = dir.0.display().to_string();
    for (name, seed, raw, text) in fuzz_seeds(&dir) {
        // The unmutated seed opens.
        let p = dir.file(name, &seed);
        let options = OpenOptions {
            raw: raw.clone(),
            ..OpenOptions::default()
        };
        if let Err(e) = fmt::open_file(&p, &options) {
            failures.push(format!("seed {name} does not open: {e}"));
        }
        for i in 0..300 {
            let bytes = mutate(&mut rng, &seed, text);
            std::fs::write(&p, &bytes).unwrap();
            let result = catch_unwind(AssertUnwindSafe(|| {
                fmt::open_file(&p, &options).map(|o| {
                    // Whatever opens must be readable throughout.
                    let scene = Scene::new(o.volume);
                    scene.value_range()
                })
            }));
            let show = || {
                let n = bytes.len().min(96);
                format!(
                    "{name} #{i} ({} bytes, first {n}: {:?})",
                    bytes.len(),
                    String::from_utf8_lossy(&bytes[..n])
                )
            };
            match result {
                Err(_) => failures.push(format!("PANIC on {}", show())),
                Ok(Ok(_)) => opened += 1,
                Ok(Err(e)) => {
                    let m = e.to_string();
                    if m.contains('\n') {
                        failures.push(format!("multi-line error on {}: {m}", show()));
                    }
                    // A detached header's errors may name its (mutated) data file.
                    let detached = name.ends_with(".nhdr") && m.contains(dir_name.as_str());
                    if !m.contains(name) && !detached {
                        failures.push(format!("error without the file name on {}: {m}", show()));
                    }
                }
            }
        }
    }
    assert!(
        opened > 0,
        "no mutated file opened at all: the mutations are too harsh"
    );
    assert!(
        failures.is_empty(),
        "{} failure(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}

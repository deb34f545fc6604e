//! libFuzzer target `dicom`: see `Target::Dicom` in `src/harness.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raycaster_fuzz::{Target, run};

fuzz_target!(|data: &[u8]| {
    run(Target::Dicom, data);
});

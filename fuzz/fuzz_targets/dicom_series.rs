//! libFuzzer target `dicom_series`: see `Target::DicomSeries` in `src/harness.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raycaster_fuzz::{Target, run};

fuzz_target!(|data: &[u8]| {
    run(Target::DicomSeries, data);
});

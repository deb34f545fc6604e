//! libFuzzer target `nhdr`: see `Target::Nhdr` in `src/harness.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raycaster_fuzz::{Target, run};

fuzz_target!(|data: &[u8]| {
    run(Target::Nhdr, data);
});

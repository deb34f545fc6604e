//! libFuzzer target `tf_json`: see `Target::TfJson` in `src/harness.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raycaster_fuzz::{Target, run};

fuzz_target!(|data: &[u8]| {
    run(Target::TfJson, data);
});

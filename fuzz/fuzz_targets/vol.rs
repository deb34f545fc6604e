//! libFuzzer target `vol`: see `Target::Vol` in `src/harness.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raycaster_fuzz::{Target, run};

fuzz_target!(|data: &[u8]| {
    run(Target::Vol, data);
});

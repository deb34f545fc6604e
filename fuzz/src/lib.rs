//! The fuzz targets' shared code: [`harness`] (also compiled by the test
//! suite's `tests/fuzz_regressions.rs`).

mod harness;

pub use harness::{Target, run};

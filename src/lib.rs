//! End-to-end tests and benchmarks of the workspace live in `tests/` and `benches/`.

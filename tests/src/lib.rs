//! Shared helpers of Parapet's cross-crate integration tests (`tests/tests/`)
//! and benchmarks: a double-integrator closed loop for the safety invariant,
//! a reference CBF-QP solved with clarabel, and the proptest case count.

pub mod bench_states;
pub mod double_integrator;
pub mod layering;
pub mod pil_support;
pub mod reference_qp;

/// Cases per property: `PARAPET_PROPTEST_CASES` (set to 10000 by `cargo xtask test`), else 256.
pub fn proptest_cases() -> u32 {
    std::env::var("PARAPET_PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
}

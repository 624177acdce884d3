//! The "wild" `f32` strategy of the property tests, written once: the core's unit tests
//! (`outer/waypoint.rs`), `core/tests/properties.rs` and `tests/tests/cbf_properties.rs`
//! include this file by path (`#[path = …] mod wild;`).

use proptest::prelude::*;

/// Any `f32`, heavy on the nasty ones: `weight` parts a finite value in `finite`, one part
/// each NaN, +∞, −∞, ±1e30, 0 and an arbitrary bit pattern.
pub fn wild(weight: u32, finite: core::ops::Range<f32>) -> impl Strategy<Value = f32> {
    prop_oneof![
        weight => finite,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(1e30f32),
        1 => Just(-1e30f32),
        1 => Just(0.0f32),
        1 => any::<f32>(),
    ]
}

//! Fuzz target `replay_csv`: arbitrary text into `parapet_sim::sim::replay::parse_rotor_csv`.
//!
//! Invariants: no panic; accepted samples are non-empty, every number finite, times strictly
//! increasing and rotor speeds >= 0 (the module's documented input format).
#![no_main]

use libfuzzer_sys::fuzz_target;
use parapet_sim::sim::replay::parse_rotor_csv;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(samples) = parse_rotor_csv(text) else { return };
    assert!(!samples.is_empty());
    for (i, (t, w)) in samples.iter().enumerate() {
        assert!(t.is_finite() && w.iter().all(|x| x.is_finite() && *x >= 0.0), "row {i}: {t} {w:?}");
        if i > 0 {
            assert!(*t > samples[i - 1].0, "row {i}: time does not increase");
        }
    }
});

//! Fuzz target `path_json`: arbitrary text into `parapet_sim::plan::pathfile::PathFile::parse`.
//!
//! Invariants: no panic; an accepted path has at least one waypoint, every coordinate finite
//! and a finite, non-negative length.
#![no_main]

use libfuzzer_sys::fuzz_target;
use parapet_sim::plan::pathfile::PathFile;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(path) = PathFile::parse(text, std::path::Path::new("fuzz.json")) else { return };
    assert!(!path.waypoints.is_empty());
    assert!(path.waypoints.iter().flatten().all(|x| x.is_finite()), "{:?}", path.waypoints);
    assert!(path.length_m.is_finite() && path.length_m >= 0.0, "length {}", path.length_m);
});

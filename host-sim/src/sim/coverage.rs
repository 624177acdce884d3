//! Pre-flight coverage check of a range-sensor set (issue 36): what the sensors cannot see of
//! the space the hull sweeps when the vehicle moves horizontally at the mission speed.
//!
//! For a horizontal bearing `β` (body frame, clockwise from the nose) the sensors whose
//! horizontal field contains `β` observe the elevations `[lo(β), hi(β)]` (the union of their
//! vertical fields, taken as its lowest and highest edge) out to the range `R(β)` (the longest of
//! them). The hull (radius `r`) reaches `±r` above and below the centre. An obstacle at height
//! offset `h`, `|h| ≤ r`, ahead on `β` is first seen at distance `|h|/tan(hi)` (above) or
//! `|h|/tan(−lo)` (below), and must be seen no nearer than the stopping distance
//! `d_s = r + v·τ + v²/(2a)` (`a`, `τ`: the braking barrier's `CBF_BRAKE_ACC` and
//! `CBF_BRAKE_DLY` plus the sensor's latency; `v` the mission speed). So `β` is covered when
//!
//! * some sensor sees it: a **bearing gap** otherwise (a forward camera, ToF sensors with gaps);
//! * `R(β) ≥ d_s`: a **range gap** otherwise, with the speed `v*` at which `d_s = R`
//!   (`v* = a·(√(τ² + 2(R − r)/a) − τ)`), the braking-limited ceiling of the sensor;
//! * `hi(β) ≥ atan(r/R)` and `lo(β) ≤ −atan(r/R)`: a **vertical gap** otherwise — obstacles
//!   above or below the observed band within the hull's reach are never seen however far the
//!   sensor reaches (a planar lidar: `lo = hi = 0`, the hanging lamp of the office).
//!
//! The check assumes static obstacles and an obstacle memory that keeps what was seen while the
//! vehicle closes in (`PCP_FORGET`); sensors looking up or down (|pitch| ≥ 45°) do not count for
//! horizontal motion. The result names each gap in words; `parapet run` prints it and
//! `summary.json` keeps it (`coverage_gaps`).
//!
//! **Refusal.** A bearing or vertical gap means part of the hull's sweep is never observed, at
//! any speed: `parapet run` / `pil` refuse such a flight (exit 2) unless an [`Assumption`] about
//! the world (`--assume`, or the scene's `[sensors] assume`) says no obstacle lies there
//! ([`Gap::accepted_by`]). A range gap is not refused: the speed governor (`GOV_ENABLE`) keeps
//! the speed under the ceiling it names (`docs/perception.md` § Coverage check).
//!
//! Work: 360 one-degree bearings × the sensors. Owns [`Gap`], [`GapKind`], [`Assumption`].
//! May import: [`super::range`].

use serde::{Deserialize, Serialize};

use super::range::RangeSensor;

/// Bearings examined, one per degree.
const BEARINGS: usize = 360;

/// The braking used for the stopping distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Braking {
    /// Deceleration `a`, m/s² (`CBF_BRAKE_ACC`).
    pub accel: f64,
    /// Delay `τ` before braking acts, s (`CBF_BRAKE_DLY`; the sensor latency is added).
    pub delay: f64,
}

/// The stopping distance `r + v·τ + v²/(2a)`, m.
pub fn stopping_distance(hull: f64, speed: f64, b: Braking) -> f64 {
    hull + speed * b.delay + speed * speed / (2.0 * b.accel)
}

/// The speed whose stopping distance is `range` (0 when `range ≤ hull`), m/s.
pub fn speed_ceiling(hull: f64, range: f64, b: Braking) -> f64 {
    if range <= hull {
        return 0.0;
    }
    b.accel * ((b.delay * b.delay + 2.0 * (range - hull) / b.accel).sqrt() - b.delay)
}

/// What kind of gap ([`gaps`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GapKind {
    /// No sensor sees any horizontal bearing (all look up or down): refused whatever is assumed.
    Blind,
    /// Horizontal bearings no sensor sees.
    Bearing,
    /// The range is shorter than the stopping distance at the mission speed.
    Range,
    /// Elevations above the observed band within the hull's reach.
    Above,
    /// Elevations below it.
    Below,
}

/// One gap of a sensor set: its kind and the sentence that names it.
#[derive(Clone, Debug, PartialEq)]
pub struct Gap {
    /// What is not seen.
    pub kind: GapKind,
    /// The gap in words (what, where, why it matters).
    pub text: String,
}

/// A world assumption that lets a sensor set with a gap fly (`--assume`, scene `[sensors]
/// assume`); each is a claim about the scene the check cannot verify, off unless given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Assumption {
    /// Nothing hangs into the hull's reach above the sensors' observed band without also
    /// crossing the band (no lamps, shelves or lintels at the flight level): accepts a gap above.
    NoOverhangs,
    /// Nothing stands within the hull's reach below the band without also rising into it (no
    /// low furniture or kerbs topped out under a planar lidar's plane): accepts a gap below.
    NoLowObstacles,
    /// The vehicle only moves towards bearings its sensors see (a forward camera with the yaw
    /// along the path, `--yaw-mode travel`, and no sideways or backward stick): accepts
    /// bearing gaps.
    ForwardFlight,
}

impl Assumption {
    /// Every assumption, in the order the messages list them.
    pub const ALL: [Assumption; 3] =
        [Assumption::NoOverhangs, Assumption::NoLowObstacles, Assumption::ForwardFlight];

    /// The name on the command line and in scene files.
    pub fn as_str(self) -> &'static str {
        match self {
            Assumption::NoOverhangs => "no-overhangs",
            Assumption::NoLowObstacles => "no-low-obstacles",
            Assumption::ForwardFlight => "forward-flight",
        }
    }

    /// The names, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL.map(Assumption::as_str).join(", ")
    }
}

impl std::str::FromStr for Assumption {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|a| a.as_str() == s)
            .ok_or_else(|| format!("unknown assumption {s:?} (allowed: {})", Self::names()))
    }
}

impl Gap {
    /// The assumption that accepts this gap (`None`: a range gap, never refused; the governor
    /// limits the speed to the ceiling it names).
    pub fn accepted_by(&self) -> Option<Assumption> {
        match self.kind {
            GapKind::Bearing => Some(Assumption::ForwardFlight),
            GapKind::Blind | GapKind::Range => None,
            GapKind::Above => Some(Assumption::NoOverhangs),
            GapKind::Below => Some(Assumption::NoLowObstacles),
        }
    }

    /// This gap refuses the flight under `assumed`: a blind set, or a gap whose assumption is
    /// not given.
    pub fn refuses(&self, assumed: &[Assumption]) -> bool {
        self.kind == GapKind::Blind || self.accepted_by().is_some_and(|a| !assumed.contains(&a))
    }
}

/// What `sensors` cannot see of the hull's sweep at `speed` (module docs), one [`Gap`] each;
/// empty when the set covers it.
pub fn gaps(sensors: &[RangeSensor], hull: f64, speed: f64, braking: Braking) -> Vec<Gap> {
    // Per bearing: lowest and highest elevation seen, longest range, largest latency.
    let mut seen: Vec<Option<(f64, f64, f64, f64)>> = vec![None; BEARINGS];
    for s in sensors.iter().filter(|s| s.pitch.abs() < 45.0) {
        let (lo, hi) = (s.pitch + s.elevation - 0.5 * s.fov_v, s.pitch + s.elevation + 0.5 * s.fov_v);
        for (deg, slot) in seen.iter_mut().enumerate() {
            let off = ((deg as f64 - s.yaw) % 360.0 + 540.0) % 360.0 - 180.0;
            if s.fov_h >= 360.0 || off.abs() <= 0.5 * s.fov_h {
                *slot = Some(match *slot {
                    None => (lo, hi, s.max_range, s.latency),
                    Some((l, h, r, t)) => (l.min(lo), h.max(hi), r.max(s.max_range), t.max(s.latency)),
                });
            }
        }
    }
    let mut out = Vec::new();
    let unseen: Vec<usize> = (0..BEARINGS).filter(|&d| seen[d].is_none()).collect();
    if unseen.len() == BEARINGS {
        let text = "no sensor sees any horizontal bearing (each looks up or down, |pitch| ≥ 45°): \
                    the set covers nothing of the hull's sweep"
            .to_string();
        out.push(Gap { kind: GapKind::Blind, text });
        return out;
    }
    if !unseen.is_empty() {
        let text = format!(
            "bearings {} (body, degrees clockwise from the nose) are seen by no sensor: obstacles there \
             are not seen before the vehicle moves that way",
            ranges(&unseen)
        );
        out.push(Gap { kind: GapKind::Bearing, text });
    }
    let covered: Vec<(f64, f64, f64, f64)> = seen.iter().flatten().copied().collect();
    if covered.is_empty() {
        return out;
    }
    let range = covered.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
    let latency = covered.iter().map(|c| c.3).fold(0.0, f64::max);
    let b = Braking { delay: braking.delay + latency, ..braking };
    let d_s = stopping_distance(hull, speed, b);
    if range < d_s {
        let text = format!(
            "range {range} m is shorter than the stopping distance {d_s:.2} m at {speed} m/s \
             (braking {} m/s² after {:.2} s, hull {hull:.2} m): the sensors allow at most {:.2} m/s",
            b.accel,
            b.delay,
            speed_ceiling(hull, range, b)
        );
        out.push(Gap { kind: GapKind::Range, text });
    }
    let need = (hull / range).atan().to_degrees();
    let hi = covered.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    let lo = covered.iter().map(|c| c.0).fold(f64::NEG_INFINITY, f64::max);
    for (kind, side, edge, ok) in
        [(GapKind::Above, "above", hi, hi >= need), (GapKind::Below, "below", lo, lo <= -need)]
    {
        if !ok {
            let text = format!(
                "elevations {side} {edge:+.1}° are seen by no sensor at some bearings, where the hull's \
                 reach ({hull:.2} m) needs {}{need:.1}° at the sensors' {range} m: obstacles {side} the \
                 observed band within the hull's reach are never seen",
                if side == "above" { "+" } else { "−" }
            );
            out.push(Gap { kind, text });
        }
    }
    out
}

/// `[3, 4, 5, 9]` → `"3°–5°, 9°"`.
fn ranges(degs: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < degs.len() {
        let mut j = i;
        while j + 1 < degs.len() && degs[j + 1] == degs[j] + 1 {
            j += 1;
        }
        parts.push(if i == j { format!("{}°", degs[i]) } else { format!("{}°–{}°", degs[i], degs[j]) });
        i = j + 1;
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::range::preset;

    const B: Braking = Braking { accel: 3.0, delay: 0.1 };

    fn gaps_of(name: &str, speed: f64) -> Vec<String> {
        gaps(&preset(name).unwrap(), 0.22, speed, B).into_iter().map(|g| g.text).collect()
    }

    #[test]
    fn a_planar_lidar_misses_above_and_below_its_plane() {
        let g = gaps_of("lidar", 1.0);
        assert_eq!(g.len(), 2, "{g:?}");
        assert!(g[0].contains("above +0.0°") && g[1].contains("below +0.0°"), "{g:?}");
    }

    #[test]
    fn the_3d_lidar_covers_the_sweep_and_the_camera_only_its_front() {
        assert!(gaps_of("lidar3d", 8.0).is_empty(), "{:?}", gaps_of("lidar3d", 8.0));
        let g = gaps_of("camera", 1.0);
        assert_eq!(g.len(), 1, "{g:?}");
        // 87° centred on the nose: 0–43° and 317–359° seen, 44°–316° not.
        assert!(g[0].starts_with("bearings 44°–316° "), "{g:?}");
    }

    #[test]
    fn the_tof_ring_runs_out_of_range_at_speed() {
        assert!(gaps_of("tof8", 2.0).is_empty(), "{:?}", gaps_of("tof8", 2.0));
        let g = gaps_of("tof8", 5.0);
        assert_eq!(g.len(), 1, "{g:?}");
        // v* for 4 m with a = 3, τ = 0.1 + 0.02: 3·(√(0.0144 + 2·3.78/3) − 0.12) = 4.42 m/s.
        assert!(g[0].contains("at most 4.42 m/s"), "{g:?}");
        // Four ToFs leave 45° gaps between their views.
        assert!(
            gaps_of("tof4", 1.0)[0].starts_with("bearings 23°–67°, 113°–157°"),
            "{:?}",
            gaps_of("tof4", 1.0)
        );
    }

    #[test]
    fn the_speed_ceiling_inverts_the_stopping_distance() {
        for v in [0.5, 2.0, 8.0] {
            let d = stopping_distance(0.22, v, B);
            assert!((speed_ceiling(0.22, d, B) - v).abs() < 1e-9);
        }
        assert_eq!(speed_ceiling(0.22, 0.1, B), 0.0);
    }

    #[test]
    fn a_planar_lidar_flies_only_with_both_vertical_assumptions_and_a_camera_with_forward_flight() {
        use Assumption::{ForwardFlight, NoLowObstacles, NoOverhangs};
        let refused = |name: &str, speed: f64, assumed: &[Assumption]| {
            gaps(&preset(name).unwrap(), 0.22, speed, B).iter().filter(|g| g.refuses(assumed)).count()
        };
        assert_eq!(refused("lidar", 1.0, &[]), 2);
        assert_eq!(refused("lidar", 1.0, &[NoOverhangs]), 1);
        assert_eq!(refused("lidar", 1.0, &[NoOverhangs, NoLowObstacles]), 0);
        assert_eq!(refused("camera", 1.0, &[NoOverhangs, NoLowObstacles]), 1);
        assert_eq!(refused("camera", 1.0, &[ForwardFlight]), 0);
        // Range gaps are the governor's: never refused.
        assert_eq!(refused("tof8", 5.0, &[]), 0);
        assert_eq!(refused("lidar3d", 8.0, &[]), 0);
        // A set that only looks up covers nothing: refused whatever is assumed.
        let up: Vec<RangeSensor> =
            preset("tof4").unwrap().into_iter().map(|s| RangeSensor { pitch: 90.0, ..s }).collect();
        let g = gaps(&up, 0.22, 1.0, B);
        assert_eq!(g.len(), 1, "{g:?}");
        assert!(g[0].refuses(&Assumption::ALL) && g[0].text.contains("covers nothing"), "{g:?}");
    }

    #[test]
    fn assumptions_parse_by_name_and_refuse_unknown_ones() {
        for a in Assumption::ALL {
            assert_eq!(a.as_str().parse::<Assumption>(), Ok(a));
        }
        let e = "obstacles-are-nice".parse::<Assumption>().unwrap_err();
        assert!(e.contains("\"obstacles-are-nice\"") && e.contains("no-overhangs, no-low-obstacles"), "{e}");
    }
}

//! Range-sensor models: what a simulated lidar, depth camera or time-of-flight
//! sensor is ([`RangeSensorSpec`], a scene's `[[sensor]]` table or a preset of
//! `parapet run --perception`), its beam pattern in the body frame and its
//! measurement errors (range noise, dropouts, min/max range).
//!
//! **Frames.** The mounting offset is in the vehicle's body frame FRD (x
//! forward, y right, z down, m), the mounting `yaw` (positive to the right)
//! and `pitch` (positive up) in degrees. A beam of azimuth `a` (positive right)
//! and elevation `e` (positive up) in the sensor frame points along
//! `(cos e cos a, cos e sin a, −sin e)` (FRD) before the mounting rotation.
//! The beams form a `columns × rows` grid, evenly spaced in angle over
//! `fov_h × fov_v` degrees (a 360° lidar: `columns` beams at `360/columns`°
//! steps starting straight ahead; otherwise centred on the boresight, the
//! first column the leftmost, the first row the top one). A depth camera is
//! modelled by its pixel rays at a decimated resolution; its value is the
//! range along the ray (not the z-depth).
//!
//! **Measurement.** Every beam sees the exact first hit of its ray (the
//! caller's ray cast) up to `max_range`; then, with the seeded generator of
//! the sensor: with probability `dropout` the beam returns nothing
//! ([`Return::Unknown`]); otherwise Gaussian noise of σ `noise` m is added; a
//! value beyond `max_range` (or no hit) is [`Return::Clear`] (free up to the
//! maximum range), one below `min_range` [`Return::Unknown`] (too close for
//! the sensor).
//!
//! Presets (`--perception lidar|lidar360|lidar3d|camera|tof|tof4|tof8`): see [`preset`].
//!
//! Owns the sensor description and error model. May import: [`crate::input`]
//! (limits, number format), rand, serde, nalgebra.

use nalgebra::{Rotation3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Most beams one sensor may have (`columns × rows`).
pub const MAX_BEAMS: usize = 4096;
/// Most range sensors a vehicle may carry.
pub const MAX_SENSORS: usize = 16;
/// Highest sensor rate, Hz (the outer loop's 250 Hz: a sensor samples at outer steps).
pub const MAX_RATE_HZ: f64 = 250.0;
/// Longest sensor latency, s.
pub const MAX_LATENCY_S: f64 = 1.0;
/// Longest maximum range, m.
pub const MAX_RANGE_M: f64 = 100.0;
/// Largest range noise σ, m.
pub const MAX_NOISE_M: f64 = 1.0;

/// The kinds of range sensor (they differ in their defaults only).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RangeKind {
    /// A planar scanning lidar, 360°.
    Lidar,
    /// A depth camera (pixel rays at a decimated resolution).
    Camera,
    /// A multi-zone time-of-flight sensor (or a single-beam ranger with 1 × 1 zones).
    Tof,
}

/// One range sensor: a `[[sensor]]` table of a scene file (every field but
/// `kind` optional, defaulting to the kind's preset).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeSensorSpec {
    /// Kind (selects the defaults).
    pub kind: RangeKind,
    /// Name in `ranges.csv` and messages (default: the kind and its position in the list).
    #[serde(default)]
    pub name: Option<String>,
    /// Mounting offset from the centre of mass, body FRD, m.
    #[serde(default)]
    pub offset: Option<[f64; 3]>,
    /// Mounting yaw, degrees, positive to the right.
    #[serde(default)]
    pub yaw: Option<f64>,
    /// Mounting pitch, degrees, positive up.
    #[serde(default)]
    pub pitch: Option<f64>,
    /// Scan rate, Hz.
    #[serde(default)]
    pub rate: Option<f64>,
    /// Latency from the scan to its delivery, s.
    #[serde(default)]
    pub latency: Option<f64>,
    /// Shortest range measured, m.
    #[serde(default)]
    pub min_range: Option<f64>,
    /// Longest range measured, m.
    #[serde(default)]
    pub max_range: Option<f64>,
    /// Range noise, standard deviation, m.
    #[serde(default)]
    pub noise: Option<f64>,
    /// Probability that a beam returns nothing.
    #[serde(default)]
    pub dropout: Option<f64>,
    /// Beams per row.
    #[serde(default)]
    pub columns: Option<u32>,
    /// Rows of beams.
    #[serde(default)]
    pub rows: Option<u32>,
    /// Horizontal field of view, degrees (360 = all around).
    #[serde(default)]
    pub fov_h: Option<f64>,
    /// Vertical field of view, degrees.
    #[serde(default)]
    pub fov_v: Option<f64>,
    /// Elevation of the vertical field's centre above the mounting plane, degrees (a 3D lidar's
    /// asymmetric field, e.g. −7°…+52°: `fov_v` 59, `elevation` 22.5; unlike `pitch` it does
    /// not tilt a 360° scan). Default 0.
    #[serde(default)]
    pub elevation: Option<f64>,
}

/// A range sensor with every value resolved (defaults applied, validated).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RangeSensor {
    /// Kind.
    pub kind: RangeKind,
    /// Name.
    pub name: String,
    /// Mounting offset, body FRD, m.
    pub offset: [f64; 3],
    /// Mounting yaw, degrees.
    pub yaw: f64,
    /// Mounting pitch, degrees.
    pub pitch: f64,
    /// Scan rate, Hz.
    pub rate: f64,
    /// Latency, s.
    pub latency: f64,
    /// Minimum range, m.
    pub min_range: f64,
    /// Maximum range, m.
    pub max_range: f64,
    /// Range noise σ, m.
    pub noise: f64,
    /// Dropout probability per beam.
    pub dropout: f64,
    /// Beams per row.
    pub columns: u32,
    /// Rows.
    pub rows: u32,
    /// Horizontal field of view, degrees.
    pub fov_h: f64,
    /// Vertical field of view, degrees.
    pub fov_v: f64,
    /// Elevation of the vertical field's centre above the mounting plane, degrees.
    #[serde(skip_serializing_if = "is_zero")]
    pub elevation: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// The defaults of a kind: a 72-beam 360° lidar at 10 Hz (0.15–12 m, 1 cm,
/// the `OBSTACLE_DISTANCE` resolution of 5°); a RealSense-D435-like depth
/// camera, 87° × 58° at 16 × 10 rays, 30 Hz, 0.3–6 m, 2 cm, 50 ms; a
/// VL53L5CX-like ToF sensor, 8 × 8 zones over 45° × 45°, 15 Hz, 0.02–4 m, 1.5 cm.
pub fn kind_defaults(kind: RangeKind) -> RangeSensor {
    let base = RangeSensor {
        kind,
        name: String::new(),
        offset: [0.0; 3],
        yaw: 0.0,
        pitch: 0.0,
        rate: 10.0,
        latency: 0.02,
        min_range: 0.15,
        max_range: 12.0,
        noise: 0.01,
        dropout: 0.01,
        columns: 72,
        rows: 1,
        fov_h: 360.0,
        fov_v: 0.0,
        elevation: 0.0,
    };
    match kind {
        RangeKind::Lidar => base,
        RangeKind::Camera => RangeSensor {
            rate: 30.0,
            latency: 0.05,
            min_range: 0.3,
            max_range: 6.0,
            noise: 0.02,
            dropout: 0.02,
            columns: 16,
            rows: 10,
            fov_h: 87.0,
            fov_v: 58.0,
            ..base
        },
        RangeKind::Tof => RangeSensor {
            rate: 15.0,
            latency: 0.02,
            min_range: 0.02,
            max_range: 4.0,
            noise: 0.015,
            dropout: 0.02,
            columns: 8,
            rows: 8,
            fov_h: 45.0,
            fov_v: 45.0,
            ..base
        },
    }
}

/// Names of the `--perception` presets.
pub const PRESETS: [&str; 7] = ["lidar", "lidar360", "lidar3d", "camera", "tof", "tof4", "tof8"];

/// The `lidar3d` preset, modelled on the Livox Mid-360: 360° × −7°…+52° (59° tall, centred 22.5°
/// up), 10 Hz, 0.1–40 m (its range at 10 % reflectivity), σ 2 cm, 1 % dropouts, 50 ms latency
/// (a 100 ms frame's mean age). Its 200,000 points/s are 20,000 per 10 Hz frame, spread by its
/// non-repetitive pattern; the simulated scan is a regular 72 × 14 lattice (5° × 4.2°, 1,008
/// beams): the controller's obstacle memory takes at most `parapet_core::perception::MAX_BEAMS`
/// (1,024) beams per scan, so the simulated sensor is **coarser** than the real one — a thin
/// obstacle between beams is seen later (5° is 0.26 m at 3 m, 1.7 m at 20 m).
pub fn lidar3d() -> RangeSensor {
    RangeSensor {
        name: "lidar3d".into(),
        elevation: 22.5,
        rate: 10.0,
        latency: 0.05,
        min_range: 0.1,
        max_range: 40.0,
        noise: 0.02,
        dropout: 0.01,
        columns: 72,
        rows: 14,
        fov_h: 360.0,
        fov_v: 59.0,
        ..kind_defaults(RangeKind::Lidar)
    }
}

/// The down-looking range sensor of the `lidar3d` set: the `tof` set's down sensor (an 8 × 8
/// VL53L5CX-like ToF, 45° × 45°, 15 Hz, 0.02–4 m) under the centre of mass. The Mid-360's field
/// starts 7° below the horizon, so an obstacle's top more than `d·tan 7°` below the sensor at a
/// horizontal distance `d` is never seen from close by; a vehicle that moves **vertically**
/// (sinking at take-off, sagging over a top) meets it unseen. Mid-360 vehicles carry such a
/// sensor for the height above ground (a flow module's rangefinder); here it puts the top under
/// the vehicle into the obstacle memory (`docs/perception.md` § Sensors, "The down sensor").
pub fn lidar3d_down() -> RangeSensor {
    RangeSensor { name: "lidar3d_down".into(), pitch: -90.0, ..kind_defaults(RangeKind::Tof) }
}

/// A `--perception` preset: `lidar` (the 72-beam lidar), `lidar360` (360 beams,
/// 1° steps), `lidar3d` (a Livox Mid-360-like 3D lidar, [`lidar3d`], and a down-looking ToF,
/// [`lidar3d_down`]), `camera` (one forward depth camera), `tof` (ten 8 × 8 ToF sensors: eight
/// every 45°, a ring whose views meet, one looking up and one down, as a multi-ranger
/// deck's up sensor and a flow deck's down sensor), `tof4` (four of them facing forward,
/// right, back and left: 45° gaps between their views; `tof` until 2026-12-05), `tof8` (the
/// ring without up and down). `None` for another name.
pub fn preset(name: &str) -> Option<Vec<RangeSensor>> {
    let named = |mut s: RangeSensor, n: &str| {
        s.name = n.to_string();
        s
    };
    match name {
        "lidar" => Some(vec![named(kind_defaults(RangeKind::Lidar), "lidar")]),
        "lidar360" => {
            Some(vec![named(RangeSensor { columns: 360, ..kind_defaults(RangeKind::Lidar) }, "lidar360")])
        }
        "lidar3d" => Some(vec![lidar3d(), lidar3d_down()]),
        "camera" => Some(vec![named(kind_defaults(RangeKind::Camera), "camera")]),
        "tof4" => Some(
            [("tof4_front", 0.0), ("tof4_right", 90.0), ("tof4_back", 180.0), ("tof4_left", -90.0)]
                .into_iter()
                .map(|(n, yaw)| named(RangeSensor { yaw, ..kind_defaults(RangeKind::Tof) }, n))
                .collect(),
        ),
        "tof8" | "tof" => {
            let mut ring: Vec<RangeSensor> = (0..8u8)
                .map(|i| {
                    let yaw = 45.0 * f64::from(i);
                    named(
                        RangeSensor { yaw, ..kind_defaults(RangeKind::Tof) },
                        &format!("{name}_{}", 45 * u16::from(i)),
                    )
                })
                .collect();
            if name == "tof" {
                for (pitch, n) in [(90.0, "up"), (-90.0, "down")] {
                    ring.push(named(
                        RangeSensor { pitch, ..kind_defaults(RangeKind::Tof) },
                        &format!("{name}_{n}"),
                    ));
                }
            }
            Some(ring)
        }
        _ => None,
    }
}

/// `field `k`: … (got v; allowed …)`, the scene loader's error format.
fn bad(field: &str, what: &str, value: impl std::fmt::Debug, allowed: &str) -> String {
    format!("field `{field}`: {what} (got {value:?}; allowed {allowed})")
}

impl RangeSensorSpec {
    /// Resolve the defaults and check every value; `index` names the sensor by
    /// default. Errors name the field, the value and the allowed range.
    pub fn resolve(&self, index: usize) -> Result<RangeSensor, String> {
        let d = kind_defaults(self.kind);
        let kind_name = match self.kind {
            RangeKind::Lidar => "lidar",
            RangeKind::Camera => "camera",
            RangeKind::Tof => "tof",
        };
        let s = RangeSensor {
            kind: self.kind,
            name: self.name.clone().unwrap_or_else(|| format!("{kind_name}{index}")),
            offset: self.offset.unwrap_or(d.offset),
            yaw: self.yaw.unwrap_or(d.yaw),
            pitch: self.pitch.unwrap_or(d.pitch),
            rate: self.rate.unwrap_or(d.rate),
            latency: self.latency.unwrap_or(d.latency),
            min_range: self.min_range.unwrap_or(d.min_range),
            max_range: self.max_range.unwrap_or(d.max_range),
            noise: self.noise.unwrap_or(d.noise),
            dropout: self.dropout.unwrap_or(d.dropout),
            columns: self.columns.unwrap_or(d.columns),
            rows: self.rows.unwrap_or(d.rows),
            fov_h: self.fov_h.unwrap_or(d.fov_h),
            fov_v: self.fov_v.unwrap_or(d.fov_v),
            elevation: self.elevation.unwrap_or(d.elevation),
        };
        s.validate()?;
        Ok(s)
    }
}

impl RangeSensor {
    /// Check every value (see the limits of this module).
    pub fn validate(&self) -> Result<(), String> {
        let s = self;
        if s.name.is_empty() || s.name.len() > 64 || s.name.contains([',', '"', '\n']) {
            return Err(bad(
                "name",
                "not a usable name",
                &s.name,
                "1–64 characters, no comma, quote or newline",
            ));
        }
        if !s.offset.iter().all(|x| x.is_finite() && x.abs() <= 10.0) {
            return Err(bad("offset", "out of range", s.offset, "finite, |x| ≤ 10 m (body FRD)"));
        }
        for (f, x) in [("yaw", s.yaw), ("pitch", s.pitch)] {
            if !(x.is_finite() && x.abs() <= 360.0) {
                return Err(bad(f, "out of range", x, "−360 ≤ angle ≤ 360 degrees"));
            }
        }
        let within = |f: &str, x: f64, lo: f64, hi: f64, lo_open: bool| -> Result<(), String> {
            let ok = x.is_finite() && x <= hi && if lo_open { x > lo } else { x >= lo };
            if ok {
                Ok(())
            } else {
                let op = if lo_open { "<" } else { "≤" };
                Err(bad(f, "out of range", x, &format!("{lo} {op} {f} ≤ {hi}")))
            }
        };
        within("rate", s.rate, 0.0, MAX_RATE_HZ, true)?;
        within("latency", s.latency, 0.0, MAX_LATENCY_S, false)?;
        within("max_range", s.max_range, 0.0, MAX_RANGE_M, true)?;
        within("min_range", s.min_range, 0.0, s.max_range, false)?;
        if s.min_range >= s.max_range {
            return Err(bad(
                "min_range",
                "the sensor covers nothing (no range between min_range and max_range)",
                s.min_range,
                &format!("0 ≤ min_range < max_range ({})", s.max_range),
            ));
        }
        within("noise", s.noise, 0.0, MAX_NOISE_M, false)?;
        within("dropout", s.dropout, 0.0, 1.0, false)?;
        if s.dropout >= 1.0 {
            return Err(bad(
                "dropout",
                "the sensor covers nothing (every beam is dropped)",
                s.dropout,
                "0 ≤ dropout < 1",
            ));
        }
        within("fov_h", s.fov_h, 0.0, 360.0, false)?;
        within("fov_v", s.fov_v, 0.0, 180.0, false)?;
        if !(s.elevation.is_finite() && s.elevation.abs() + 0.5 * s.fov_v <= 90.0) {
            return Err(bad(
                "elevation",
                "the vertical field leaves ±90°",
                s.elevation,
                &format!("|elevation| + fov_v / 2 ≤ 90 degrees (fov_v {})", s.fov_v),
            ));
        }
        if s.columns == 0 || s.rows == 0 || (s.columns as usize) * (s.rows as usize) > MAX_BEAMS {
            return Err(bad(
                "columns",
                "beam count out of range",
                (s.columns, s.rows),
                &format!("columns ≥ 1, rows ≥ 1, columns × rows ≤ {MAX_BEAMS}"),
            ));
        }
        Ok(())
    }

    /// Number of beams.
    pub fn beams(&self) -> usize {
        self.columns as usize * self.rows as usize
    }

    /// Every beam points into the front half of the body (`x_FRD ≥ 0`, beams at exactly
    /// ±90° included): the sensor never sees behind the vehicle (a forward camera).
    pub fn forward_only(&self) -> bool {
        self.beam_directions().iter().all(|d| d.x > -1e-9)
    }

    /// Mounting rotation sensor → body (yaw about z down, then pitch up about y).
    pub fn mount(&self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(0.0, self.pitch.to_radians(), self.yaw.to_radians())
    }

    /// Unit beam directions in the body frame FRD, row by row (beam index
    /// `row × columns + column`), see the module doc.
    pub fn beam_directions(&self) -> Vec<Vector3<f64>> {
        let mount = self.mount();
        let (nc, nr) = (self.columns as usize, self.rows as usize);
        let full_circle = self.fov_h >= 360.0;
        let step_h = if full_circle { 360.0 / nc as f64 } else { self.fov_h / nc as f64 };
        let step_v = self.fov_v / nr as f64;
        let mut out = Vec::with_capacity(nc * nr);
        for r in 0..nr {
            // Rows from the bottom: elevation −fov_v/2 + (r + ½) step (+ the field's centre).
            let e0 = -0.5 * self.fov_v + (r as f64 + 0.5) * step_v;
            let e = if self.elevation == 0.0 { e0 } else { e0 + self.elevation }.to_radians();
            for c in 0..nc {
                let a = if full_circle {
                    c as f64 * step_h
                } else {
                    -0.5 * self.fov_h + (c as f64 + 0.5) * step_h
                }
                .to_radians();
                // FRD: elevation up is −z; the mounting pitch (about y) is positive nose-up.
                let d = Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), -e.sin());
                out.push(mount * d);
            }
        }
        out
    }

    /// The measurement of a beam whose exact first hit is `hit` (m, `None`
    /// = nothing within `max_range`): dropout, noise, then the range limits
    /// (see the module doc). Draws from `rng` for every beam (a dropout draw,
    /// and a noise draw when σ > 0), so the stream does not depend on the scene.
    pub fn measure(&self, hit: Option<f64>, rng: &mut ChaCha8Rng, noise_on: bool) -> Return {
        let dropped = self.dropout > 0.0 && rng.random::<f64>() < self.dropout;
        let n = match Normal::new(0.0, self.noise) {
            Ok(n) if noise_on && self.noise > 0.0 => n.sample(rng),
            _ => 0.0,
        };
        match hit {
            _ if dropped => Return::Unknown,
            None => Return::Clear,
            Some(h) if h + n > self.max_range => Return::Clear,
            Some(h) if h + n < self.min_range => Return::Unknown,
            Some(h) => Return::Hit(h + n),
        }
    }
}

/// One beam's measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Return {
    /// A return at this range, m.
    Hit(f64),
    /// Nothing within `max_range`.
    Clear,
    /// No information (dropout, closer than `min_range`).
    Unknown,
}

impl Return {
    /// The range of a hit.
    pub fn range(&self) -> Option<f64> {
        match self {
            Return::Hit(r) => Some(*r),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn presets_are_valid_and_point_where_documented() {
        for name in PRESETS {
            for s in preset(name).unwrap() {
                s.validate().unwrap();
                assert_eq!(s.beam_directions().len(), s.beams());
            }
        }
        assert!(preset("sonar").is_none());
        let lidar = &preset("lidar").unwrap()[0];
        let d = lidar.beam_directions();
        assert_eq!(d.len(), 72);
        assert!((d[0] - Vector3::x()).norm() < 1e-12);
        // Beam 18 (90°) points right (+y FRD), all horizontal.
        assert!((d[18] - Vector3::y()).norm() < 1e-12);
        assert!(d.iter().all(|v| v.z.abs() < 1e-12 && (v.norm() - 1.0).abs() < 1e-12));
        let cam = &preset("camera").unwrap()[0];
        let d = cam.beam_directions();
        // First row looks down (+z), first column left (−y); the centre forward.
        assert!(d[0].z > 0.3 && d[0].y < -0.5);
        let mean: Vector3<f64> = d.iter().sum::<Vector3<f64>>() / d.len() as f64;
        assert!(mean.y.abs() < 1e-12 && mean.z.abs() < 1e-12 && mean.x > 0.7);
        let tof = preset("tof4").unwrap();
        assert_eq!(tof.len(), 4);
        let back: Vector3<f64> = tof[2].beam_directions().iter().sum();
        assert!(back.normalize().x < -0.99);
        // Pitch up points up.
        let up = RangeSensor { pitch: 30.0, ..kind_defaults(RangeKind::Tof) };
        let m: Vector3<f64> = up.beam_directions().iter().sum();
        assert!((m.normalize().z + 0.5).abs() < 1e-9);
    }

    /// The Mid-360-like 3D lidar: 1,008 beams all around, from 7° below the horizon to 52°
    /// above it (FRD: up is −z), 40 m.
    #[test]
    fn lidar3d_covers_360_by_minus_7_to_52_degrees() {
        let l = &preset("lidar3d").unwrap()[0];
        let d = l.beam_directions();
        assert_eq!((d.len(), l.max_range, l.rate), (1008, 40.0, 10.0));
        let elev: Vec<f64> = d.iter().map(|v| (-v.z).asin().to_degrees()).collect();
        let (lo, hi) =
            elev.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &e| (a.min(e), b.max(e)));
        // Beam centres half a row inside the field's edges.
        let half_row = 0.5 * l.fov_v / f64::from(l.rows);
        assert!((lo - (-7.0 + half_row)).abs() < 1e-9 && (hi - (52.0 - half_row)).abs() < 1e-9, "{lo}..{hi}");
        // Every 5° bearing has beams (the lamp above a planar scan is seen: elevation > 0).
        for b in 0..72 {
            let a = (b as f64 * 5.0).to_radians();
            let u = Vector3::new(a.cos(), a.sin(), 0.0);
            assert!(d.iter().any(|v| Vector3::new(v.x, v.y, 0.0).normalize().dot(&u) > 0.999), "bearing {b}");
        }
        assert!(!l.forward_only());
        // With the down-looking ToF under it (the field below −7° is blind).
        let set = preset("lidar3d").unwrap();
        assert_eq!(set.len(), 2);
        let down: Vector3<f64> = set[1].beam_directions().iter().sum();
        assert!(down.normalize().z > 0.99, "FRD: down is +z");
        assert_eq!((set[1].kind, set[1].max_range), (RangeKind::Tof, 4.0));
    }

    /// Which sensors see only the front half (the default yaw mode follows it).
    #[test]
    fn forward_only_is_the_front_half() {
        assert!(preset("camera").unwrap()[0].forward_only());
        assert!(!preset("lidar").unwrap()[0].forward_only());
        let tof: Vec<bool> = preset("tof4").unwrap().iter().map(RangeSensor::forward_only).collect();
        assert_eq!(tof, [true, false, false, false], "front, right, back, left");
        // The ring of eight: the views meet (every 5° bearing within some sensor's 45°).
        let seen = |set: &[RangeSensor], deg: f64| {
            let a = deg.to_radians();
            let u = Vector3::new(a.cos(), a.sin(), 0.0);
            set.iter().any(|s| s.beam_directions().iter().any(|d| d.dot(&u) > 5.0f64.to_radians().cos()))
        };
        let ring = preset("tof8").unwrap();
        assert_eq!(ring.len(), 8);
        for b in 0..72 {
            assert!(seen(&ring, b as f64 * 5.0), "tof8: bearing {}° unseen", b * 5);
        }
        assert!(!seen(&preset("tof4").unwrap(), 45.0), "tof4: the gap at 45°");
        // tof: the same ring, then up (−z FRD) and down (+z).
        let ten = preset("tof").unwrap();
        assert_eq!(ten.len(), 10);
        for b in 0..72 {
            assert!(seen(&ten, b as f64 * 5.0), "tof: bearing {}° unseen", b * 5);
        }
        let mean = |s: &RangeSensor| s.beam_directions().iter().sum::<Vector3<f64>>().normalize();
        assert!(mean(&ten[8]).z < -0.99 && mean(&ten[9]).z > 0.99, "up, then down");
        assert!(!ten.iter().all(RangeSensor::forward_only), "the set sees behind: hold by default");
        // A 180° camera reaches ±90° exactly: still the front half; yawed 10° it is not.
        let wide = RangeSensor { fov_h: 180.0, columns: 2, ..kind_defaults(RangeKind::Camera) };
        assert!(RangeSensor { columns: 180, ..wide.clone() }.forward_only());
        assert!(!RangeSensor { columns: 180, yaw: 10.0, ..wide }.forward_only());
        // A camera looking back.
        assert!(!RangeSensor { yaw: 180.0, ..kind_defaults(RangeKind::Camera) }.forward_only());
    }

    #[test]
    fn bad_tables_name_the_field_value_and_range() {
        let spec = |f: &dyn Fn(&mut RangeSensorSpec)| {
            let mut s: RangeSensorSpec = toml::from_str("kind = \"lidar\"").unwrap();
            f(&mut s);
            s.resolve(0)
        };
        assert_eq!(spec(&|_| {}).unwrap().name, "lidar0");
        let e = spec(&|s| s.rate = Some(0.0)).unwrap_err();
        assert!(e.contains("`rate`") && e.contains("got 0.0") && e.contains("250"), "{e}");
        let e = spec(&|s| s.min_range = Some(20.0)).unwrap_err();
        assert!(e.contains("`min_range`") && e.contains("12"), "{e}");
        let e = spec(&|s| s.dropout = Some(f64::NAN)).unwrap_err();
        assert!(e.contains("`dropout`"), "{e}");
        // A sensor that covers nothing, a negative latency (issue 36).
        let e = spec(&|s| s.min_range = Some(12.0)).unwrap_err();
        assert!(
            e.contains("`min_range`") && e.contains("covers nothing") && e.contains("< max_range"),
            "{e}"
        );
        let e = spec(&|s| s.dropout = Some(1.0)).unwrap_err();
        assert!(e.contains("`dropout`") && e.contains("covers nothing") && e.contains("dropout < 1"), "{e}");
        let e = spec(&|s| s.latency = Some(-0.1)).unwrap_err();
        assert!(e.contains("`latency`") && e.contains("-0.1") && e.contains("0 ≤ latency"), "{e}");
        let e = spec(&|s| s.columns = Some(5000)).unwrap_err();
        assert!(e.contains("4096"), "{e}");
        let e = spec(&|s| {
            s.fov_v = Some(59.0);
            s.elevation = Some(70.0);
        })
        .unwrap_err();
        assert!(e.contains("`elevation`") && e.contains("70") && e.contains("≤ 90"), "{e}");
        assert!(spec(&|s| s.elevation = Some(f64::NAN)).is_err());
        let ok = spec(&|s| {
            s.fov_v = Some(59.0);
            s.rows = Some(14);
            s.elevation = Some(22.5);
        });
        assert_eq!(ok.map(|s| s.elevation), Ok(22.5));
        assert!(toml::from_str::<RangeSensorSpec>("kind = \"sonar\"").is_err());
        assert!(toml::from_str::<RangeSensorSpec>("kind = \"tof\"\nbeams = 3").is_err());
    }

    #[test]
    fn measurement_noise_dropout_and_limits() {
        let s = RangeSensor { noise: 0.05, dropout: 0.1, ..kind_defaults(RangeKind::Lidar) };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 20_000;
        let got: Vec<Option<f64>> = (0..n).map(|_| s.measure(Some(5.0), &mut rng, true).range()).collect();
        let drops = got.iter().filter(|r| r.is_none()).count() as f64 / n as f64;
        assert!((drops - 0.1).abs() < 0.01, "dropout rate {drops}");
        let vals: Vec<f64> = got.iter().flatten().copied().collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / vals.len() as f64).sqrt();
        assert!((mean - 5.0).abs() < 0.002 && (sd - 0.05).abs() < 0.002, "{mean} {sd}");
        // Limits: nothing beyond max or below min; noise off is exact.
        let exact = RangeSensor { dropout: 0.0, ..s.clone() };
        assert_eq!(exact.measure(None, &mut rng, true), Return::Clear);
        assert_eq!(exact.measure(Some(3.0), &mut rng, false), Return::Hit(3.0));
        assert_eq!(exact.measure(Some(0.1), &mut rng, false), Return::Unknown);
        assert_eq!(exact.measure(Some(12.5), &mut rng, false), Return::Clear);
        let always = RangeSensor { dropout: 1.0, ..s.clone() };
        assert_eq!(always.measure(Some(3.0), &mut rng, false), Return::Unknown);
    }
}

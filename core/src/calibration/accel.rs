//! Accelerometer six-position calibration (MAV_CMD_PREFLIGHT_CALIBRATION param5 = 1): the
//! vehicle is put at rest on each of its six faces in any order; for each the calibrator
//! waits until it is still, detects which face is down, averages the raw sensor-frame
//! specific force and restarts that face when it moves. With all six faces it fits a
//! per-axis offset and scale ([`fit_six`]) and reports the result.
//!
//! Progress is reported as [`CalEvent`]s whose [`CalEvent::write`] text is PX4's
//! (`src/modules/commander/calibration_messages.h`, the strings QGroundControl's sensor
//! page parses): `[cal] calibration started: 2 accel`, `[cal] <face> orientation detected`,
//! `[cal] progress <N>`, `[cal] <face> side done, rotate to a different side`,
//! `[cal] calibration done: accel`, `[cal] calibration failed: <why>`.
//! Face names are PX4's: `down` (level, the normal attitude), `up` (upside down), `left`,
//! `right` (lying on that side), `front` (nose down), `back` (tail down).
//!
//! ## The fit
//! Model: `true = scale ⊙ (raw − offset)` per sensor axis; at rest `|true| = g`. Start: the
//! offset is the mean of the six face means (exact for six axis-aligned faces), the scale
//! `2g / (max − min)` per axis; then Gauss-Newton on the six residuals
//! `|scale ⊙ (mean_k − offset)|² − g²` (six equations, six unknowns, a 6×6 LU per
//! iteration, at most [`FIT_ITERATIONS`]), so faces held a few degrees off the axes do not
//! bias the scale (the closed form alone would by 1 − cos(tilt)).
//!
//! Bounded: one sample is a handful of vector operations; the fit runs once, at the end.
//! May import: the parent (`calibration`), `frame`, `fmath`.

use super::{BoardRotation, ACCEL_OFFSET_MAX, ACCEL_SCALE_RANGE};
use crate::fmath;
use crate::frame::GRAVITY;
use crate::Vec3;
use nalgebra::{Matrix3, Matrix6, Vector6};

/// Most Gauss-Newton iterations of [`fit_six`].
pub const FIT_ITERATIONS: usize = 20;

/// A face of the vehicle, PX4's names and order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Face {
    /// Tail down: specific force `(+g, 0, 0)` in the body frame.
    Back,
    /// Nose down: `(−g, 0, 0)`.
    Front,
    /// On its left side: `(0, +g, 0)`.
    Left,
    /// On its right side: `(0, −g, 0)`.
    Right,
    /// Upside down: `(0, 0, +g)`.
    Up,
    /// Level: `(0, 0, −g)`.
    Down,
}

impl Face {
    /// All six, in PX4's order.
    pub const ALL: [Face; 6] = [Face::Back, Face::Front, Face::Left, Face::Right, Face::Up, Face::Down];

    /// PX4's name.
    pub fn name(self) -> &'static str {
        match self {
            Face::Back => "back",
            Face::Front => "front",
            Face::Left => "left",
            Face::Right => "right",
            Face::Up => "up",
            Face::Down => "down",
        }
    }

    fn index(self) -> usize {
        self as usize
    }

    /// The face a body-frame specific force shows: one axis within 30 % of ±g and the
    /// others within 30 % of 0, else `None`.
    pub fn detect(body: &Vec3) -> Option<Face> {
        let tol = 0.3 * GRAVITY;
        let near = |x: f32, t: f32| (x - t).abs() < tol;
        Face::ALL.into_iter().find(|f| {
            let g = f.specific_force();
            near(body.x, g.x) && near(body.y, g.y) && near(body.z, g.z)
        })
    }

    /// The body-frame specific force at rest on this face (±g along one axis, the variants'
    /// docs).
    pub fn specific_force(self) -> Vec3 {
        match self {
            Face::Back => Vec3::new(GRAVITY, 0.0, 0.0),
            Face::Front => Vec3::new(-GRAVITY, 0.0, 0.0),
            Face::Left => Vec3::new(0.0, GRAVITY, 0.0),
            Face::Right => Vec3::new(0.0, -GRAVITY, 0.0),
            Face::Up => Vec3::new(0.0, 0.0, GRAVITY),
            Face::Down => Vec3::new(0.0, 0.0, -GRAVITY),
        }
    }
}

/// Why a calibration failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalFailure {
    /// No face completed within [`CalParams::timeout_s`].
    Timeout,
    /// The fit did not converge or gave an offset or scale outside the parameter ranges.
    Fit,
    /// A sample was not finite.
    Sensor,
}

impl CalFailure {
    fn text(self) -> &'static str {
        match self {
            CalFailure::Timeout => "timeout",
            CalFailure::Fit => "fit out of range",
            CalFailure::Sensor => "reading sensor",
        }
    }
}

/// Per-axis accelerometer offset and scale (sensor frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelFit {
    /// Offset, m/s² (`CAL_ACC0_XOFF` …).
    pub offset: Vec3,
    /// Scale (`CAL_ACC0_XSCALE` …).
    pub scale: Vec3,
}

/// One step of the calibration, as a STATUSTEXT ([`CalEvent::write`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CalEvent {
    /// The calibration began.
    Started,
    /// The vehicle is still on this face; averaging.
    OrientationDetected(Face),
    /// Overall progress, percent.
    Progress(u8),
    /// This face is done.
    SideDone(Face),
    /// This face was done before: turn to another one.
    AlreadyDone(Face),
    /// It moved while averaging: the face starts again.
    Motion,
    /// Finished; the result to store.
    Done(AccelFit),
    /// Failed; nothing stored.
    Failed(CalFailure),
    /// Cancelled by the caller; nothing stored.
    Cancelled,
}

impl CalEvent {
    /// The PX4 / QGroundControl text (at most 50 bytes, one STATUSTEXT). Written piecewise
    /// with `write_str` (no `write!`): the board image then links no `core::fmt` machinery
    /// for these texts (issue 22's flash budget).
    pub fn write(&self, w: &mut impl core::fmt::Write) -> core::fmt::Result {
        let (head, mid, tail) = match self {
            CalEvent::Started => ("[cal] calibration started: 2 accel", "", ""),
            CalEvent::OrientationDetected(f) => ("[cal] ", f.name(), " orientation detected"),
            CalEvent::Progress(p) => return write_progress(w, *p),
            CalEvent::SideDone(f) => ("[cal] ", f.name(), " side done, rotate to a different side"),
            CalEvent::AlreadyDone(f) => ("[cal] ", f.name(), " side already completed"),
            CalEvent::Motion => ("[cal] detected motion, hold still...", "", ""),
            CalEvent::Done(_) => ("[cal] calibration done: accel", "", ""),
            CalEvent::Failed(why) => ("[cal] calibration failed: ", why.text(), ""),
            CalEvent::Cancelled => ("[cal] calibration cancelled", "", ""),
        };
        w.write_str(head)?;
        w.write_str(mid)?;
        w.write_str(tail)
    }
}

/// `[cal] progress <p>` (QGroundControl's progress text), `p` in decimal without `core::fmt`.
fn write_progress(w: &mut impl core::fmt::Write, p: u8) -> core::fmt::Result {
    w.write_str("[cal] progress <")?;
    let digits = [b'0' + p / 100, b'0' + p / 10 % 10, b'0' + p % 10];
    let skip = usize::from(p < 100) + usize::from(p < 10); // leading zeros
    for &d in &digits[skip..] {
        w.write_char(char::from(d))?;
    }
    w.write_char('>')
}

/// Calibrator settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalParams {
    /// Time constant of the stillness filter, s. Default 0.2.
    pub ema_tau_s: f32,
    /// Largest filtered deviation still counted as "still", m/s² (RMS). Default 0.25.
    pub still_rms: f32,
    /// Time the vehicle must be still before a face is detected, s. Default 1.
    pub still_time_s: f32,
    /// Averaging time per face, s. Default 2.
    pub collect_time_s: f32,
    /// A sample further than this from the face's mean restarts the face, m/s². Default 1.5.
    pub motion_max: f32,
    /// Time without completing a face before the calibration fails, s. Default 60.
    pub timeout_s: f32,
}

impl Default for CalParams {
    fn default() -> Self {
        Self {
            ema_tau_s: 0.2,
            still_rms: 0.25,
            still_time_s: 1.0,
            collect_time_s: 2.0,
            motion_max: 1.5,
            timeout_s: 60.0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Waiting { still_since_us: Option<u64> },
    Collecting { face: Face, since_us: u64, sum: Vec3, n: u32 },
    Finished,
}

/// The six-position calibration state machine (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct AccelCalibrator {
    params: CalParams,
    board: Matrix3<f32>,
    faces: [Option<Vec3>; 6],
    phase: Phase,
    ema: Option<Vec3>,
    var: f32,
    last_us: u64,
    progress_at_us: u64,
    last_face_us: u64,
    last_progress: u8,
}

impl AccelCalibrator {
    /// Start a calibration; `board` is the IMU orientation used to name the faces. Send the
    /// returned [`CalEvent::Started`].
    pub fn start(now_us: u64, params: CalParams, board: BoardRotation) -> (Self, CalEvent) {
        let c = Self {
            params,
            board: board.matrix(),
            faces: [None; 6],
            phase: Phase::Waiting { still_since_us: None },
            ema: None,
            var: 0.0,
            last_us: now_us,
            progress_at_us: now_us,
            last_face_us: now_us,
            last_progress: 0,
        };
        (c, CalEvent::Started)
    }

    /// Faces done so far.
    pub fn faces_done(&self) -> usize {
        self.faces.iter().filter(|f| f.is_some()).count()
    }

    /// `true` once done or failed.
    pub fn finished(&self) -> bool {
        self.phase == Phase::Finished
    }

    /// Stop (the caller sends [`CalEvent::Cancelled`]).
    pub fn cancel(&mut self) -> CalEvent {
        self.phase = Phase::Finished;
        CalEvent::Cancelled
    }

    /// One raw sensor-frame accelerometer sample (specific force, m/s², no calibration
    /// applied). At most one event per sample.
    pub fn update(&mut self, now_us: u64, raw: Vec3) -> Option<CalEvent> {
        if self.phase == Phase::Finished {
            return None;
        }
        if !crate::frame::is_finite3(&raw) {
            self.phase = Phase::Finished;
            return Some(CalEvent::Failed(CalFailure::Sensor));
        }
        let dt = now_us.saturating_sub(self.last_us) as f32 * 1e-6;
        self.last_us = now_us;
        if now_us.saturating_sub(self.last_face_us) as f32 * 1e-6 > self.params.timeout_s {
            self.phase = Phase::Finished;
            return Some(CalEvent::Failed(CalFailure::Timeout));
        }
        // Stillness: EMA of the sample and of its squared deviation.
        let a = if self.params.ema_tau_s > 0.0 { fmath::minf(dt / self.params.ema_tau_s, 1.0) } else { 1.0 };
        let ema = match self.ema {
            Some(e) => e + (raw - e) * a,
            None => raw,
        };
        self.ema = Some(ema);
        self.var += a * ((raw - ema).norm_squared() - self.var);
        let still = self.var < self.params.still_rms * self.params.still_rms;
        match self.phase {
            Phase::Waiting { still_since_us } => {
                if !still {
                    self.phase = Phase::Waiting { still_since_us: None };
                    return None;
                }
                let since = still_since_us.unwrap_or(now_us);
                self.phase = Phase::Waiting { still_since_us: Some(since) };
                if now_us.saturating_sub(since) as f32 * 1e-6 < self.params.still_time_s {
                    return None;
                }
                let face = Face::detect(&(self.board * ema))?;
                if self.faces[face.index()].is_some() {
                    // Say it once per stillness, then wait for the vehicle to move.
                    self.phase = Phase::Waiting { still_since_us: Some(u64::MAX / 2) };
                    return Some(CalEvent::AlreadyDone(face));
                }
                self.phase = Phase::Collecting { face, since_us: now_us, sum: Vec3::zeros(), n: 0 };
                Some(CalEvent::OrientationDetected(face))
            }
            Phase::Collecting { face, since_us, sum, n } => {
                let mean = if n > 0 { sum / n as f32 } else { ema };
                if (raw - mean).norm() > self.params.motion_max || !still {
                    self.phase = Phase::Waiting { still_since_us: None };
                    return Some(CalEvent::Motion);
                }
                let (sum, n) = (sum + raw, n + 1);
                let elapsed = now_us.saturating_sub(since_us) as f32 * 1e-6;
                if elapsed >= self.params.collect_time_s {
                    self.faces[face.index()] = Some(sum / n as f32);
                    self.last_face_us = now_us;
                    self.phase = Phase::Waiting { still_since_us: None };
                    if self.faces_done() == 6 {
                        self.phase = Phase::Finished;
                        return Some(self.result());
                    }
                    return Some(CalEvent::SideDone(face));
                }
                self.phase = Phase::Collecting { face, since_us, sum, n };
                let frac = elapsed / self.params.collect_time_s;
                let p = ((self.faces_done() as f32 + frac) * 100.0 / 6.0) as u8;
                if p >= self.last_progress.saturating_add(5)
                    && now_us.saturating_sub(self.progress_at_us) >= 200_000
                {
                    self.last_progress = p;
                    self.progress_at_us = now_us;
                    return Some(CalEvent::Progress(p));
                }
                None
            }
            Phase::Finished => None,
        }
    }

    fn result(&self) -> CalEvent {
        let mut means = [Vec3::zeros(); 6];
        for (m, f) in means.iter_mut().zip(self.faces.iter()) {
            match f {
                Some(v) => *m = *v,
                None => return CalEvent::Failed(CalFailure::Fit),
            }
        }
        match fit_six(&means) {
            Some(fit) => CalEvent::Done(fit),
            None => CalEvent::Failed(CalFailure::Fit),
        }
    }
}

/// Per-axis offset and scale from six rest means (any order; see the module docs). `None`
/// when the fit does not converge or leaves the parameter ranges.
pub fn fit_six(means: &[Vec3; 6]) -> Option<AccelFit> {
    let mut b = means.iter().fold(Vec3::zeros(), |s, m| s + m) / 6.0;
    let mut s = Vec3::zeros();
    for i in 0..3 {
        let (lo, hi) = means.iter().fold((f32::MAX, f32::MIN), |(lo, hi), m| (lo.min(m[i]), hi.max(m[i])));
        if (hi - lo).is_nan() || hi - lo <= GRAVITY {
            return None; // the six faces do not span this axis
        }
        s[i] = 2.0 * GRAVITY / (hi - lo);
    }
    let g2 = GRAVITY * GRAVITY;
    for _ in 0..FIT_ITERATIONS {
        let mut j = Matrix6::<f32>::zeros();
        let mut f = Vector6::<f32>::zeros();
        for (k, m) in means.iter().enumerate() {
            let d = m - b;
            f[k] = s.component_mul(&d).norm_squared() - g2;
            for i in 0..3 {
                j[(k, i)] = -2.0 * s[i] * s[i] * d[i];
                j[(k, 3 + i)] = 2.0 * s[i] * d[i] * d[i];
            }
        }
        let step = j.lu().solve(&(-f))?;
        for i in 0..3 {
            b[i] += step[i];
            s[i] += step[3 + i];
        }
        if step.norm() < 1e-6 {
            break;
        }
    }
    let residual =
        means.iter().map(|m| (fmath::norm3(&s.component_mul(&(m - b))) - GRAVITY).abs()).fold(0.0, f32::max);
    let ok = crate::frame::is_finite3(&b)
        && crate::frame::is_finite3(&s)
        && b.iter().all(|x| x.abs() <= ACCEL_OFFSET_MAX)
        && s.iter().all(|x| (ACCEL_SCALE_RANGE.0..=ACCEL_SCALE_RANGE.1).contains(x))
        && residual < 0.05;
    ok.then_some(AccelFit { offset: b, scale: s })
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::string::String;
    use std::vec::Vec;

    const OFFSET: Vec3 = Vec3::new(0.35, -0.22, 0.51);
    const SCALE: Vec3 = Vec3::new(1.03, 0.97, 1.015);

    /// Raw reading of a true specific force under the test's bias and scale.
    fn raw_of(truth: Vec3) -> Vec3 {
        truth.component_div(&SCALE) + OFFSET
    }

    /// A deterministic noise source (xorshift).
    struct Noise(u32);
    impl Noise {
        fn next(&mut self, amp: f32) -> Vec3 {
            let mut v = [0.0; 3];
            for x in &mut v {
                self.0 ^= self.0 << 13;
                self.0 ^= self.0 >> 17;
                self.0 ^= self.0 << 5;
                *x = ((self.0 as f32 / u32::MAX as f32) * 2.0 - 1.0) * amp;
            }
            Vec3::new(v[0], v[1], v[2])
        }
    }

    fn face_truth(f: Face) -> Vec3 {
        f.specific_force()
    }

    /// Run a calibration: for each face, `hold_s` at rest at 200 Hz, then a 0.5 s turn.
    fn run(order: &[Face], noise: f32, hold_s: f32, jolt_at: Option<f32>) -> Vec<CalEvent> {
        let (mut cal, first) = AccelCalibrator::start(0, CalParams::default(), BoardRotation::NONE);
        let mut ev = std::vec![first];
        let mut t = 0u64;
        let mut rng = Noise(0x1234_5678);
        for (k, f) in order.iter().enumerate() {
            let steps = (hold_s * 200.0) as u32;
            for i in 0..steps {
                let mut truth = face_truth(*f);
                if k == 0 && jolt_at.is_some_and(|j| (i as f32 / 200.0 - j).abs() < 0.02) {
                    truth += Vec3::new(4.0, 0.0, 0.0);
                }
                ev.extend(cal.update(t, raw_of(truth) + rng.next(noise)));
                t += 5_000;
            }
            for i in 0..100 {
                let spin = Vec3::new((i as f32 * 0.3).sin() * 6.0, 3.0, 2.0);
                ev.extend(cal.update(t, raw_of(face_truth(*f) + spin)));
                t += 5_000;
            }
        }
        ev
    }

    fn done(ev: &[CalEvent]) -> Option<AccelFit> {
        ev.iter().find_map(|e| if let CalEvent::Done(f) = e { Some(*f) } else { None })
    }

    #[test]
    fn recovers_bias_and_scale_in_any_order() {
        let orders = [
            Face::ALL,
            [Face::Down, Face::Up, Face::Left, Face::Right, Face::Front, Face::Back],
            [Face::Up, Face::Back, Face::Right, Face::Down, Face::Left, Face::Front],
        ];
        for order in orders {
            let ev = run(&order, 0.05, 5.0, None);
            let fit = done(&ev).unwrap_or_else(|| panic!("{order:?}: {ev:?}"));
            assert!((fit.offset - OFFSET).norm() < 0.02, "{fit:?}");
            assert!((fit.scale - SCALE).norm() < 0.002, "{fit:?}");
            let detected: Vec<Face> = ev
                .iter()
                .filter_map(|e| if let CalEvent::OrientationDetected(f) = e { Some(*f) } else { None })
                .collect();
            assert_eq!(detected, order);
            assert!(ev.iter().any(|e| matches!(e, CalEvent::Progress(_))));
        }
    }

    #[test]
    fn a_face_done_twice_is_reported_and_the_calibration_waits() {
        let order = [Face::Down, Face::Down, Face::Up, Face::Left, Face::Right, Face::Front, Face::Back];
        let ev = run(&order, 0.02, 5.0, None);
        assert!(ev.contains(&CalEvent::AlreadyDone(Face::Down)));
        assert!(done(&ev).is_some());
    }

    #[test]
    fn motion_restarts_the_face() {
        let ev = run(&Face::ALL, 0.02, 6.0, Some(2.0));
        let motion = ev.iter().position(|e| *e == CalEvent::Motion).expect("motion detected");
        // The face is detected again after the jolt and the calibration still succeeds.
        assert!(ev[motion..].contains(&CalEvent::OrientationDetected(Face::Back)));
        let fit = done(&ev).unwrap();
        assert!((fit.offset - OFFSET).norm() < 0.02);
    }

    #[test]
    fn fit_tolerates_tilted_faces_and_refuses_nonsense() {
        // Each face held 5° off its axis (about a different axis each time).
        let tilt = 5f32.to_radians();
        let (s, c) = tilt.sin_cos();
        let truths = [
            Vec3::new(GRAVITY * c, GRAVITY * s, 0.0),
            Vec3::new(-GRAVITY * c, 0.0, GRAVITY * s),
            Vec3::new(0.0, GRAVITY * c, -GRAVITY * s),
            Vec3::new(GRAVITY * s, -GRAVITY * c, 0.0),
            Vec3::new(0.0, -GRAVITY * s, GRAVITY * c),
            Vec3::new(-GRAVITY * s, 0.0, -GRAVITY * c),
        ];
        let means = truths.map(raw_of);
        let fit = fit_six(&means).unwrap();
        assert!((fit.offset - OFFSET).norm() < 0.01, "{fit:?}");
        assert!((fit.scale - SCALE).norm() < 0.001, "{fit:?}");
        // Six times the same face: no span.
        assert!(fit_six(&[raw_of(face_truth(Face::Down)); 6]).is_none());
        let mut bad = Face::ALL.map(|f| raw_of(face_truth(f)));
        bad[0].x = f32::NAN;
        assert!(fit_six(&bad).is_none());
    }

    #[test]
    fn timeout_and_bad_samples_fail() {
        let (mut cal, _) = AccelCalibrator::start(0, CalParams::default(), BoardRotation::NONE);
        let mut last = None;
        for k in 0..(61 * 10) {
            // Moving the whole time: nothing is detected.
            let v = Vec3::new((k as f32).sin() * 5.0, 0.0, -GRAVITY);
            if let Some(e) = cal.update(k * 100_000, v) {
                last = Some(e);
            }
        }
        assert_eq!(last, Some(CalEvent::Failed(CalFailure::Timeout)));
        let (mut cal, _) = AccelCalibrator::start(0, CalParams::default(), BoardRotation::NONE);
        assert_eq!(cal.update(1, Vec3::new(f32::NAN, 0.0, 0.0)), Some(CalEvent::Failed(CalFailure::Sensor)));
        assert!(cal.finished());
    }

    #[test]
    fn faces_are_named_through_the_board_rotation() {
        // IMU mounted upside down (roll 180): the level vehicle reads +g on the sensor's z.
        let (mut cal, _) =
            AccelCalibrator::start(0, CalParams::default(), BoardRotation::from_code(8).unwrap());
        let mut ev = Vec::new();
        for k in 0..400 {
            ev.extend(cal.update(k * 5_000, Vec3::new(0.0, 0.0, GRAVITY)));
        }
        assert!(ev.contains(&CalEvent::OrientationDetected(Face::Down)), "{ev:?}");
    }

    #[test]
    fn texts_are_px4s_and_fit_a_statustext() {
        let fit = AccelFit { offset: Vec3::zeros(), scale: Vec3::zeros() };
        let cases = [
            (CalEvent::Started, "[cal] calibration started: 2 accel"),
            (CalEvent::OrientationDetected(Face::Down), "[cal] down orientation detected"),
            (CalEvent::Progress(17), "[cal] progress <17>"),
            (CalEvent::SideDone(Face::Front), "[cal] front side done, rotate to a different side"),
            (CalEvent::Done(fit), "[cal] calibration done: accel"),
            (CalEvent::Failed(CalFailure::Timeout), "[cal] calibration failed: timeout"),
        ];
        for (e, want) in cases {
            let mut s = String::new();
            e.write(&mut s).unwrap();
            assert_eq!(s, want);
            assert!(s.len() <= 50);
        }
    }

    /// The progress text without `core::fmt` is `format!`'s for every percentage.
    #[test]
    fn progress_text_is_formats_for_every_value() {
        for p in 0..=u8::MAX {
            let mut s = String::new();
            CalEvent::Progress(p).write(&mut s).unwrap();
            assert_eq!(s, std::format!("[cal] progress <{p}>"));
        }
    }
}

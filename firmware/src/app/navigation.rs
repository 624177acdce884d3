//! The navigation filter on the vehicle (issue 39): [`parapet_core::nav::aid::NavAid`] — the
//! code the host's in-process controller runs (`host-sim/src/fc/nav.rs`) — in the outer stage,
//! fed with the inner stage's IMU samples and the filtered sources' fixes, and read by the
//! outer stage as its position fix at every outer step.
//!
//! * **Predict**: the inner stage publishes one [`NavSample`] per step (the sample's time, its
//!   specific force and the attitude estimate after the step, as the host feeds the filter
//!   after `step_inner`) into [`crate::app::mailbox::Mailboxes::nav`]; the outer stage
//!   predicts with every queued sample before it fuses a fix and before its step, so fixes and
//!   samples reach the filter in the order they happened (≤ [`NAV_SAMPLE_DEPTH`] samples wait
//!   between two outer steps; on an overflow the oldest go and the next predict spans the gap).
//!   The predict (≈ 7.6k instructions on the Cortex-M4F, `docs/performance.md`) runs in the
//!   outer task, not in the 1 ms inner step.
//! * **Barometer**: HIL_SENSOR's `pressure_alt` (its `fields_updated` bit
//!   `HIL_SENSOR_UPDATED_PRESSURE_ALT`; m AMSL, home at `wire::geo::ORIGIN`'s altitude) is
//!   fused as a height with σ [`BARO_SIGMA_M`] at the sample's time
//!   ([`crate::link::inputs::hil_baro_down`]), as the host fuses its barometer.
//! * **Fixes**: GPS_INPUT (absolute), VISION_POSITION_ESTIMATE and a VIO's ODOMETRY (relative:
//!   their frame may jump) go to the filter with the σ they state
//!   ([`crate::link::position_sources`]); other ODOMETRY — the motion capture of the PIL and the
//!   lab — keeps the latest-fix path, as the host flies `mocap` without the filter (so the PIL
//!   flights and their host twin are unchanged).
//! * **The controller's fix**: while the filter is usable (a position fused within
//!   `NAV_TIMEOUT_US`, σ within bounds) it is handed to the outer loop as the fix of now before
//!   each outer step; afterwards nothing is, and the outer loop's 0.2 s position timeout brakes
//!   and lands (the failsafe of `docs/navigation.md` § Dropouts).
//! * **Resets**: an absolute source's position reset (the estimate jumped by δ) is handed to
//!   the outer loop once, before the step's fix (`OuterLoop::position_reset`: the guidance
//!   shifts its reference by δ), as the host's `fc/control.rs` does.
//! * **Margins** (`docs/filter.md` § 18, the host's `fc/control.rs` and `flight/sensing.rs`):
//!   with a filtered source the bound on the estimate's error
//!   ([`parapet_core::nav::bound`]: 3σ of the filter per axis, plus a relative source's frame
//!   drift since the first fix at [`VISION_DRIFT_M_PER_SQRT_S`], and once a barometer height
//!   has been fused the barometer's drift at [`BARO_DRIFT_M_PER_SQRT_S`] on the vertical) is set as the ground/ceiling margin before each outer step, and, once
//!   the filter is initialised, is the cascade's `Autopilot::mapped_margin` of that step, with
//!   which the link moves the **mapped** (world-frame) obstacle points towards the estimate
//!   (`crate::link::obstacles`) until the next outer step. Without a filtered source (motion
//!   capture) nothing is set: margin 0, the points as sent. A NaN σ: the bound is its largest,
//!   [`parapet_core::nav::bound::ERROR_BOUND_MAX_M`], and the filter is not usable (no fix: the
//!   position timeout brakes and lands).
//! * **Status**: [`NavReport`] for ESTIMATOR_STATUS (flags, test ratios, accuracies).
//!
//! Owns: [`Navigation`], [`NavSample`], [`NavReport`]. May import: `parapet_core`.

use parapet_core::msg::{Euler, PositionFix};
use parapet_core::nav::aid::{NavAid, SourceNoise, BARO_SIGMA_M};
use parapet_core::nav::bound::{
    ErrorBound, UnobservedDrift, BARO_DRIFT_M_PER_SQRT_S, VISION_DRIFT_M_PER_SQRT_S,
};
use parapet_core::nav::{FixKind, Fusion, NavParams, CHI2_GATE};
use parapet_core::Vec3;

/// IMU samples that may wait for the outer stage (16 ms at 1 kHz; 4 per outer step).
pub const NAV_SAMPLE_DEPTH: usize = 16;

/// One IMU sample for the filter: time, specific force (body FRD, m/s²), attitude estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavSample {
    /// Sample time, µs.
    pub t_us: u64,
    /// Specific force, body FRD, m/s².
    pub accel: Vec3,
    /// The attitude estimator's attitude after the step.
    pub attitude: Euler,
}

/// ESTIMATOR_STATUS's `flags` bits (MAVLink `ESTIMATOR_STATUS_FLAGS`).
pub mod flags {
    /// Attitude estimate good.
    pub const ATTITUDE: u16 = 1;
    /// Horizontal velocity good.
    pub const VELOCITY_HORIZ: u16 = 2;
    /// Vertical velocity good.
    pub const VELOCITY_VERT: u16 = 4;
    /// Horizontal position (relative) good.
    pub const POS_HORIZ_REL: u16 = 8;
    /// Horizontal position (absolute) good.
    pub const POS_HORIZ_ABS: u16 = 16;
    /// Vertical position (absolute) good.
    pub const POS_VERT_ABS: u16 = 32;
    /// The source's fixes disagree with the prediction (gated in a row).
    pub const GPS_GLITCH: u16 = 1024;
}

/// What ESTIMATOR_STATUS reports of the filter.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct NavReport {
    /// [`flags`] bits.
    pub flags: u16,
    /// Velocity test ratio: the last velocity fix's NIS / its χ² gate (> 1: gated).
    pub vel_ratio: f32,
    /// Position test ratio: the last position fix's NIS / its χ² gate (horizontal and
    /// vertical share the one 3-D test).
    pub pos_ratio: f32,
    /// Horizontal position σ (the larger of north and east), m.
    pub pos_horiz_accuracy: f32,
    /// Vertical position σ, m.
    pub pos_vert_accuracy: f32,
}

/// The filter (it knows the kind of the source feeding it, so whether it feeds the controller).
#[derive(Clone, Debug)]
pub struct Navigation {
    aid: NavAid,
    /// A barometer height has been given: its drift enters the error bound.
    baro: bool,
}

impl Default for Navigation {
    fn default() -> Self {
        Self::new()
    }
}

impl Navigation {
    /// No fix yet: the controller keeps the latest-fix path until a filtered source speaks.
    pub fn new() -> Self {
        Self { aid: NavAid::new(NavParams::default()), baro: false }
    }

    /// Predict with one IMU sample.
    pub fn sample(&mut self, s: &NavSample) {
        let _ = self.aid.imu(s.t_us, &s.accel, &s.attitude);
    }

    /// A fix of a filtered source of `kind` with σ `noise`.
    pub fn fix(&mut self, fix: &PositionFix, kind: FixKind, noise: SourceNoise) -> Fusion {
        self.aid.fix(fix, noise, kind)
    }

    /// A barometer height of `t_us` (NED down, m) with σ [`BARO_SIGMA_M`]; from the first one
    /// the error bound carries the barometer's drift ([`BARO_DRIFT_M_PER_SQRT_S`]).
    pub fn height(&mut self, t_us: u64, down: f32) -> Fusion {
        let fused = self.aid.height(t_us, down, BARO_SIGMA_M);
        self.baro |= fused == Fusion::Fused;
        fused
    }

    /// The outer loop's fix of `now_us`: `None` without a filtered source and in the failsafe.
    pub fn controller_fix(&self, now_us: u64) -> Option<PositionFix> {
        self.aid.controller_fix(now_us)
    }

    /// An absolute source's position reset not yet handed to the outer loop (its delta, once:
    /// [`NavAid::take_reset`]), as the host's controller takes it.
    pub fn take_reset(&mut self) -> Option<Vec3> {
        self.aid.take_reset()
    }

    /// The bound on the estimate's error at `now_us` (module docs); `None` without a filtered
    /// source (motion capture: no margin).
    pub fn error_bound(&self, now_us: u64) -> Option<ErrorBound> {
        let relative = match self.aid.kind()? {
            FixKind::Relative => VISION_DRIFT_M_PER_SQRT_S,
            FixKind::Absolute => 0.0,
        };
        let baro = if self.baro { BARO_DRIFT_M_PER_SQRT_S } else { 0.0 };
        Some(self.aid.error_bound(now_us, &UnobservedDrift { relative, baro }))
    }

    /// The filter (read-only).
    pub fn aid(&self) -> &NavAid {
        &self.aid
    }

    /// ESTIMATOR_STATUS of `now_us`; `None` until a filtered source has initialised the filter.
    pub fn report(&self, now_us: u64) -> Option<NavReport> {
        let kind = self.aid.kind()?;
        if !self.aid.filter().is_initialised() {
            return None;
        }
        let st = self.aid.status();
        let mut f = flags::ATTITUDE;
        if self.aid.usable(now_us) {
            f |= flags::VELOCITY_HORIZ | flags::VELOCITY_VERT | flags::POS_HORIZ_REL;
            if kind == FixKind::Absolute {
                f |= flags::POS_HORIZ_ABS | flags::POS_VERT_ABS;
            }
        }
        if self.aid.filter().consecutive_gated() > 0 {
            f |= flags::GPS_GLITCH;
        }
        Some(NavReport {
            flags: f,
            vel_ratio: st.last_velocity_nis / CHI2_GATE[2],
            pos_ratio: st.last_nis / CHI2_GATE[2],
            pos_horiz_accuracy: st.sigma_p.x.max(st.sigma_p.y),
            pos_vert_accuracy: st.sigma_p.z,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::{Autopilot, ControlSteps, ImuSample};
    use crate::app::cascade::Cascade;
    use parapet_core::controller::ControllerParams;
    use parapet_core::nav::aid::NAV_TIMEOUT_US;
    use parapet_core::nav::bound::MAPPED_MARGIN_SIGMA;

    const GPS: SourceNoise = SourceNoise { position: 0.5, velocity: 0.1 };

    fn imu(t_us: u64) -> ImuSample {
        let w = (t_us as f32 * 1e-4).sin();
        ImuSample { gyro: Vec3::new(0.01 * w, 0.0, 0.0), accel: Vec3::new(0.3 * w, -0.1, -9.81) }
    }

    /// A fix every 100 ms describing the time 150 ms before (GPS-like), moving north.
    fn fix_due(t_us: u64) -> Option<PositionFix> {
        (t_us >= 200_000 && t_us.is_multiple_of(100_000)).then(|| {
            let tm = t_us - 150_000;
            let x = tm as f32 * 1e-6;
            PositionFix {
                t_us: tm,
                position: Vec3::new(x, 0.2, -1.0),
                velocity: Vec3::new(1.0, 0.0, 0.0),
                yaw: None,
            }
        })
    }

    /// The cascade's stages (samples through the mailbox, fixes through the port, the estimate
    /// at each outer step) compute exactly what the core's `NavAid` computes when driven in the
    /// host's order (`host-sim/src/fc/control.rs`): the firmware and the host run one filter.
    #[test]
    fn the_outer_loop_flies_the_filter_estimate_bit_for_bit_as_the_host_drives_it() {
        let Ok(mut c) = Cascade::new(ControllerParams::default()) else { panic!("cascade") };
        let mut host = NavAid::new(NavParams::default());
        let (mut compared, mut baro_fused) = (0, false);
        for k in 1..=1_500u64 {
            let t = k * 1_000;
            if let Some(f) = fix_due(t) {
                c.navigation_fix(&f, FixKind::Absolute, GPS);
                host.fix(&f, GPS, FixKind::Absolute);
            }
            // A barometer at 50 Hz, 0.1 m above the fixes' height (HIL_SENSOR's pressure_alt).
            if t.is_multiple_of(20_000) {
                c.navigation_height(t, -1.1);
                baro_fused |= host.height(t, -1.1, BARO_SIGMA_M) == Fusion::Fused;
            }
            let s = imu(t);
            c.step_inner(t, &s);
            host.imu(t, &s.accel, &c.inner().inner().estimate().attitude);
            if t.is_multiple_of(4_000) {
                c.step_outer(t);
                if let Some(h) = host.controller_fix(t) {
                    let o = c.outer().outer().telemetry();
                    assert_eq!((o.position, o.velocity), (h.position, h.velocity), "t = {t}");
                    // The mapped obstacles' bound: the core's, of the filter's σ and, once a
                    // height is fused, the barometer's drift on the vertical.
                    let baro = if baro_fused { BARO_DRIFT_M_PER_SQRT_S } else { 0.0 };
                    let b = c.mapped_margin();
                    assert_eq!(
                        b,
                        Some(host.error_bound(t, &UnobservedDrift { relative: 0.0, baro })),
                        "t = {t}"
                    );
                    assert!(
                        !baro_fused || b.is_some_and(|b| b.vertical > MAPPED_MARGIN_SIGMA * 0.05),
                        "{b:?}"
                    );
                    compared += 1;
                }
            }
        }
        // From the third agreeing fix (initialised at 0.4 s, `NavParams::init_fixes`) to 1.5 s:
        // 275 outer steps compared.
        assert!(compared >= 275, "{compared}");
        assert!(baro_fused, "the heights were fused");
        let r = c.telemetry().nav.map(|n| n.flags);
        assert_eq!(r, Some(flags::ATTITUDE | 0b11_1110), "{r:?}");
    }

    /// The bound the margins take: none without a filtered source (motion capture keeps its
    /// margins at 0), 3σ of the filter with GPS, plus the vision drift since the first fix with
    /// a relative source.
    #[test]
    fn the_error_bound_is_none_without_a_filter_and_grows_with_a_relative_sources_drift() {
        use parapet_core::nav::bound::drift_bound;
        let mut gps = Navigation::new();
        assert_eq!(gps.error_bound(1_000_000), None);
        let mut vio = Navigation::new();
        for k in 1..=1_500u64 {
            let t = k * 1_000;
            if let Some(f) = fix_due(t) {
                gps.fix(&f, FixKind::Absolute, GPS);
                vio.fix(&f, FixKind::Relative, GPS);
            }
            let s = imu(t);
            let sample =
                NavSample { t_us: t, accel: s.accel, attitude: Euler { roll: 0.0, pitch: 0.0, yaw: 0.0 } };
            gps.sample(&sample);
            vio.sample(&sample);
        }
        let now = 1_500_000;
        let (Some(g), Some(v)) = (gps.error_bound(now), vio.error_bound(now)) else { panic!("no bound") };
        let sg = gps.aid().status().sigma_p;
        assert_eq!(g.horizontal, MAPPED_MARGIN_SIGMA * f64::from(sg.x.max(sg.y)));
        assert_eq!(g.vertical, MAPPED_MARGIN_SIGMA * f64::from(sg.z));
        assert!(g.horizontal > 0.05 && g.horizontal < 1.5, "{g:?}");
        // The first fix describes 50 ms (due at 200 ms, 150 ms old).
        let sv = vio.aid().status().sigma_p;
        let rel = drift_bound(VISION_DRIFT_M_PER_SQRT_S, 1_450_000_f64 * 1e-6, 3.0);
        assert_eq!(v.horizontal, MAPPED_MARGIN_SIGMA * f64::from(sv.x.max(sv.y)) + rel);
        assert!(rel > 0.2, "{rel}");
    }

    /// Fixes stop: the estimate is flown for `NAV_TIMEOUT_US` (bridged), then the controller
    /// gets no fix and its position goes stale (the brake-and-land failsafe's trigger).
    #[test]
    fn a_dropout_is_bridged_for_the_timeout_then_the_position_goes_stale() {
        let Ok(mut c) = Cascade::new(ControllerParams::default()) else { panic!("cascade") };
        let last_fix = 1_000_000;
        let mut fresh_until = 0;
        for k in 1..=4_000u64 {
            let t = k * 1_000;
            if let Some(f) = fix_due(t).filter(|_| t <= last_fix) {
                c.navigation_fix(&f, FixKind::Absolute, GPS);
            }
            c.step_inner(t, &imu(t));
            if t.is_multiple_of(4_000) {
                c.step_outer(t);
                if c.telemetry().position_fresh {
                    fresh_until = t;
                }
            }
        }
        // The last fix describes 850 ms; it is flown until NAV_TIMEOUT_US after it, then the
        // outer loop's 0.2 s position timeout runs out.
        let last_fused = last_fix - 150_000;
        assert!(fresh_until >= last_fused + NAV_TIMEOUT_US, "{fresh_until}");
        assert!(fresh_until <= last_fused + NAV_TIMEOUT_US + 204_000, "{fresh_until}");
        let r = c.telemetry().nav.map(|n| n.flags);
        assert_eq!(r, Some(flags::ATTITUDE), "{r:?}");
    }

    /// GPS fixes jump by 4 m east while the vehicle takes off and holds: the filter gates
    /// them, resets its position to the source after `reset_after` fixes, and the outer stage
    /// hands the reset to the guidance, which moves its reference by the same δ (the vehicle
    /// stays where it is; `docs/navigation.md` § A position reset) — once, in the step that
    /// took the reset. Without the hand-over the horizontal reference never moves.
    #[test]
    fn an_absolute_reset_shifts_the_reference_by_its_delta() {
        use crate::app::autopilot::VehicleCommand;
        let Ok(mut c) = Cascade::new(ControllerParams::default()) else { panic!("cascade") };
        let fix_at = |t_us: u64, east: f32| PositionFix {
            t_us,
            position: Vec3::new(0.0, east, 0.0),
            velocity: Vec3::zeros(),
            yaw: Some(0.0),
        };
        let (mut before, mut moves) = (None, Vec::new());
        for k in 1..=4_000u64 {
            let t = k * 1_000;
            if t.is_multiple_of(100_000) {
                let east = if t >= 2_500_000 { 4.0 } else { 0.0 };
                c.navigation_fix(&fix_at(t - 50_000, east), FixKind::Absolute, GPS);
            }
            match t {
                500_000 => assert_eq!(c.command(t, VehicleCommand::Arm), Ok(())),
                600_000 => assert_eq!(c.command(t, VehicleCommand::Takeoff { height_m: Some(1.0) }), Ok(())),
                _ => {}
            }
            c.step_inner(t, &ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) });
            if t.is_multiple_of(4_000) {
                c.update_obstacles(t, &[]);
                c.step_outer(t);
                let r = c.outer().outer().telemetry().reference.position;
                let st = c.outer().navigation().aid().status();
                if let Some((r0, n0)) = before.filter(|_| t > 700_000) {
                    let (moved, r0): (Vec3, Vec3) = (r - r0, r0);
                    if moved.xy().norm() > 1e-6 || st.resets != n0 {
                        moves.push((t, moved, st.resets, st.last_reset_delta, r0));
                    }
                }
                before = Some((r, st.resets));
            }
        }
        // One reset; the horizontal reference moved once, by the reset's delta, in its step.
        assert_eq!(moves.len(), 1, "{moves:?}");
        let (_, moved, resets, delta, _) = moves[0];
        assert_eq!(resets, 1);
        assert!(delta.y > 3.0, "{delta:?}");
        assert!((moved.xy() - delta.xy()).norm() < 1e-5, "reference moved {moved:?}, reset delta {delta:?}");
    }
}

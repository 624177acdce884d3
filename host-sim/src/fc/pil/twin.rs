//! [`FirmwareTwin`]: the firmware's cascade and lockstep sequence on the host,
//! to tell what the ARM build and the link change from what the sequence does.
//!
//! With a `gps` / `rtk` source the twin also runs the firmware's navigation filter
//! (`parapet_core::nav::aid::NavAid`, as `firmware/src/app/navigation.rs` does): each fix as
//! the firmware decodes the GPS_INPUT the link sends ([`super::gcs::gps_input`] →
//! [`super::gcs::gps_input_decoded`]: lat/lon 1e-7 °, the same `wire::geo` conversion), every
//! IMU sample predicted after its inner step with the attitude estimate, and before each outer
//! step an absolute reset handed to the guidance and the filter's estimate given as the fix of
//! now — the firmware's order. It records that fix ([`FirmwareTwin::fixes`]) to compare with
//! the firmware's LOCAL_POSITION_NED. Each barometer height goes with the next step's HIL_SENSOR
//! (`pressure_alt`, [`super::gcs::baro_decoded`]) and is fused before that step, as the
//! firmware's router does on receipt. The filter's error bound
//! ([`parapet_core::nav::bound`], with the barometer's drift once a height is fused, as the
//! firmware's `Navigation::error_bound`) gives the margins
//! as the firmware applies them: the ground/ceiling margin before each outer step, and the
//! mapped obstacle points (the scene's map, sent in LOCAL_NED) moved towards the last outer
//! step's position by that step's bound (once the filter is initialised) when the batch
//! reaches the firmware (`firmware/src/link/obstacles.rs`, the telemetry's `mapped_margin`).
//!
//! May import: `parapet-core` (controller, schedule, wire lockstep rule, navigation filter),
//! [`super::gcs`] (the firmware's parameters, path and start-up timing),
//! [`crate::flight`], [`crate::sim::sensors`], [`crate::sim::battery`] (readings),
//! [`crate::world::scene`].

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::battery::BatteryEstimator;
use parapet_core::controller::{FlightController, PositionFix};
use parapet_core::estimator::ImuSample;
use parapet_core::failsafe::FailsafeState;
use parapet_core::nav::aid::{NavAid, SourceNoise, BARO_SIGMA_M};
use parapet_core::nav::bound::{
    ErrorBound, UnobservedDrift, BARO_DRIFT_M_PER_SQRT_S, VISION_DRIFT_M_PER_SQRT_S,
};
use parapet_core::nav::{FixKind, Fusion, NavParams};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::schedule::OuterSchedule;
use parapet_core::wire::battery::{battery_from_wire, battery_to_wire};
use parapet_core::wire::codes::{odometry_quaternion, odometry_yaw};
use parapet_core::wire::lockstep::{LockstepClock, MotorCommand};
use parapet_core::Vec3;

use super::gcs::{
    baro_decoded, filtered_source, firmware_params, gps_input, gps_input_decoded, preroll_start,
    quantised_path, vio_decoded, vio_odometry, WARMUP_STEPS,
};
use crate::flight::runner::{run_with, RunConfig, RunOutput};
use crate::flight::stack::{clock_us, FlightStack, OuterOut};
use crate::sim::battery::BatteryReading;
use crate::sim::sensors::{ImuReading, PositionReading};
use crate::world::scene::{to_f32, Scene};

/// The pure-host counterpart of [`PilLink`](super::PilLink): the same `parapet-core` `FlightController`, built
/// with the firmware's parameters ([`firmware_params`]), driven with the firmware's lockstep
/// sequence (pre-roll, commands at the previous step's time, obstacle batch closed at the step,
/// inner step before the outer step, fixes with the yaw the firmware decodes from ODOMETRY's
/// quaternion, quantised path, battery readings at the link's mV / cA resolution measured by
/// the firmware's estimator). Flying a scene with
/// this and with `PilLink` isolates what the ARM build and the link change.
pub struct FirmwareTwin {
    fc: FlightController,
    cbf: bool,
    path: Vec<Vector3<f64>>,
    /// The path as the firmware receives it (quantised) and how many of it the controller was
    /// given (a path longer than `PATH_CAPACITY` streams in).
    waypoints: Vec<parapet_core::Vec3>,
    sent: usize,
    n_params: usize,
    pending_obstacles: Option<Vec<ObstaclePoint>>,
    schedule: OuterSchedule,
    clock: LockstepClock,
    last_t_us: u64,
    mission_start_pending: bool,
    /// The firmware's PIL battery measurement (`firmware/src/pil/battery.rs`).
    battery: BatteryEstimator,
    /// The firmware's navigation filter, the kind of its source and the σ the host states
    /// (GPS_INPUT for `gps` / `rtk`, a VIO's ODOMETRY for `vio`).
    nav: Option<(NavAid, FixKind, SourceNoise)>,
    /// The filter's fix given to the outer loop at each outer step (firmware time µs, NED m).
    fixes: Vec<(u64, Vec3)>,
    /// The firmware's `mapped_margin` of the last outer step (module docs).
    mapped_margin: Option<ErrorBound>,
    /// The barometer height (NED down, m) for the next step's HIL_SENSOR (with `gps` / `rtk`).
    baro: Option<f64>,
    /// A height has been fused: the error bound carries the barometer's drift (the
    /// firmware's `Navigation::error_bound`).
    baro_fused: bool,
    /// The magnetometer field for the next step's HIL_SENSOR (`gps`, `rtk`).
    mag: Option<Vec3>,
    /// Its heading, tilt-compensated with the attitude estimate before the step (the
    /// firmware's router), given to the next GPS fix without a yaw.
    mag_heading: Option<(u64, f32)>,
}

impl FirmwareTwin {
    /// Controller with the firmware's parameters for `scene` and `cfg`.
    pub fn new(scene: &Scene, cfg: &RunConfig) -> Result<Self> {
        let (p, updates) = firmware_params(scene, cfg)?;
        let n_params = updates.len();
        let mut fc = FlightController::new(p)
            .map_err(|e| anyhow!("{}", crate::flight::validate::describe_param_error(scene, &p, e)))?;
        // A path longer than the cascade holds streams in after each outer step, as the host's
        // controller does (issue 38; the firmware streams at its link poll, so such a twin is
        // not bit-identical to the firmware).
        let waypoints = quantised_path(&cfg.path);
        let sent = waypoints.len().min(parapet_core::controller::PATH_CAPACITY);
        fc.set_path(&waypoints[..sent])
            .map_err(|e| anyhow!("{}", crate::flight::validate::describe_command_error(e)))?;
        Ok(FirmwareTwin {
            fc,
            cbf: cfg.cbf,
            path: cfg.path.clone(),
            waypoints,
            sent,
            n_params,
            pending_obstacles: None,
            schedule: OuterSchedule::new(&p),
            clock: OuterSchedule::new(&p).clock(),
            last_t_us: 0,
            mission_start_pending: false,
            battery: BatteryEstimator::new(p.battery),
            nav: filtered_source(cfg).map(|(k, n)| (NavAid::new(NavParams::default()), k, n)),
            fixes: Vec::new(),
            mapped_margin: None,
            baro: None,
            baro_fused: false,
            mag: None,
            mag_heading: None,
        })
    }

    /// The navigation filter's fix of each outer step (firmware time µs, NED m); empty without
    /// a `gps` / `rtk` source.
    pub fn fixes(&self) -> &[(u64, Vec3)] {
        &self.fixes
    }

    fn fix(&mut self, t_us: u64, fix: &PositionReading) {
        if let Some((nav, kind, noise)) = self.nav.as_mut() {
            // The message the link sends, as the firmware decodes it.
            if *kind == FixKind::Relative {
                let (f, stated) = vio_decoded(&vio_odometry(t_us, fix, *noise), *noise);
                let _ = nav.fix(&f, stated, FixKind::Relative);
            } else if let Some(f) = gps_input(t_us, fix, *noise).as_ref().and_then(gps_input_decoded) {
                let yaw = f.yaw.or(parapet_core::nav::mag::fresh_heading(self.mag_heading, t_us));
                let f = PositionFix { yaw, ..f };
                let _ = nav.fix(&f, *noise, FixKind::Absolute);
            }
            return;
        }
        self.fc.update_position(PositionFix {
            t_us,
            position: to_f32(&fix.position),
            velocity: to_f32(&fix.velocity),
            // What the firmware feeds its estimator: the yaw of the ODOMETRY quaternion the
            // PIL link sends (`gcs::odometry`).
            yaw: odometry_yaw(odometry_quaternion(fix.yaw as f32)),
        });
    }

    fn obstacles(&mut self, obstacles: &[ObstaclePoint]) {
        self.pending_obstacles = Some(if self.cbf { obstacles.to_vec() } else { Vec::new() });
    }

    /// The firmware's margin on the map's points (module docs): each point moved towards the
    /// last outer step's position by that step's bound.
    fn mapped_margin(&self, points: &mut [ObstaclePoint]) {
        let Some(b) = self.mapped_margin else { return };
        let p = self.fc.outer().telemetry().position;
        for o in points.iter_mut() {
            o.point = b.shift_mapped(&o.point, &p);
        }
    }

    /// The firmware's lockstep step (`parapet_core::wire::lockstep`): close the obstacle
    /// batch, inner step, outer step when the lockstep clock says so, sanitised motors.
    fn step(&mut self, t_us: u64, imu: &ImuReading) -> [f32; 4] {
        if let Some(mut o) = self.pending_obstacles.take() {
            self.mapped_margin(&mut o);
            self.fc.update_obstacles(t_us, &o);
        }
        // The HIL_SENSOR's magnetometer heading and barometer height, as the firmware's router
        // takes them on receipt, before the step.
        if let Some(b) = self.mag.take() {
            let a = self.fc.inner().estimate().attitude;
            if let Some(h) = parapet_core::nav::mag::heading(&b, a.roll, a.pitch) {
                self.mag_heading = Some((t_us, h));
            }
        }
        if let (Some(down), Some((nav, _, _))) = (self.baro.take(), self.nav.as_mut()) {
            let fused = nav.height(t_us, baro_decoded(down), BARO_SIGMA_M);
            self.baro_fused |= fused == Fusion::Fused;
        }
        let sample = ImuSample { gyro: to_f32(&imu.gyro), accel: to_f32(&imu.accel) };
        let m = self.fc.step_inner(t_us, &sample);
        if let Some((nav, _, _)) = self.nav.as_mut() {
            let _ = nav.imu(t_us, &sample.accel, &self.fc.inner().estimate().attitude);
        }
        if self.clock.tick(t_us).run_outer {
            if let Some((nav, kind, _)) = self.nav.as_mut() {
                if let Some(delta) = nav.take_reset() {
                    self.fc.position_reset(delta);
                }
                if let Some(f) = nav.controller_fix(t_us) {
                    self.fc.update_position(f);
                    self.fixes.push((t_us, f.position));
                }
                let baro = if self.baro_fused { BARO_DRIFT_M_PER_SQRT_S } else { 0.0 };
                // The firmware's `Navigation::error_bound`: a relative source's assumed drift.
                let relative = if *kind == FixKind::Relative { VISION_DRIFT_M_PER_SQRT_S } else { 0.0 };
                let drift = UnobservedDrift { relative, baro };
                let bound = nav.kind().map(|_| nav.error_bound(t_us, &drift));
                if let Some(b) = bound {
                    self.fc.set_boundary_margin(b.vertical as f32);
                }
                self.mapped_margin = bound.filter(|_| nav.filter().is_initialised());
            }
            self.fc.step_outer(t_us);
            if let Some(waiting) = self.waypoints.get(self.sent..).filter(|w| !w.is_empty()) {
                self.sent += self.fc.stream_path(waiting).unwrap_or(0);
            }
        }
        self.last_t_us = t_us;
        MotorCommand { throttle: m.throttle, armed: m.armed }.sanitized().throttle
    }
}

impl FlightStack for FirmwareTwin {
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        let crate::flight::stack::StackStart { t, start, fix, obstacles, imu, .. } = *s;
        let t0 = clock_us(t);
        let (period, div) = (self.schedule.period_us(), self.schedule.divider());
        let t_pre = preroll_start(t0, self.n_params, self.path.len(), &self.schedule);
        // The firmware rebuilds the cascade at each PARAM_SET (processed before the step's
        // HIL_SENSOR): its history starts with the step of the last one. Its outer schedule
        // started at the first pre-roll step.
        let mut tk = t_pre + (self.n_params.max(1) as u64 - 1) * 1000;
        self.clock = self.schedule.clock().with_next_outer(t_pre + (tk - t_pre).div_ceil(period) * period);
        let warmup_from = t0 - (WARMUP_STEPS + div) * 1000;
        while tk < t0 {
            if (t0 - tk).is_multiple_of(period) && tk > warmup_from {
                self.fix(tk, &fix);
                self.obstacles(obstacles);
            }
            if tk == t0 - period {
                let prev = self.last_t_us;
                self.fc
                    .arm(prev)
                    .map_err(|e| anyhow!("{}", crate::flight::validate::describe_command_error(e)))?;
                self.fc.hold_position(prev, to_f32(&start)).map_err(|e| {
                    anyhow!("hold refused: {}", crate::flight::validate::describe_command_error(e))
                })?;
            }
            self.step(tk, imu);
            tk += 1000;
        }
        self.mission_start_pending = true;
        Ok(())
    }

    fn position_fix(&mut self, fix: PositionReading) {
        self.fix(clock_us(fix.t_measured), &fix);
    }

    fn mag_fix(&mut self, _t: f64, field: Vec3) {
        if self.nav.as_ref().is_some_and(|n| n.1 == FixKind::Absolute) {
            self.mag = Some(field);
        }
    }

    fn height_fix(&mut self, _t: f64, down: f64) {
        if self.nav.is_some() {
            self.baro = Some(down);
        }
    }

    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        self.obstacles(obstacles);
        if self.mission_start_pending {
            self.mission_start_pending = false;
            let _ = self.fc.start_mission(self.last_t_us);
        }
        let _ = t;
        OuterOut::from_telemetry(&self.fc.telemetry())
    }

    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        self.step(clock_us(t), imu)
    }

    fn state_name(&self) -> String {
        format!("{:?}", self.fc.state())
    }

    /// The reading as the link carries it (mV, cA), measured at the step's time as the
    /// firmware's PIL battery input measures it.
    fn battery(&mut self, t: f64, r: &BatteryReading) {
        let (v, i) = battery_from_wire(battery_to_wire(r.voltage_v, r.current_a));
        let armed = self.fc.state() != FailsafeState::Disarmed;
        let s = self.battery.update(clock_us(t), v, i, armed).state();
        self.fc.set_battery(&s);
    }
}

/// Fly `scene` with the [`FirmwareTwin`] (pure host, firmware parameters and sequence).
pub fn run_twin(scene: &Scene, cfg: &RunConfig) -> Result<RunOutput> {
    Ok(run_twin_with_fixes(scene, cfg)?.0)
}

/// [`run_twin`], with the navigation filter's fix of each outer step ([`FirmwareTwin::fixes`]).
pub fn run_twin_with_fixes(scene: &Scene, cfg: &RunConfig) -> Result<(RunOutput, Vec<(u64, Vec3)>)> {
    let mut twin = FirmwareTwin::new(scene, cfg)?;
    let out = run_with(scene, cfg, &mut twin, &mut |_| {})?;
    Ok((out, twin.fixes))
}

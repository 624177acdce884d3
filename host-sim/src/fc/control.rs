//! Adapter between the runner and [`parapet_core::controller::FlightController`]:
//! f64 simulator types ↔ f32 core types, simulator time ↔ controller clock,
//! and the start-up sequence.
//!
//! * **Clock**: [`crate::flight::stack::clock_us`].
//! * **Start-up** (at t = 0, vehicle hovering at the start): one IMU sample
//!   initialises the estimator, a position fix and the obstacle report are
//!   given, then `arm`, `hold_position(start)`, one outer step (the reference
//!   becomes the start) and `start_mission`.
//! * **Position fixes** carry the time they were measured (so the controller's
//!   latency compensation by extrapolation applies) and the true yaw (a motion
//!   capture system measures it).
//! * **`--no-cbf`**: the controller is told that no obstacle is in range (an
//!   empty report), so its filter passes the nominal input through unchanged
//!   (region "none"). The controller itself is the same.
//!
//! May import: `parapet-core`, [`crate::flight`] (run settings, the loop, `FlightStack`),
//! [`crate::sim::sensors`] (readings), [`crate::world::scene`].

use anyhow::{anyhow, Result};
use nalgebra::Vector3;
use parapet_core::battery::BatteryEstimator;
use parapet_core::cbf::CbfParams;
use parapet_core::controller::{CommandError, ControllerParams, FlightController, PositionFix, Telemetry};
use parapet_core::estimator::ImuSample;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;

use crate::fc::nav::NavAid;
use crate::flight::runner::{controller_params, run_with, RunConfig, RunOutput};
use crate::flight::stack::{clock_us, FlightStack, OuterOut};
use crate::sim::battery::BatteryReading;
use crate::sim::sensors::{ImuReading, PositionReading};
use crate::world::scene::{to_f32, Scene};

/// The flight controller as the runner drives it.
pub struct Controller {
    fc: FlightController,
    cbf: bool,
    /// The battery estimator fed by the simulated pack (`[battery]`), as the F405's ADC task.
    battery: BatteryEstimator,
    /// The navigation filter of a filtered position source (`None`: motion capture).
    nav: Option<NavAid>,
    /// The on-board replanner (`RPL_*`; issue 38), run after each outer step.
    replan: crate::fc::replan::OnboardReplan,
    /// The whole path (NED) and how many of its waypoints the controller was given: a path
    /// longer than `PATH_CAPACITY` streams in windows (`parapet_core::outer::path_stream`).
    path: Vec<Vec3>,
    sent: usize,
}

impl Controller {
    /// Build the controller and give it the path. Errors name the rejected parameter or path.
    pub fn new(scene: &Scene, cfg: &RunConfig, cbf: CbfParams) -> Result<Self> {
        Self::with_params(scene, cfg, controller_params(scene, cfg, cbf, cfg.variant))
    }

    /// [`new`](Self::new) with explicit controller parameters (e.g. [`controller_params`]
    /// with a slowed attitude loop, for tests).
    pub fn with_params(scene: &Scene, cfg: &RunConfig, params: ControllerParams) -> Result<Self> {
        let mut fc = FlightController::new(params)
            .map_err(|e| anyhow!("{}", crate::flight::validate::describe_param_error(scene, &params, e)))?;
        let wps: Vec<Vec3> = cfg.path.iter().map(to_f32).collect();
        let sent = wps.len().min(parapet_core::controller::PATH_CAPACITY);
        // The rest streams in as the mission is flown (`stream_path`).
        fc.set_path(&wps[..sent]).map_err(|e| {
            anyhow!("path rejected by the controller: {}", crate::flight::validate::describe_command_error(e))
        })?;
        let nav = NavAid::for_sensors(&cfg.sensors);
        let (lo, hi) = scene.bounds_ned();
        let area = ([lo.x as f32, lo.y as f32], [hi.x as f32, hi.y as f32]);
        let replan = crate::fc::replan::OnboardReplan::new(&fc, area);
        let battery = BatteryEstimator::new(params.battery);
        Ok(Controller { fc, cbf: cfg.cbf, battery, nav, replan, path: wps, sent })
    }

    /// The next waypoints of a path longer than the controller holds, when a refill is due
    /// (`FlightController::stream_path`).
    fn stream_path(&mut self) {
        let waiting = self.path.get(self.sent..).unwrap_or(&[]);
        if !waiting.is_empty() {
            self.sent += self.fc.stream_path(waiting).unwrap_or(0);
        }
    }

    fn report_obstacles(&mut self, now: u64, obstacles: &[ObstaclePoint]) {
        if self.cbf {
            self.fc.update_obstacles(now, obstacles);
        } else {
            self.fc.update_obstacles(now, &[]);
        }
    }

    /// Latest telemetry.
    pub fn telemetry(&self) -> Telemetry {
        self.fc.telemetry()
    }

    /// The controller (read-only).
    pub fn fc(&self) -> &FlightController {
        &self.fc
    }

    /// The navigation filter, with a filtered position source.
    pub fn nav(&self) -> Option<&NavAid> {
        self.nav.as_ref()
    }

    /// The controller, for commands besides the start-up (pilot input, `crate::pilot`).
    pub fn fc_mut(&mut self) -> &mut FlightController {
        &mut self.fc
    }
}

impl FlightStack for Controller {
    /// Start-up at simulated time `t` (see the module docs).
    fn start(&mut self, s: &crate::flight::stack::StackStart<'_>) -> Result<()> {
        let crate::flight::stack::StackStart { t, start, warmup, fix, obstacles, imu } = *s;
        let now = clock_us(t);
        self.inner(t, imu);
        for f in warmup {
            self.position_fix(*f);
        }
        self.position_fix(fix);
        self.outer_fix(now);
        self.report_obstacles(now, obstacles);
        self.fc.arm(now).map_err(|e| match e {
            CommandError::Arm(r) => anyhow!("the flight controller refused to arm at the start: {r}"),
            other => anyhow!(
                "the flight controller refused to arm at the start: {}",
                crate::flight::validate::describe_command_error(other)
            ),
        })?;
        self.fc
            .hold_position(now, to_f32(&start))
            .map_err(|e| anyhow!("hold refused: {}", crate::flight::validate::describe_command_error(e)))?;
        self.fc.step_outer(now);
        self.fc.start_mission(now).map_err(|e| {
            anyhow!("mission start refused: {}", crate::flight::validate::describe_command_error(e))
        })?;
        Ok(())
    }

    /// A position/velocity/yaw fix (measured at `fix.t_measured`).
    fn position_fix(&mut self, fix: PositionReading) {
        if let Some(nav) = self.nav.as_mut() {
            nav.fix(clock_us(fix.t_measured), &fix);
            return;
        }
        self.fc.update_position(PositionFix {
            t_us: clock_us(fix.t_measured),
            position: to_f32(&fix.position),
            velocity: to_f32(&fix.velocity),
            yaw: Some(fix.yaw as f32),
        });
    }

    /// One outer step at simulated time `t` with the obstacles the proximity sensor reports.
    fn outer(&mut self, t: f64, obstacles: &[ObstaclePoint]) -> OuterOut {
        let now = clock_us(t);
        self.outer_fix(now);
        self.report_obstacles(now, obstacles);
        self.fc.step_outer(now);
        if self.cbf {
            self.replan.step(t, now, &mut self.fc);
        }
        self.stream_path();
        OuterOut::from_telemetry(&self.fc.telemetry())
    }

    /// One inner step at simulated time `t`: IMU in, throttles out.
    fn inner(&mut self, t: f64, imu: &ImuReading) -> [f32; 4] {
        let (now, sample) = (clock_us(t), imu_sample(imu));
        let out = self.fc.step_inner(now, &sample);
        if let Some(nav) = self.nav.as_mut() {
            nav.imu(now, &sample.accel, &self.fc.inner().estimate().attitude);
        }
        out.throttle
    }

    fn navigation(&self, t: f64) -> Option<(Vector3<f64>, crate::flight::sensing::ErrorBound)> {
        let nav = self.nav.as_ref()?;
        let (p, _) = nav.estimate(clock_us(t))?;
        Some((Vector3::new(p.x as f64, p.y as f64, p.z as f64), nav.error_bound(clock_us(t))))
    }

    fn height_fix(&mut self, t: f64, down: f64) {
        if let Some(nav) = self.nav.as_mut() {
            nav.height(clock_us(t), down);
        }
    }

    fn state_name(&self) -> String {
        format!("{:?}", self.fc.state())
    }

    fn replan_summary(&self) -> crate::report::ReplanSummary {
        self.replan.summary()
    }

    fn replans(&self) -> u32 {
        self.replan.replans()
    }

    /// The path flown now and the waypoints of a streamed path not given to the controller yet.
    fn mission(&self) -> Option<(Vec<Vector3<f64>>, u16)> {
        let waiting = self.path.get(self.sent..).unwrap_or(&[]);
        let path =
            self.fc.path().iter().chain(waiting).map(|w| Vector3::new(w.x as f64, w.y as f64, w.z as f64));
        let path = path.collect();
        use parapet_core::replan::onboard::MissionControl;
        Some((path, self.fc.outer_telemetry().progress.segment))
    }

    /// A reading of the simulated pack: the estimator (as the F405's ADC task runs it) and
    /// the controller's battery failsafes (Low → Return, Critical → Land).
    fn battery(&mut self, t: f64, r: &BatteryReading) {
        let armed = self.fc.state() != parapet_core::failsafe::FailsafeState::Disarmed;
        let s = self.battery.update(clock_us(t), r.voltage_v, r.current_a, armed).state();
        self.fc.set_battery(&s);
    }
}

impl Controller {
    /// With a filtered source, hand the filter's estimate to the controller as its fix of
    /// `now` (none in the navigation failsafe, `crate::fc::nav`).
    fn outer_fix(&mut self, now: u64) {
        if let Some(delta) = self.nav.as_mut().and_then(NavAid::take_reset) {
            self.fc.position_reset(delta);
        }
        if let Some(fix) = self.nav.as_ref().and_then(|n| n.controller_fix(now)) {
            self.fc.update_position(fix);
        }
        // The ground and ceiling are world planes: they get the vertical error bound.
        if let Some(nav) = self.nav.as_ref() {
            self.fc.set_boundary_margin(nav.error_bound(now).vertical as f32);
        }
    }
}

fn imu_sample(imu: &ImuReading) -> ImuSample {
    ImuSample { gyro: to_f32(&imu.gyro), accel: to_f32(&imu.accel) }
}

/// Fly `scene` with `cfg` and the in-process [`Controller`] (`parapet-core`'s
/// `FlightController`). `progress` is called with the simulated time (s) about
/// 10 times per simulated second.
pub fn run(scene: &Scene, cfg: &RunConfig, progress: &mut dyn FnMut(f64)) -> Result<RunOutput> {
    let cbf = cfg.cbf_params()?;
    let mut ctrl = Controller::new(scene, cfg, cbf)?;
    run_with(scene, cfg, &mut ctrl, progress)
}

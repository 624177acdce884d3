//! The flight logger: turns telemetry samples into ULog records in a [`LogStore`], from arming
//! to disarming, at a bounded rate.
//!
//! - **When**: a log starts on the first armed sample (header, formats, infos, every parameter
//!   of the table, subscriptions) and ends on the first disarmed one (which is still written,
//!   so the log shows the disarm). Samples while disarmed cost one comparison.
//! - **Rate**: one record set per `period_us` (default [`DEFAULT_PERIOD_US`] = 25 Hz); samples in
//!   between are skipped (counted). Six records of ≤ 66 bytes each per set, so a set is
//!   ≈ 320 bytes: 8 KB/s at 25 Hz.
//! - **Bounded work**: a sample writes at most one record set (6 messages), the first one also
//!   the definitions (6 formats, 3 infos, `parapet_core::params::COUNT` parameters).
//! - **Replanner events** (issue 38): each event of the on-board replanner seen in a written
//!   sample is a logged string (ULog `L`, INFO for a new path, WARNING for no path), worded as
//!   its STATUSTEXT (`crate::app::replanner::event_text`).
//! - **Errors**: a store error is counted; [`LogError::Full`] stops the log's records (the
//!   log stays readable up to there, `truncated`).
//!
//! Topics and records are the host simulator's `flight.ulg` ones, defined once in
//! `parapet_core::wire::log_topics` (so the same tools plot both); the onboard log has no ground
//! truth, so `cbf_status.h_bar` (true h̄) and `clearance` are NaN and `vehicle_local_position`
//! is the estimate.
//!
//! May import: [`crate::log::ulog`], [`crate::log::store`], [`crate::app::autopilot`]
//! (the telemetry snapshot), [`crate::app::replanner`] (the events' text), `parapet_core` (parameters, thrust map, the ULog writer).

use parapet_core::controller::ControllerParams;
use parapet_core::thrust::{map_acceleration, ThrustParams};
use parapet_core::wire::log_topics::{write_definitions, write_records, FlightRecord};

use crate::app::autopilot::TelemetrySnapshot;
use crate::app::replanner::event_text;
use crate::log::store::{Appender, LogStore};
use crate::log::ulog::LogError;
use parapet_core::replan::ReplanOutcome;
use parapet_core::wire::ulog::write_logging;

/// Default record period, µs (25 Hz).
pub const DEFAULT_PERIOD_US: u64 = 40_000;

/// One telemetry sample for the log (what a control task sends to the log task).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogSample {
    /// Firmware time, µs.
    pub t_us: u64,
    /// The cascade's state after the step.
    pub snapshot: TelemetrySnapshot,
    /// Motor throttles 0..1 of rotors 1-4 (PX4 numbering, `parapet_core::airframe`).
    pub motors: [f32; 4],
}

/// Logger counters (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoggerStats {
    /// Logs started.
    pub logs: u32,
    /// Record sets written.
    pub records: u32,
    /// Armed samples skipped by the rate limit.
    pub skipped: u32,
    /// Store writes that failed.
    pub store_errors: u32,
    /// The current (or last) log was cut because the store was full.
    pub truncated: bool,
}

/// PX4 quaternion (w, x, y, z), body FRD → NED, of ZYX Euler angles (`quat_from_euler`: the
/// sines of `libm::sincosf`, which this function called itself before, bit for bit).
pub fn quat(roll: f32, pitch: f32, yaw: f32) -> [f32; 4] {
    let q = parapet_core::frame::quat_from_euler(roll, pitch, yaw);
    [q.w, q.i, q.j, q.k]
}

/// The logger state (see the module doc).
pub struct FlightLogger {
    period_us: u64,
    next_us: u64,
    logging: bool,
    thrust: ThrustParams,
    mass: f32,
    board: &'static str,
    stats: LoggerStats,
    /// The replanner's event count last logged.
    replan_events: u16,
}

impl FlightLogger {
    /// A logger writing one record set per `period_us` (≥ 1), with the thrust map of `params`
    /// (for the attitude setpoint), naming `board` in the log's `parapet_board` info.
    pub fn new(period_us: u64, params: &ControllerParams, board: &'static str) -> Self {
        Self {
            period_us: period_us.max(1),
            next_us: 0,
            logging: false,
            thrust: params.thrust,
            mass: params.airframe.mass,
            board,
            stats: LoggerStats::default(),
            replan_events: 0,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LoggerStats {
        self.stats
    }

    /// `true` while a log is being written.
    pub fn logging(&self) -> bool {
        self.logging
    }

    fn count(&mut self, r: Result<(), LogError>) -> bool {
        match r {
            Ok(()) => true,
            Err(e) => {
                self.stats.store_errors = self.stats.store_errors.saturating_add(1);
                if e == LogError::Full {
                    self.stats.truncated = true;
                }
                false
            }
        }
    }

    /// Handles one sample; `param` gives the current value of a parameter by name (written
    /// once, at the log's start).
    pub fn on_sample<S: LogStore>(
        &mut self,
        s: &LogSample,
        store: &mut S,
        mut param: impl FnMut(&str) -> Option<f32>,
    ) {
        let armed = s.snapshot.armed;
        if !self.logging {
            if !armed {
                return;
            }
            self.stats.truncated = false;
            let started = store.begin(0).map(|_| ());
            if !self.count(started) {
                return;
            }
            self.logging = true;
            self.stats.logs = self.stats.logs.saturating_add(1);
            let r = self.definitions(s.t_us, store, &mut param);
            self.count(r);
            self.next_us = s.t_us;
        }
        if armed && s.t_us < self.next_us {
            self.stats.skipped = self.stats.skipped.saturating_add(1);
            return;
        }
        if !self.stats.truncated {
            let r = self.records(s, store);
            if self.count(r) {
                self.stats.records = self.stats.records.saturating_add(1);
            }
            let r = self.replan_event(s, store);
            self.count(r);
        }
        self.next_us = s.t_us.saturating_add(self.period_us);
        if !armed {
            store.end();
            self.logging = false;
        }
    }

    fn definitions<S: LogStore>(
        &self,
        t0_us: u64,
        store: &mut S,
        param: &mut impl FnMut(&str) -> Option<f32>,
    ) -> Result<(), LogError> {
        let params = parapet_core::params::TABLE.iter().filter_map(|p| Some((p.name, param(p.name)?)));
        let infos = [("parapet_board", self.board)];
        write_definitions(&mut Appender(store), t0_us, env!("CARGO_PKG_VERSION"), infos, params)
    }

    /// The replanner's latest event as a logged string, once (module docs).
    fn replan_event<S: LogStore>(&mut self, s: &LogSample, store: &mut S) -> Result<(), LogError> {
        let r = s.snapshot.replan;
        if r.events == self.replan_events {
            return Ok(());
        }
        self.replan_events = r.events;
        let Some(e) = r.last else { return Ok(()) };
        let mut buf = [0u8; 50];
        let n = event_text(&e, &mut buf);
        let text = core::str::from_utf8(buf.get(..n).unwrap_or(&[])).unwrap_or("Replan");
        let level = if matches!(e.outcome, ReplanOutcome::Replanned { .. }) { b'6' } else { b'4' };
        write_logging(&mut Appender(store), level, s.t_us, text)
    }

    fn records<S: LogStore>(&self, s: &LogSample, store: &mut S) -> Result<(), LogError> {
        let t = &s.snapshot;
        let [roll, pitch, yaw] = [t.attitude_rpy.x, t.attitude_rpy.y, t.attitude_rpy.z];
        let (p, v) = (t.position_ned, t.velocity_ned);
        let u = t.setpoint.accel_filtered_ned;
        let sp = map_acceleration(&self.thrust, self.mass, &u, yaw, roll, pitch);
        let thrust_norm = if self.thrust.thrust_max > 0.0 { sp.thrust / self.thrust.thrust_max } else { 0.0 };
        let un = t.setpoint.accel_nominal_ned;
        let r = FlightRecord {
            t_us: s.t_us,
            position: [p.x, p.y, p.z],
            velocity: [v.x, v.y, v.z],
            heading: yaw,
            attitude_q: quat(roll, pitch, yaw),
            setpoint_rpy: [sp.roll, sp.pitch, sp.yaw],
            setpoint_q: quat(sp.roll, sp.pitch, sp.yaw),
            thrust_norm,
            motors: s.motors,
            armed: t.armed,
            guidance: t.guidance,
            mode: t.mode,
            h_bar_true: f32::NAN,
            clearance: f32::NAN,
            filter: t.filter,
            u_nominal: [un.x, un.y, un.z],
            u: [u.x, u.y, u.z],
            // NaN without a limit, as the host's log (`host-sim/src/report/ulog.rs`).
            governor_limit: if t.governor_limit.is_finite() { t.governor_limit } else { f32::NAN },
            governor_cause: t.governor_cause,
        };
        write_records(&mut Appender(store), &r)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::log::store::RamRing;
    use parapet_core::controller::GuidanceMode;
    use parapet_core::wire::codes::FlightPhase;
    use parapet_core::Vec3;

    /// (type, payload) of every message after the 16-byte header.
    fn parse(bytes: &[u8]) -> std::vec::Vec<(u8, &[u8])> {
        parapet_core::wire::ulog::messages(bytes).expect("ULog magic").collect()
    }

    pub(crate) fn sample(t_us: u64, armed: bool) -> LogSample {
        let mut snapshot = TelemetrySnapshot::BOOT;
        snapshot.armed = armed;
        snapshot.phase = if armed { FlightPhase::Hover } else { FlightPhase::Disarmed };
        snapshot.guidance = if armed { GuidanceMode::Hold } else { GuidanceMode::Off };
        snapshot.position_ned = Vec3::new(1.0, 2.0, -(t_us as f32) * 1e-6);
        snapshot.attitude_rpy = Vec3::new(0.0, 0.0, 0.5);
        LogSample { t_us, snapshot, motors: [0.4, 0.41, 0.42, 0.43] }
    }

    #[test]
    fn logs_from_arming_to_disarming_at_the_rate() {
        let params = ControllerParams::default();
        let mut lg = FlightLogger::new(40_000, &params, "test");
        let mut store: RamRing<16384, 4> = RamRing::new();
        let get = |n: &str| parapet_core::params::get(&params, n);
        for k in 0..10 {
            lg.on_sample(&sample(k * 4000, false), &mut store, get);
        }
        assert_eq!(store.count(), 0);
        // 1 s armed at 250 Hz, then disarmed.
        for k in 0..250 {
            lg.on_sample(&sample(1_000_000 + k * 4000, true), &mut store, get);
        }
        lg.on_sample(&sample(2_000_000, false), &mut store, get);
        lg.on_sample(&sample(2_004_000, false), &mut store, get);
        let st = lg.stats();
        assert_eq!(st.logs, 1);
        assert_eq!(st.records, 25 + 1, "25 Hz for 1 s and the disarm sample");
        assert_eq!(st.skipped, 250 - 25);
        assert_eq!(st.store_errors, 0);
        assert!(!store.is_open() && !lg.logging());
        assert_eq!(store.count(), 1);
        let mut bytes = std::vec![0u8; store.info(0).unwrap().size as usize];
        let id = store.info(0).unwrap().id;
        assert_eq!(store.read(id, 0, &mut bytes), Ok(bytes.len()));
        let msgs = parse(&bytes);
        let n = |ty: u8| msgs.iter().filter(|m| m.0 == ty).count();
        assert_eq!((n(b'F'), n(b'A'), n(b'D')), (6, 6, 6 * 26));
        assert_eq!(n(b'P'), parapet_core::params::COUNT);
    }

    /// The speed governor's limit and cause reach `cbf_status` (they were NaN / 0 until the
    /// telemetry snapshot carried them): a distinctive limit's bytes and its cause's code follow
    /// each other in the logged records, and a log without a limit has none of them.
    #[test]
    fn the_governor_limit_reaches_the_log() {
        let params = ControllerParams::default();
        let log_with = |limit: f32, cause: u8| {
            let mut lg = FlightLogger::new(4000, &params, "test");
            let mut store: RamRing<16384, 4> = RamRing::new();
            for k in 0..5 {
                let mut s = sample(1_000_000 + k * 4000, true);
                s.snapshot.governor_limit = limit;
                s.snapshot.governor_cause = cause;
                lg.on_sample(&s, &mut store, |n| parapet_core::params::get(&params, n));
            }
            lg.on_sample(&sample(2_000_000, false), &mut store, |_| None);
            let info = store.info(0).unwrap();
            let mut bytes = std::vec![0u8; info.size as usize];
            assert_eq!(store.read(info.id, 0, &mut bytes), Ok(bytes.len()));
            bytes
        };
        let mut want = 2.375f32.to_le_bytes().to_vec();
        want.push(3);
        let has = |bytes: &[u8]| {
            parse(bytes).iter().filter(|m| m.0 == b'D').any(|m| m.1.windows(5).any(|w| w == want.as_slice()))
        };
        assert!(has(&log_with(2.375, 3)));
        assert!(!has(&log_with(f32::INFINITY, 3)));
    }

    #[test]
    fn a_full_store_truncates_the_log_and_counts() {
        let params = ControllerParams::default();
        let mut lg = FlightLogger::new(1, &params, "test");
        let mut store: RamRing<4096, 4> = RamRing::new();
        for k in 0..100 {
            lg.on_sample(&sample(k * 4000, true), &mut store, |_| Some(1.0));
        }
        let st = lg.stats();
        assert!(st.truncated && st.store_errors > 0 && st.records < 100);
        assert!(store.info(0).unwrap().size <= 4096);
        lg.on_sample(&sample(500_000, false), &mut store, |_| None);
        assert!(!store.is_open());
    }

    /// The venv's python with pyulog (`PARAPET_PYTHON`, else `target/venv/bin/python`), or
    /// `None`: SKIP loudly — except with `CI` or `PARAPET_PYTHON` set, where it fails.
    fn python() -> Option<std::path::PathBuf> {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let env = std::env::var_os("PARAPET_PYTHON").map(std::path::PathBuf::from);
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(std::path::PathBuf::from)
            .unwrap_or_else(|| root.join("target"));
        let py = env.clone().unwrap_or_else(|| target.join("venv/bin/python"));
        let ok = std::process::Command::new(&py)
            .args(["-c", "import pyulog"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Some(py);
        }
        let ci = std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "0" && v != "false");
        assert!(!ci && env.is_none(), "no python with pyulog at {} (cargo xtask venv)", py.display());
        std::eprintln!(
            "\n*** SKIP: no python with pyulog at {} (cargo xtask venv): pyulog NOT RUN ***\n",
            py.display()
        );
        None
    }

    #[test]
    fn pyulog_reads_the_onboard_log() {
        let params = ControllerParams::default();
        let mut lg = FlightLogger::new(DEFAULT_PERIOD_US, &params, "host-test");
        let mut store: RamRing<65536, 4> = RamRing::new();
        // 2 s armed at the 250 Hz outer rate, then the disarm sample.
        for k in 0..500u64 {
            lg.on_sample(&sample(3_000_000 + k * 4000, true), &mut store, |n| {
                parapet_core::params::get(&params, n)
            });
        }
        lg.on_sample(&sample(5_000_000, false), &mut store, |_| None);
        assert_eq!(lg.stats().store_errors, 0);
        let info = store.info(0).expect("one log");
        let mut bytes = std::vec![0u8; info.size as usize];
        assert_eq!(store.read(info.id, 0, &mut bytes), Ok(bytes.len()));
        check_with_pyulog(&bytes, "onboard", &["25", "51", "1", "2"], "ok: 51 records");
    }

    /// The log's `vehicle_status.nav_state` is PX4's for every flight and guidance mode, read
    /// with pyulog (`tests/python/check_ulog_modes.py`, PX4's numbers written there on their
    /// own): Position 2 → Return 5 → Land 18, Mission 3, Offboard 14, Manual 0, takeoff 17, hold 4.
    #[test]
    fn pyulog_reads_px4_s_nav_state_for_every_mode() {
        use parapet_core::supervisor::modes::FlightMode as F;
        let steps = [
            (GuidanceMode::Ground, F::Mission),
            (GuidanceMode::Takeoff, F::Mission),
            (GuidanceMode::Mission, F::Mission),
            (GuidanceMode::Hold, F::Hold),
            (GuidanceMode::Assist, F::Position),
            (GuidanceMode::Return, F::Return),
            (GuidanceMode::Land, F::Return),
            (GuidanceMode::Offboard, F::Offboard),
            (GuidanceMode::Brake, F::Offboard),
            (GuidanceMode::Manual, F::Manual),
            (GuidanceMode::NoFix, F::Land),
        ];
        let params = ControllerParams::default();
        let mut lg = FlightLogger::new(DEFAULT_PERIOD_US, &params, "host-test");
        let mut store: RamRing<65536, 4> = RamRing::new();
        let mut t = 1_000_000u64;
        for (g, m) in steps {
            for _ in 0..20 {
                let mut s = sample(t, true);
                (s.snapshot.guidance, s.snapshot.mode) = (g, m);
                lg.on_sample(&s, &mut store, |n| parapet_core::params::get(&params, n));
                t += 10_000;
            }
        }
        lg.on_sample(&sample(t, false), &mut store, |_| None);
        let info = store.info(0).expect("one log");
        let mut bytes = std::vec![0u8; info.size as usize];
        assert_eq!(store.read(info.id, 0, &mut bytes), Ok(bytes.len()));
        run_pyulog_script(
            &bytes,
            "modes",
            "check_ulog_modes.py",
            &["3,17,3,4,2,5,18,14,4,0,12"],
            "nav_state",
        );
    }

    /// Runs `tests/python/check_onboard_ulog.py FILE ARGS` on `bytes` (a ULog) and asserts it
    /// passes and prints `expect` (skipped loudly without a python with pyulog, see [`python`]).
    pub(crate) fn check_with_pyulog(bytes: &[u8], name: &str, args: &[&str], expect: &str) {
        run_pyulog_script(bytes, name, "check_onboard_ulog.py", args, expect);
    }

    /// Runs `tests/python/SCRIPT FILE ARGS` on `bytes` (a ULog) and asserts it passes and prints
    /// `expect` (skipped loudly without a python with pyulog, see [`python`]).
    fn run_pyulog_script(bytes: &[u8], name: &str, script: &str, args: &[&str], expect: &str) {
        let Some(py) = python() else { return };
        let dir =
            std::env::temp_dir().join(std::format!("parapet-onboard-ulog-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("onboard.ulg");
        std::fs::write(&path, bytes).expect("write log");
        let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/python").join(script);
        let out =
            std::process::Command::new(py).arg(script).arg(&path).args(args).output().expect("run python");
        let text = std::string::String::from_utf8_lossy(&out.stdout).into_owned()
            + &std::string::String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "pyulog check failed:\n{text}");
        assert!(text.contains(expect), "{text}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn quaternion_is_body_to_ned() {
        let q = quat(0.0, 0.0, core::f32::consts::FRAC_PI_2);
        assert!((q[0] - q[3]).abs() < 1e-6 && q[1].abs() < 1e-7 && q[2].abs() < 1e-7 && q[3] > 0.0);
    }
}

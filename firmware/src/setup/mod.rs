//! Pre-flight setup services behind three MAVLink commands, independent of the dialect (the
//! router passes the COMMAND_LONG / COMMAND_INT id and params, and sends the [`SetupAck`] and the
//! queued STATUSTEXTs):
//!
//! | command | id | what |
//! |---|---|---|
//! | `MAV_CMD_PREFLIGHT_STORAGE` | 245 | param1 0 read the stored parameters, 1 write them, 2 reset to defaults; queued for the storage task ([`Setup::take_storage`]) |
//! | `MAV_CMD_PREFLIGHT_CALIBRATION` | 241 | param1 1 gyro (stillness check: the estimator learns the bias), param5 1 accelerometer six-position, param5 2 level horizon; all params 0 cancels |
//! | `MAV_CMD_DO_MOTOR_TEST` | 209 | [`parapet_core::motor_test`]; every other command stops a running test |
//!
//! Everything here is refused while armed (ACK DENIED plus a STATUSTEXT saying why).
//! Calibration results are written through [`parapet_core::params::set`] (so they are range
//! checked like a PARAM_SET) and schedule a save ([`crate::storage::SaveSchedule`]).
//!
//! The STATUSTEXT queue holds [`TEXT_QUEUE_LEN`] texts; when full the oldest is dropped and
//! counted ([`Setup::texts_dropped`]): the newest calibration state is the one that matters.
//! Every function is bounded (no loops over unbounded data).
//!
//! Owns [`Setup`], [`SetupAck`], [`StorageRequest`], [`Text`]. May import `parapet_core` and
//! [`crate::storage`] (the save schedule) only.

use crate::storage::SaveSchedule;
use heapless::{Deque, String};
use parapet_core::calibration::accel::{AccelCalibrator, CalEvent, CalParams};
use parapet_core::calibration::{level_trim, ImuCorrection};
use parapet_core::config::ControllerParams;
use parapet_core::motor_test::{MotorTest, MotorTestRequest, MAX_MOTORS};
use parapet_core::msg::ImuSample;
use parapet_core::params;
use parapet_core::Vec3;

/// MAV_CMD_DO_MOTOR_TEST.
pub const CMD_DO_MOTOR_TEST: u16 = 209;
/// MAV_CMD_PREFLIGHT_CALIBRATION.
pub const CMD_PREFLIGHT_CALIBRATION: u16 = 241;
/// MAV_CMD_PREFLIGHT_STORAGE.
pub const CMD_PREFLIGHT_STORAGE: u16 = 245;
/// STATUSTEXTs kept for the link.
pub const TEXT_QUEUE_LEN: usize = 8;
/// Averaging time of the gyro and level checks, µs.
pub const STILL_TIME_US: u64 = 2_000_000;
/// Largest rate during the gyro / level checks, rad/s.
pub const STILL_RATE_MAX: f32 = 0.05;

/// One STATUSTEXT (MAVLink's 50 bytes).
pub type Text = String<50>;

/// How to answer a command (COMMAND_ACK `result`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupAck {
    /// MAV_RESULT_ACCEPTED.
    Accepted,
    /// MAV_RESULT_DENIED (armed, or a value out of range; the reason is queued as a text).
    Denied,
    /// MAV_RESULT_UNSUPPORTED (a calibration or mode this firmware does not have).
    Unsupported,
    /// MAV_RESULT_TEMPORARILY_REJECTED (another calibration or storage request is running).
    TemporarilyRejected,
}

/// What the storage task is asked to do (PREFLIGHT_STORAGE param1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StorageRequest {
    /// 0: read the stored set into the parameters.
    Read,
    /// 1: write the parameters now.
    Write,
    /// 2: erase the store and apply the defaults.
    Reset,
}

// No allocation: the one calibration in progress is held inline (≈ 250 B).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
enum Calibration {
    Accel(AccelCalibrator),
    /// Gyro stillness check or level trim: average for [`STILL_TIME_US`].
    Still {
        level: bool,
        since_us: u64,
        sum: Vec3,
        n: u32,
        last_progress: u8,
    },
}

/// The setup services' state (see the module docs).
pub struct Setup {
    motor: MotorTest,
    cal: Option<Calibration>,
    storage: Option<StorageRequest>,
    save: SaveSchedule,
    texts: Deque<Text, TEXT_QUEUE_LEN>,
    dropped: u32,
}

impl Default for Setup {
    fn default() -> Self {
        Self::new()
    }
}

fn text(s: &str) -> Text {
    let mut t = Text::new();
    for c in s.chars() {
        if t.push(c).is_err() {
            break;
        }
    }
    t
}

impl Setup {
    /// Nothing running.
    pub const fn new() -> Self {
        Self {
            motor: MotorTest::new(),
            cal: None,
            storage: None,
            save: SaveSchedule::new(),
            texts: Deque::new(),
            dropped: 0,
        }
    }

    fn say(&mut self, t: Text) {
        if self.texts.is_full() {
            self.texts.pop_front();
            self.dropped = self.dropped.saturating_add(1);
        }
        let _ = self.texts.push_back(t);
    }

    fn say_event(&mut self, e: &CalEvent) {
        let mut t = Text::new();
        // A PX4 text is at most 50 bytes (tested in core); a longer one is cut.
        let _ = e.write(&mut t);
        self.say(t);
    }

    /// Queue a STATUSTEXT of the caller's (storage outcomes).
    pub fn say_text(&mut self, s: &str) {
        self.say(text(s));
    }

    /// Next STATUSTEXT for the link.
    pub fn pop_text(&mut self) -> Option<Text> {
        self.texts.pop_front()
    }

    /// STATUSTEXTs dropped because the queue was full.
    pub fn texts_dropped(&self) -> u32 {
        self.dropped
    }

    /// A parameter changed (PARAM_SET accepted): save it after the debounce.
    pub fn param_changed(&mut self, now_us: u64) {
        self.save.changed(now_us);
    }

    /// `true` when the storage task should save now (debounced, disarmed only).
    pub fn save_due(&mut self, now_us: u64, armed: bool) -> bool {
        self.save.due(now_us, armed)
    }

    /// The storage task's next request.
    pub fn take_storage(&mut self) -> Option<StorageRequest> {
        self.storage.take()
    }

    /// A calibration is running.
    pub fn calibrating(&self) -> bool {
        self.cal.is_some()
    }

    /// Stop every motor of a motor test: an arming attempt by RC, a kill, the link lost.
    pub fn stop_motors(&mut self) {
        self.motor.stop();
    }

    /// The motor-test output, if a test runs (0..1 per motor, output order); the caller sends
    /// it to the ESCs instead of the mixer's (disarmed) zeros.
    pub fn motor_output(&mut self, now_us: u64, pilot_throttle: Option<f32>) -> Option<[f32; MAX_MOTORS]> {
        self.motor.output(now_us, pilot_throttle)
    }

    /// A COMMAND_LONG / COMMAND_INT: the answer when it is one of the three setup commands,
    /// `None` otherwise. Any command but a motor test stops a running motor test.
    pub fn command(
        &mut self,
        now_us: u64,
        id: u16,
        p: [f32; 7],
        armed: bool,
        board: &ControllerParams,
    ) -> Option<SetupAck> {
        if id != CMD_DO_MOTOR_TEST {
            self.motor.stop();
        }
        match id {
            CMD_DO_MOTOR_TEST => Some(self.motor_test(now_us, p, armed)),
            CMD_PREFLIGHT_CALIBRATION => Some(self.calibration(now_us, p, armed, board)),
            CMD_PREFLIGHT_STORAGE => Some(self.storage_cmd(p, armed)),
            _ => None,
        }
    }

    fn motor_test(&mut self, now_us: u64, p: [f32; 7], armed: bool) -> SetupAck {
        let [instance, throttle_type, value, timeout_s, count, order, _] = p;
        let req = MotorTestRequest { instance, throttle_type, value, timeout_s, count, order };
        if self.cal.is_some() {
            self.say(text("Motor test refused: calibration running"));
            return SetupAck::TemporarilyRejected;
        }
        match self.motor.start(now_us, &req, armed, MAX_MOTORS) {
            Ok(()) => SetupAck::Accepted,
            Err(why) => {
                self.say(text(why.reason()));
                if why.unsupported() {
                    SetupAck::Unsupported
                } else {
                    SetupAck::Denied
                }
            }
        }
    }

    fn calibration(&mut self, now_us: u64, p: [f32; 7], armed: bool, board: &ControllerParams) -> SetupAck {
        if p.iter().all(|&x| x == 0.0) {
            if self.cal.take().is_some() {
                self.say(text("[cal] calibration cancelled"));
            }
            return SetupAck::Accepted;
        }
        if armed {
            self.say(text("[cal] calibration denied: vehicle armed"));
            return SetupAck::Denied;
        }
        if self.cal.is_some() {
            return SetupAck::TemporarilyRejected;
        }
        // param2 mag, 3 baro/ground pressure, 4 RC, 6 airspeed/compass-motor, 7 ESC: none here.
        if p[1] != 0.0 || p[2] != 0.0 || p[3] != 0.0 || p[5] != 0.0 || p[6] != 0.0 {
            return SetupAck::Unsupported;
        }
        let still = |level| Calibration::Still {
            level,
            since_us: now_us,
            sum: Vec3::zeros(),
            n: 0,
            last_progress: 0,
        };
        match (p[0], p[4]) {
            (g, a) if g == 1.0 && a == 0.0 => {
                self.say(text("[cal] calibration started: 2 gyro"));
                self.cal = Some(still(false));
            }
            (g, a) if g == 0.0 && a == 1.0 => {
                let (c, e) =
                    AccelCalibrator::start(now_us, CalParams::default(), board.sensors.board_rotation);
                self.say_event(&e);
                self.cal = Some(Calibration::Accel(c));
            }
            (g, a) if g == 0.0 && a == 2.0 => {
                self.say(text("[cal] calibration started: 2 level"));
                self.cal = Some(still(true));
            }
            _ => return SetupAck::Unsupported,
        }
        SetupAck::Accepted
    }

    fn storage_cmd(&mut self, p: [f32; 7], armed: bool) -> SetupAck {
        if armed {
            self.say(text("Params: storage denied while armed"));
            return SetupAck::Denied;
        }
        if self.storage.is_some() {
            return SetupAck::TemporarilyRejected;
        }
        let req = if p[0] == 0.0 {
            StorageRequest::Read
        } else if p[0] == 1.0 {
            StorageRequest::Write
        } else if p[0] == 2.0 {
            StorageRequest::Reset
        } else {
            return SetupAck::Unsupported;
        };
        self.storage = Some(req);
        SetupAck::Accepted
    }

    /// One raw IMU sample (sensor frame, before [`ImuCorrection`]) while a calibration runs.
    /// Returns `true` when a result was written into `params` (the caller rebuilds its
    /// [`ImuCorrection`] from `params.sensors`); the save is scheduled here.
    pub fn imu(&mut self, now_us: u64, raw: &ImuSample, params: &mut ControllerParams) -> bool {
        let Some(cal) = self.cal else { return false };
        match cal {
            Calibration::Accel(mut c) => {
                let event = c.update(now_us, raw.accel);
                self.cal = (!c.finished()).then_some(Calibration::Accel(c));
                let Some(e) = event else { return false };
                let mut wrote = false;
                if let CalEvent::Done(fit) = e {
                    let names = [
                        ("CAL_ACC0_XOFF", fit.offset.x),
                        ("CAL_ACC0_YOFF", fit.offset.y),
                        ("CAL_ACC0_ZOFF", fit.offset.z),
                        ("CAL_ACC0_XSCALE", fit.scale.x),
                        ("CAL_ACC0_YSCALE", fit.scale.y),
                        ("CAL_ACC0_ZSCALE", fit.scale.z),
                    ];
                    wrote = self.write_all(params, &names, now_us);
                    if !wrote {
                        self.say(text("[cal] calibration failed: to set parameters"));
                        return false;
                    }
                }
                self.say_event(&e);
                wrote
            }
            Calibration::Still { level, since_us, sum, n, last_progress } => {
                let what = if level { "level" } else { "gyro" };
                if !(raw.gyro.iter().all(|w| w.is_finite() && w.abs() < STILL_RATE_MAX)) {
                    self.cal = None;
                    let mut t = text("[cal] calibration failed: ");
                    let _ = t.push_str(what);
                    let _ = t.push_str(" motion");
                    self.say(t);
                    return false;
                }
                // Level: the body-frame specific force with the board rotation and the
                // accelerometer calibration, without the current trim.
                let mut no_trim = params.sensors;
                no_trim.trim_roll = 0.0;
                no_trim.trim_pitch = 0.0;
                let body = ImuCorrection::new(&no_trim).apply(raw).accel;
                let (sum, n) = (sum + body, n + 1);
                let elapsed = now_us.saturating_sub(since_us);
                if elapsed < STILL_TIME_US {
                    let pct = (elapsed * 100 / STILL_TIME_US) as u8;
                    let mut lp = last_progress;
                    if pct >= last_progress.saturating_add(20) {
                        lp = pct;
                        self.say_event(&CalEvent::Progress(pct));
                    }
                    self.cal = Some(Calibration::Still { level, since_us, sum, n, last_progress: lp });
                    return false;
                }
                self.cal = None;
                if !level {
                    self.say(text("[cal] calibration done: gyro"));
                    return false;
                }
                match level_trim(&(sum / n as f32)) {
                    Ok((roll, pitch)) => {
                        if self.write_all(
                            params,
                            &[("CAL_TRIM_ROLL", roll), ("CAL_TRIM_PITCH", pitch)],
                            now_us,
                        ) {
                            self.say(text("[cal] calibration done: level"));
                            true
                        } else {
                            self.say(text("[cal] calibration failed: to set parameters"));
                            false
                        }
                    }
                    Err(e) => {
                        let why = match e {
                            parapet_core::calibration::TrimError::NotAtRest => {
                                "[cal] calibration failed: not at rest"
                            }
                            parapet_core::calibration::TrimError::TooLarge => {
                                "[cal] calibration failed: tilt too large"
                            }
                        };
                        self.say(text(why));
                        false
                    }
                }
            }
        }
    }

    /// Set every `(name, value)` or none (checked first); schedules a save.
    fn write_all(&mut self, p: &mut ControllerParams, values: &[(&str, f32)], now_us: u64) -> bool {
        let mut next = *p;
        for (name, v) in values {
            if params::set(&mut next, name, *v).is_err() {
                return false;
            }
        }
        *p = next;
        self.save.changed(now_us);
        true
    }
}

#[cfg(test)]
mod tests;

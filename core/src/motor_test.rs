//! Motor test: the state machine behind MAVLink `MAV_CMD_DO_MOTOR_TEST` (209), used with the
//! props off to check motor order and spin direction against the airframe table
//! ([`crate::airframe`]: 1 front-right CCW, 2 rear-left CCW, 3 front-left CW, 4 rear-right CW).
//!
//! Owns [`MotorTest`], [`MotorTestRequest`], [`ThrottleType`], [`TestOrder`],
//! [`MotorTestRefused`].
//!
//! ## Rules
//! * **Disarmed only**: [`MotorTest::start`] refuses while armed ([`MotorTestRefused::Armed`],
//!   MAVLink: ACK DENIED and the reason in a STATUSTEXT) and refuses out-of-range fields with
//!   their own reason (ACK DENIED / UNSUPPORTED, see [`MotorTestRefused::unsupported`]).
//! * **Instance** (param1) is 1-based; with [`TestOrder::Default`] / [`TestOrder::Board`] it
//!   is the output number (the PX4 numbering above), with [`TestOrder::Sequence`] the
//!   position clockwise from the front-right motor (A = 1 FR, B = 4 RR, C = 2 RL, D = 3 FL),
//!   as ArduPilot's motor test page labels them.
//! * **Throttle** (param2 type, param3 value): percent 0..100, PWM 1000..2000 µs (mapped
//!   linearly to 0..1), or the pilot's throttle stick (passed in each step; no stick → 0).
//!   A value of 0 ends a running test.
//! * **Timeout** (param4) in (0, [`MAX_TIMEOUT_S`]] s for each motor; **motor count**
//!   (param5) 0 or 1 tests one motor, n > 1 tests n motors one after the other from the
//!   instance on, each for the timeout.
//! * **Every motor stops** at the timeout, on [`MotorTest::stop`] (the firmware calls it on
//!   any other command, on an arming attempt and on link loss) and whenever a new test is refused.
//!
//! Bounded: [`MotorTest::output`] is constant time. No allocation, no panics.
//!
//! May import: nothing of the crate (it sits beside the mixer; the caller passes the motor count).

/// Most motors a test addresses.
pub const MAX_MOTORS: usize = 4;
/// Longest time one motor may spin in a test, s.
pub const MAX_TIMEOUT_S: f32 = 10.0;
/// Highest throttle a test may command (fraction of full). PX4 and ArduPilot allow 100 %;
/// props must be off anyway.
pub const MAX_THROTTLE: f32 = 1.0;

/// MAVLink `MOTOR_TEST_THROTTLE_TYPE`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThrottleType {
    /// 0: percent, 0..100.
    Percent,
    /// 1: PWM pulse width, 1000..2000 µs.
    Pwm,
    /// 2: the pilot's throttle stick.
    Pilot,
}

impl ThrottleType {
    /// From the MAVLink code (3, compass calibration, is not supported).
    pub fn from_code(code: f32) -> Option<Self> {
        match whole(code)? {
            0 => Some(ThrottleType::Percent),
            1 => Some(ThrottleType::Pwm),
            2 => Some(ThrottleType::Pilot),
            _ => None,
        }
    }
}

/// MAVLink `MOTOR_TEST_ORDER`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TestOrder {
    /// 0: the instance is the output number.
    Default,
    /// 1: the instance is the position clockwise from front-right.
    Sequence,
    /// 2: the instance is the board's output number (same as `Default` here).
    Board,
}

impl TestOrder {
    /// From the MAVLink code.
    pub fn from_code(code: f32) -> Option<Self> {
        match whole(code)? {
            0 => Some(TestOrder::Default),
            1 => Some(TestOrder::Sequence),
            2 => Some(TestOrder::Board),
            _ => None,
        }
    }
}

/// `x` as a whole number, if it is one.
fn whole(x: f32) -> Option<i32> {
    (x.is_finite() && x == (x as i32) as f32).then_some(x as i32)
}

/// Output index (0-based, PX4 order) of the clockwise sequence position `k` (0-based).
const CLOCKWISE: [u8; MAX_MOTORS] = [0, 3, 1, 2];

/// The fields of one DO_MOTOR_TEST (COMMAND_LONG param1..param6, unconverted).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorTestRequest {
    /// param1: motor instance, 1-based.
    pub instance: f32,
    /// param2: throttle type code.
    pub throttle_type: f32,
    /// param3: throttle value.
    pub value: f32,
    /// param4: timeout, s.
    pub timeout_s: f32,
    /// param5: motor count (0 or 1: one motor).
    pub count: f32,
    /// param6: test order code.
    pub order: f32,
}

/// Why a test was not started (every motor is stopped).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotorTestRefused {
    /// The vehicle is armed.
    Armed,
    /// Instance not a whole number in 1..=motors.
    Instance,
    /// Unknown throttle type (compass calibration is not supported).
    ThrottleType,
    /// Throttle value not finite or outside its type's range.
    Value,
    /// Timeout not in (0, 10] s.
    Timeout,
    /// Motor count not a whole number in 0..=motors.
    Count,
    /// Unknown test order.
    Order,
}

impl MotorTestRefused {
    /// The STATUSTEXT reason.
    pub fn reason(self) -> &'static str {
        match self {
            MotorTestRefused::Armed => "Motor test refused: vehicle armed",
            MotorTestRefused::Instance => "Motor test refused: no such motor",
            MotorTestRefused::ThrottleType => "Motor test refused: throttle type not supported",
            MotorTestRefused::Value => "Motor test refused: throttle out of range",
            MotorTestRefused::Timeout => "Motor test refused: timeout not in (0, 10] s",
            MotorTestRefused::Count => "Motor test refused: bad motor count",
            MotorTestRefused::Order => "Motor test refused: test order not supported",
        }
    }

    /// `true` when the MAVLink answer is UNSUPPORTED (a mode the firmware does not have)
    /// rather than DENIED.
    pub fn unsupported(self) -> bool {
        matches!(self, MotorTestRefused::ThrottleType | MotorTestRefused::Order)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Running {
    /// 0-based first position (output number or clockwise position).
    first: u8,
    count: u8,
    sequence: bool,
    throttle: Throttle,
    started_us: u64,
    step_us: u64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Throttle {
    Fixed(f32),
    Pilot,
}

/// The motor-test state machine (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotorTest {
    running: Option<Running>,
}

impl MotorTest {
    /// No test running.
    pub const fn new() -> Self {
        Self { running: None }
    }

    /// A test is running (the motors are the test's, not the controller's).
    pub fn active(&self) -> bool {
        self.running.is_some()
    }

    /// Start a test (replacing a running one) or, with value 0, end it. `motors` is the
    /// airframe's motor count (at most [`MAX_MOTORS`]). On a refusal every motor stops.
    pub fn start(
        &mut self,
        now_us: u64,
        req: &MotorTestRequest,
        armed: bool,
        motors: usize,
    ) -> Result<(), MotorTestRefused> {
        self.running = None;
        let motors = motors.min(MAX_MOTORS) as f32;
        if armed {
            return Err(MotorTestRefused::Armed);
        }
        if !(whole(req.instance).is_some() && req.instance >= 1.0 && req.instance <= motors) {
            return Err(MotorTestRefused::Instance);
        }
        let ty = ThrottleType::from_code(req.throttle_type).ok_or(MotorTestRefused::ThrottleType)?;
        let order = TestOrder::from_code(req.order).ok_or(MotorTestRefused::Order)?;
        let throttle = match ty {
            ThrottleType::Percent if (0.0..=100.0).contains(&req.value) => Throttle::Fixed(req.value / 100.0),
            ThrottleType::Pwm if (1000.0..=2000.0).contains(&req.value) => {
                Throttle::Fixed((req.value - 1000.0) / 1000.0)
            }
            ThrottleType::Pilot => Throttle::Pilot,
            _ => return Err(MotorTestRefused::Value),
        };
        if !(req.timeout_s > 0.0 && req.timeout_s <= MAX_TIMEOUT_S) {
            return Err(MotorTestRefused::Timeout);
        }
        if !(whole(req.count).is_some() && req.count >= 0.0 && req.count <= motors) {
            return Err(MotorTestRefused::Count);
        }
        if throttle == Throttle::Fixed(0.0) {
            return Ok(()); // value 0: stop
        }
        let first = req.instance as u8 - 1;
        // A sequence runs to the last motor at most.
        let count = (req.count as u8).max(1).min(motors as u8 - first);
        self.running = Some(Running {
            first,
            count,
            sequence: order == TestOrder::Sequence,
            throttle: match throttle {
                Throttle::Fixed(t) => Throttle::Fixed(t.min(MAX_THROTTLE)),
                p => p,
            },
            started_us: now_us,
            step_us: (req.timeout_s * 1e6) as u64,
        });
        Ok(())
    }

    /// Stop every motor (any other command, an arming attempt, link loss).
    pub fn stop(&mut self) {
        self.running = None;
    }

    /// The motor commands (0..1, output order) at `now_us`, or `None` when no test runs
    /// (the test ended at its timeout or was stopped). `pilot_throttle` (0..1) is the pilot's
    /// stick for [`ThrottleType::Pilot`] tests (`None` or not finite: 0).
    pub fn output(&mut self, now_us: u64, pilot_throttle: Option<f32>) -> Option<[f32; MAX_MOTORS]> {
        let r = self.running?;
        let elapsed = now_us.saturating_sub(r.started_us);
        let step = elapsed.checked_div(r.step_us).unwrap_or(u64::MAX);
        if step >= u64::from(r.count) {
            self.running = None;
            return None;
        }
        let pos = (u64::from(r.first) + step) as usize % MAX_MOTORS;
        let out = if r.sequence { CLOCKWISE.get(pos).copied().unwrap_or(0) as usize } else { pos };
        let t = match r.throttle {
            Throttle::Fixed(t) => t,
            Throttle::Pilot => {
                pilot_throttle.filter(|t| t.is_finite()).map_or(0.0, |t| t.clamp(0.0, MAX_THROTTLE))
            }
        };
        let mut m = [0.0; MAX_MOTORS];
        if let Some(slot) = m.get_mut(out) {
            *slot = t;
        }
        Some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;

    fn req(instance: f32, value: f32, timeout_s: f32) -> MotorTestRequest {
        MotorTestRequest { instance, throttle_type: 0.0, value, timeout_s, count: 0.0, order: 0.0 }
    }

    #[test]
    fn one_motor_spins_until_the_timeout() {
        let mut t = MotorTest::new();
        t.start(0, &req(3.0, 15.0, 2.0), false, 4).unwrap();
        assert_eq!(t.output(0, None), Some([0.0, 0.0, 0.15, 0.0]));
        assert_eq!(t.output(2 * S - 1, None), Some([0.0, 0.0, 0.15, 0.0]));
        assert_eq!(t.output(2 * S, None), None);
        assert!(!t.active());
        assert_eq!(t.output(3 * S, None), None);
    }

    #[test]
    fn refused_while_armed_and_for_bad_fields() {
        let mut t = MotorTest::new();
        assert_eq!(t.start(0, &req(1.0, 10.0, 1.0), true, 4), Err(MotorTestRefused::Armed));
        let cases = [
            (MotorTestRequest { instance: 0.0, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Instance),
            (MotorTestRequest { instance: 5.0, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Instance),
            (MotorTestRequest { instance: 1.5, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Instance),
            (MotorTestRequest { instance: f32::NAN, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Instance),
            (MotorTestRequest { throttle_type: 3.0, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::ThrottleType),
            (req(1.0, 101.0, 1.0), MotorTestRefused::Value),
            (req(1.0, f32::NAN, 1.0), MotorTestRefused::Value),
            (MotorTestRequest { throttle_type: 1.0, ..req(1.0, 900.0, 1.0) }, MotorTestRefused::Value),
            (req(1.0, 10.0, 0.0), MotorTestRefused::Timeout),
            (req(1.0, 10.0, 11.0), MotorTestRefused::Timeout),
            (req(1.0, 10.0, f32::INFINITY), MotorTestRefused::Timeout),
            (MotorTestRequest { count: 5.0, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Count),
            (MotorTestRequest { order: 7.0, ..req(1.0, 10.0, 1.0) }, MotorTestRefused::Order),
        ];
        for (r, why) in cases {
            // A refusal also stops a running test.
            t.start(0, &req(1.0, 10.0, 5.0), false, 4).unwrap();
            assert_eq!(t.start(S, &r, false, 4), Err(why), "{r:?}");
            assert_eq!(t.output(S, None), None);
            assert!(!why.reason().is_empty());
        }
        assert!(MotorTestRefused::Order.unsupported() && !MotorTestRefused::Armed.unsupported());
    }

    #[test]
    fn stop_and_zero_value_end_the_test() {
        let mut t = MotorTest::new();
        t.start(0, &req(1.0, 20.0, 5.0), false, 4).unwrap();
        t.stop();
        assert_eq!(t.output(1, None), None);
        t.start(0, &req(1.0, 20.0, 5.0), false, 4).unwrap();
        t.start(1, &req(1.0, 0.0, 5.0), false, 4).unwrap();
        assert_eq!(t.output(2, None), None);
    }

    #[test]
    fn pwm_and_pilot_throttle() {
        let mut t = MotorTest::new();
        let r = MotorTestRequest { throttle_type: 1.0, ..req(2.0, 1250.0, 1.0) };
        t.start(0, &r, false, 4).unwrap();
        assert_eq!(t.output(0, None), Some([0.0, 0.25, 0.0, 0.0]));
        let r = MotorTestRequest { throttle_type: 2.0, ..req(4.0, 0.0, 1.0) };
        t.start(0, &r, false, 4).unwrap();
        assert_eq!(t.output(0, Some(0.3)), Some([0.0, 0.0, 0.0, 0.3]));
        assert_eq!(t.output(1, None), Some([0.0; 4]));
        assert_eq!(t.output(2, Some(f32::NAN)), Some([0.0; 4]));
        assert_eq!(t.output(3, Some(7.0)), Some([0.0, 0.0, 0.0, 1.0]));
    }

    #[test]
    fn count_runs_motors_in_turn_and_sequence_order_goes_clockwise() {
        let mut t = MotorTest::new();
        t.start(0, &MotorTestRequest { count: 4.0, ..req(1.0, 10.0, 1.0) }, false, 4).unwrap();
        let on = |m: [f32; 4]| m.iter().position(|&x| x > 0.0).unwrap();
        let seq: [usize; 4] = core::array::from_fn(|k| on(t.output(k as u64 * S + 1, None).unwrap()));
        assert_eq!(seq, [0, 1, 2, 3]);
        assert_eq!(t.output(4 * S, None), None);
        // Clockwise from front-right: FR (1), RR (4), RL (2), FL (3).
        let r = MotorTestRequest { count: 4.0, order: 1.0, ..req(1.0, 10.0, 1.0) };
        t.start(0, &r, false, 4).unwrap();
        let seq: [usize; 4] = core::array::from_fn(|k| on(t.output(k as u64 * S + 1, None).unwrap()));
        assert_eq!(seq, [0, 3, 1, 2]);
        // A count past the last motor stops at the last one.
        t.start(0, &MotorTestRequest { count: 4.0, ..req(3.0, 10.0, 1.0) }, false, 4).unwrap();
        assert_eq!(on(t.output(S + 1, None).unwrap()), 3);
        assert_eq!(t.output(2 * S, None), None);
    }
}

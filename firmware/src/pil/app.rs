//! The processor-in-the-loop application: handshake, then lockstep over one byte link.
//!
//! Hardware-independent (the QEMU board supplies a [`BytePort`] on its semihosting console and a
//! [`TickCounter`] on SysTick), so the whole protocol is host-tested. The protocol itself is
//! specified in `firmware/README.md` ("QEMU lockstep protocol").
//!
//! **Battery**: the host's raw pack readings (BATTERY_STATUS from the host's id) are taken out
//! of the byte stream before the link dispatches them and measured by [`crate::pil::battery`]
//! at the firmware time of the last answered step.
//!
//! **Onboard log** ([`PilApp::with_log`]): after each control step that ran the outer loop, the
//! step's telemetry goes through a bounded queue ([`LOG_QUEUE_LEN`], the same `embassy-sync`
//! channel a board's control task would use; full → dropped, counted) to the log writer, which
//! runs after the step's answer was queued, outside the measured step, like a board's
//! lowest-priority log task. Then the log download sends at most
//! [`crate::log::transfer::REPLIES_PER_POLL`] messages. Per written record set the firmware
//! reports `ins_log` (instructions of the write), `ins_logq` (of handing the sample over: what the
//! control side pays) and `ins_logm` (the longest section with interrupts masked in it).

use crate::link::dialect::{MavSeverity, HEARTBEAT_DATA};
use parapet_core::schedule::OuterSchedule;
use parapet_core::wire::names;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use parapet_core::controller::ControllerParams;

use crate::app::autopilot::{ControlSteps, MotorCommand};
use crate::app::loop_timing::{LoopReport, LoopTimer};
use crate::link::framing::{FrameWriter, AUTOPILOT_COMPONENT_ID, VEHICLE_SYSTEM_ID};
use crate::link::outbound::{named_int, Outbound};
use crate::link::telemetry::{heartbeat, status_text, ErrorCounters, TelemetryInputs, TelemetryScheduler};
use crate::link::{FixClock, Link};
use crate::log::logger::{FlightLogger, LogSample, DEFAULT_PERIOD_US};
use crate::log::service::{LogService, RamLogStore};
use crate::log::transfer::{LogReply, REPLIES_PER_POLL};
use crate::pil::battery::{is_host_reading, reading_of, PilBattery};
use crate::pil::lockstep::{InstructionCalibration, LockstepScheduler};

/// Instructions of the start-up calibration loop (2 × 50 000 iterations of a 2-instruction loop
/// difference, see `board::qemu::InstructionCounter::calibrate`).
pub const CALIBRATION_ITERATIONS: u32 = 50_000;
/// Telemetry samples in flight from the control step to the log writer.
pub const LOG_QUEUE_LEN: usize = 2;
/// NAMED_VALUE_INT names of the log measurements (see the module doc).
pub const INS_LOG: &str = "ins_log";
/// Instructions of handing one sample to the log queue.
pub const INS_LOG_QUEUE: &str = "ins_logq";
/// Longest masked section while handing a sample over, instructions.
pub const INS_LOG_MASKED: &str = "ins_logm";

/// A byte link polled by the application.
pub trait BytePort {
    /// One received byte, if any.
    fn try_read(&mut self) -> Option<u8>;
    /// Sends `bytes` (blocking).
    fn write(&mut self, bytes: &[u8]);
}

/// A free-running tick counter (SysTick under `qemu -icount`).
pub trait TickCounter {
    /// Current raw value.
    fn now(&self) -> u32;
    /// Ticks elapsed since `start`.
    fn since(&self, start: u32) -> u32;
    /// Ticks of the longest section with interrupts masked since the previous call (a board
    /// that measures its critical sections, `board::qemu`); 0 when not measured.
    fn take_masked_max(&self) -> u32 {
        0
    }
}

/// Counters of the PIL application.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PilStats {
    /// Heartbeats sent during the handshake.
    pub handshake_heartbeats: u32,
    /// Control steps answered.
    pub steps: u32,
    /// Largest instruction count of one control step.
    pub max_step_instructions: u32,
    /// Longest section with interrupts masked during a control step, instructions.
    pub max_masked_instructions: u32,
    /// Log samples dropped because the log queue was full.
    pub log_dropped: u32,
    /// Largest instruction count of one log write (a record set; the first also writes the
    /// log's header, formats and parameters).
    pub max_log_instructions: u32,
    /// Largest instruction count of handing a sample to the log queue.
    pub max_log_queue_instructions: u32,
    /// Longest section with interrupts masked while handing a sample over, instructions.
    pub max_log_masked_instructions: u32,
}

/// The PIL application state.
pub struct PilApp<A: ControlSteps> {
    autopilot: A,
    link: Link,
    scheduler: LockstepScheduler,
    telemetry: TelemetryScheduler,
    writer: FrameWriter,
    calibration: InstructionCalibration,
    inner_timer: LoopTimer,
    outer_timer: LoopTimer,
    stats: PilStats,
    last_t_us: u64,
    log: Option<LogService<RamLogStore>>,
    log_queue: Channel<CriticalSectionRawMutex, LogSample, LOG_QUEUE_LEN>,
    battery: PilBattery,
}

/// AUTOPILOT_VERSION `uid` of the simulated vehicle: QEMU's netduinoplus2 has no unique device
/// id, so the PIL vehicle has this fixed one (the ASCII of "PARAPET" + 1), the same every run
/// as PX4 SITL's.
pub const PIL_UID: u64 = u64::from_be_bytes(*b"PARAPET\x01");

impl<A: ControlSteps> PilApp<A> {
    /// Application around `autopilot` with the start-up `calibration`.
    pub fn new(autopilot: A, calibration: InstructionCalibration) -> Self {
        Self {
            autopilot,
            link: {
                let mut l = Link::new(VEHICLE_SYSTEM_ID, FixClock::Message);
                l.set_uid(PIL_UID);
                l
            },
            scheduler: LockstepScheduler::default(),
            telemetry: TelemetryScheduler::new(),
            writer: FrameWriter::new(VEHICLE_SYSTEM_ID, AUTOPILOT_COMPONENT_ID),
            calibration,
            // Periods are measured in simulated µs (1 "cycle" per µs).
            inner_timer: LoopTimer::new(1000, 1),
            outer_timer: LoopTimer::new(
                OuterSchedule::DEFAULT.period_us().min(u64::from(u32::MAX)) as u32,
                1,
            ),
            stats: PilStats::default(),
            last_t_us: 0,
            log: None,
            log_queue: Channel::new(),
            battery: PilBattery::new(),
        }
    }

    /// With the onboard log in `store` (a `static`: see [`LogService::new`]), recording with the
    /// thrust map of `params`.
    pub fn with_log(mut self, store: &'static mut RamLogStore, params: &ControllerParams) -> Self {
        self.set_log(store, params);
        self
    }

    /// [`PilApp::with_log`] in place (an application in a `static`: no copy of it on the stack).
    pub fn set_log(&mut self, store: &'static mut RamLogStore, params: &ControllerParams) {
        let logger = FlightLogger::new(DEFAULT_PERIOD_US, params, "qemu-netduinoplus2");
        self.log = Some(LogService::new(store, logger, VEHICLE_SYSTEM_ID));
    }

    /// The onboard log, if any.
    pub fn log(&mut self) -> Option<&mut LogService<RamLogStore>> {
        self.log.as_mut()
    }

    fn send(&mut self, port: &mut impl BytePort, msg: &Outbound) {
        let raw = msg.encode(&mut self.writer);
        port.write(raw.raw_bytes());
    }

    /// Counters so far.
    pub fn stats(&self) -> PilStats {
        self.stats
    }

    /// The link (counters).
    pub fn link(&self) -> &Link {
        &self.link
    }

    /// The battery measurement of the host's simulated pack (counters).
    pub fn battery(&self) -> &PilBattery {
        &self.battery
    }

    /// The autopilot.
    pub fn autopilot(&self) -> &A {
        &self.autopilot
    }

    /// The autopilot, for the board's work between the lockstep steps (the parameter store's
    /// [`crate::vehicle::SetupVehicle::storage_step`]).
    pub fn autopilot_mut(&mut self) -> &mut A {
        &mut self.autopilot
    }

    /// The start-up instruction calibration (SysTick ticks → instructions).
    pub fn calibration(&self) -> InstructionCalibration {
        self.calibration
    }

    /// The simulator time of the last answered step, µs (0 before the first).
    pub fn now_us(&self) -> u64 {
        self.last_t_us
    }

    /// Sends one NAMED_VALUE_INT `name` = `value` stamped with the last step's time (the
    /// board's measurements of its work between the steps, e.g. `ins_store`).
    pub fn report(&mut self, port: &mut impl BytePort, name: &str, value: u32) {
        let m = named_int((self.last_t_us / 1000) as u32, name, value.min(i32::MAX as u32) as i32);
        self.send(port, &m);
    }

    /// One handshake round: sends a HEARTBEAT, then polls the port for `period_ticks`. Returns
    /// `true` (after sending the calibration and a ready STATUSTEXT) once the first valid frame
    /// arrived; the bytes of that frame are processed normally.
    pub fn handshake_round(
        &mut self,
        port: &mut impl BytePort,
        ticks: &impl TickCounter,
        period_ticks: u32,
    ) -> bool {
        let hb: HEARTBEAT_DATA = heartbeat(&self.autopilot.telemetry());
        self.send(port, &Outbound::Heartbeat(hb));
        self.stats.handshake_heartbeats = self.stats.handshake_heartbeats.saturating_add(1);
        let t0 = ticks.now();
        while ticks.since(t0) < period_ticks {
            if let Some(b) = port.try_read() {
                self.link.push_byte(b, 0, &mut self.autopilot);
                if self.link.peer_seen() {
                    self.after_handshake(port);
                    return true;
                }
            }
        }
        false
    }

    fn after_handshake(&mut self, port: &mut impl BytePort) {
        let c = self.calibration;
        self.send(port, &named_int(0, names::INS_CAL_N, c.instructions.min(i32::MAX as u32) as i32));
        self.send(port, &named_int(0, names::INS_CAL, c.ticks.min(i32::MAX as u32) as i32));
        let ready = status_text(MavSeverity::MAV_SEVERITY_INFO, names::PIL_READY_TEXT, "");
        self.send(port, &Outbound::StatusText(ready));
    }

    /// Processes every byte available now; answers each HIL_SENSOR (see [`crate::pil::lockstep`]).
    /// Returns the number of control steps answered.
    pub fn poll(&mut self, port: &mut impl BytePort, ticks: &impl TickCounter) -> u32 {
        let mut answered = 0;
        while let Some(b) = port.try_read() {
            if let Some(log) = self.log.as_mut() {
                log.on_byte(b);
            }
            let now = self.scheduler_time();
            // The host's raw battery reading is taken here, never dispatched (`pil::battery`).
            let mut reading = None;
            self.link.push_byte_diverting(b, now, &mut self.autopilot, &mut |f| {
                let host = is_host_reading(f);
                if host {
                    reading = Some(reading_of(f.payload));
                }
                host
            });
            match reading {
                Some(Some(r)) => {
                    let _ = self.battery.take(now, r, &mut self.autopilot);
                }
                Some(None) => self.battery.undecodable(),
                None => {}
            }
            while let Some(r) = self.link.pop_reply() {
                self.send(port, &r);
            }
            if let Some(sample) = self.link.take_hil_sample() {
                self.answer(port, ticks, &sample);
                answered += 1;
            }
        }
        answered
    }

    fn scheduler_time(&self) -> u64 {
        self.last_t_us
    }

    fn answer(
        &mut self,
        port: &mut impl BytePort,
        ticks: &impl TickCounter,
        sample: &crate::link::HilSample,
    ) {
        let t = sample.time_usec;
        let t32 = t as u32;
        self.inner_timer.start(t32);
        let _ = ticks.take_masked_max();
        let t0 = ticks.now();
        let out = self.scheduler.step_timed(sample, &mut self.link, &mut self.autopilot, ticks);
        let spent = ticks.since(t0);
        let masked = self.calibration.instructions_for(ticks.take_masked_max());
        self.inner_timer.end(t32);
        if out.ran_outer {
            self.outer_timer.start(t32);
            self.outer_timer.end(t32);
        }
        let ins = self.calibration.instructions_for(spent);
        self.stats.steps = self.stats.steps.saturating_add(1);
        self.stats.max_step_instructions = self.stats.max_step_instructions.max(ins);
        self.stats.max_masked_instructions = self.stats.max_masked_instructions.max(masked);
        self.last_t_us = t;
        self.link.poll(t, &mut self.autopilot);
        while let Some(r) = self.link.pop_reply() {
            self.send(port, &r);
        }
        let inputs = TelemetryInputs {
            snapshot: self.autopilot.telemetry(),
            inner: self.inner_timer.report(),
            outer: self.outer_timer.report(),
            parser: self.link.parser_stats(),
            counters: ErrorCounters::from_link(&self.link),
        };
        let mut queued: heapless::Vec<Outbound, { crate::link::telemetry::MAX_PER_POLL }> =
            heapless::Vec::new();
        self.telemetry.poll(t, &inputs, |m| {
            // Room for the most messages one poll emits.
            let _ = queued.push(m);
        });
        if self.telemetry.loops_reported {
            let _: LoopReport = self.inner_timer.take_report();
            let _: LoopReport = self.outer_timer.take_report();
        }
        for m in &queued {
            self.send(port, m);
        }
        if let Some(outer) = out.outer_ticks {
            let ins_outer = self.calibration.instructions_for(outer);
            self.send(
                port,
                &named_int((t / 1000) as u32, names::INS_OUTER, ins_outer.min(i32::MAX as u32) as i32),
            );
        }
        self.send(port, &named_int((t / 1000) as u32, names::INS_MASKED, masked.min(i32::MAX as u32) as i32));
        self.send(port, &named_int((t / 1000) as u32, names::INS_STEP, ins.min(i32::MAX as u32) as i32));
        self.send(port, &Outbound::HilActuatorControls(out.controls));
        self.log_step(port, ticks, t, out.ran_outer, &out.motors);
    }

    /// The onboard log after a control step (see the module doc).
    fn log_step(
        &mut self,
        port: &mut impl BytePort,
        ticks: &impl TickCounter,
        t: u64,
        ran_outer: bool,
        motors: &MotorCommand,
    ) {
        let Some(log) = self.log.as_mut() else { return };
        if ran_outer {
            // The control side: hand the sample over, never wait.
            let sample = LogSample { t_us: t, snapshot: self.autopilot.telemetry(), motors: motors.throttle };
            let _ = ticks.take_masked_max();
            let t0 = ticks.now();
            let queued = self.log_queue.try_send(sample).is_ok();
            let queue_ins = self.calibration.instructions_for(ticks.since(t0));
            let masked = self.calibration.instructions_for(ticks.take_masked_max());
            if !queued {
                self.stats.log_dropped = self.stats.log_dropped.saturating_add(1);
            }
            // The log side.
            let t1 = ticks.now();
            let mut wrote = false;
            while let Ok(s) = self.log_queue.try_receive() {
                let ap = &self.autopilot;
                wrote |= log.on_sample(&s, |n| ap.get_param(n));
            }
            let write_ins = self.calibration.instructions_for(ticks.since(t1));
            let st = &mut self.stats;
            st.max_log_queue_instructions = st.max_log_queue_instructions.max(queue_ins);
            st.max_log_masked_instructions = st.max_log_masked_instructions.max(masked);
            if wrote {
                st.max_log_instructions = st.max_log_instructions.max(write_ins);
                let ms = (t / 1000) as u32;
                for (name, v) in [(INS_LOG, write_ins), (INS_LOG_QUEUE, queue_ins), (INS_LOG_MASKED, masked)]
                {
                    let raw = named_int(ms, name, v.min(i32::MAX as u32) as i32).encode(&mut self.writer);
                    port.write(raw.raw_bytes());
                }
            }
        }
        let mut replies: heapless::Vec<LogReply, REPLIES_PER_POLL> = heapless::Vec::new();
        log.poll(&mut |r| {
            // REPLIES_PER_POLL is both the capacity and the most poll() emits.
            let _ = replies.push(r);
        });
        for r in &replies {
            let raw = r.encode(&mut self.writer);
            port.write(raw.raw_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::autopilot::test_double::RecordingAutopilot;
    use crate::link::dialect::{HIL_ACTUATOR_CONTROLS_DATA, HIL_SENSOR_DATA, NAMED_VALUE_INT_DATA};
    use crate::link::frame_parser::FrameParser;
    use crate::link::messages::frame_extra_crc;
    use mavlink_core::{MavlinkVersion, MessageData};
    use std::cell::Cell;
    use std::collections::VecDeque;
    use std::vec::Vec;

    #[derive(Default)]
    struct FakePort {
        rx: VecDeque<u8>,
        tx: Vec<u8>,
    }
    impl BytePort for FakePort {
        fn try_read(&mut self) -> Option<u8> {
            self.rx.pop_front()
        }
        fn write(&mut self, bytes: &[u8]) {
            self.tx.extend_from_slice(bytes);
        }
    }

    /// Counts down by 7 per read (like SysTick); every masked-section window reports 14 ticks
    /// (as if a critical section of 14 ticks ran in it).
    struct FakeTicks(Cell<u32>);
    impl TickCounter for FakeTicks {
        fn take_masked_max(&self) -> u32 {
            14
        }
        fn now(&self) -> u32 {
            let v = self.0.get().wrapping_sub(7);
            self.0.set(v);
            v
        }
        fn since(&self, start: u32) -> u32 {
            start.wrapping_sub(self.now())
        }
    }

    fn frames(bytes: &[u8]) -> Vec<(u32, Vec<u8>)> {
        let mut p = FrameParser::new();
        let mut out = Vec::new();
        p.push_bytes(bytes, frame_extra_crc, |f| out.push((f.msg_id, f.payload.to_vec())));
        out
    }

    #[test]
    fn handshake_then_lockstep_answers_each_sensor_sample() {
        let cal = InstructionCalibration { instructions: 100_000, ticks: 16_800 };
        let mut app = PilApp::new(RecordingAutopilot::new(), cal);
        let mut port = FakePort::default();
        let ticks = FakeTicks(Cell::new(1_000_000));
        assert!(!app.handshake_round(&mut port, &ticks, 700));
        assert!(!app.handshake_round(&mut port, &ticks, 700));
        let sent = frames(&port.tx);
        assert_eq!(sent.len(), 2);
        assert!(sent.iter().all(|(id, _)| *id == HEARTBEAT_DATA::ID));

        let mut host = FrameWriter::new(255, 190);
        port.rx.extend(host.encode(&HEARTBEAT_DATA::default()).raw_bytes());
        port.tx.clear();
        assert!(app.handshake_round(&mut port, &ticks, 700));
        let sent = frames(&port.tx);
        let ints: Vec<NAMED_VALUE_INT_DATA> = sent
            .iter()
            .filter(|(id, _)| *id == NAMED_VALUE_INT_DATA::ID)
            .filter_map(|(_, p)| NAMED_VALUE_INT_DATA::deser(MavlinkVersion::V2, p).ok())
            .collect();
        assert!(ints
            .iter()
            .any(|m| crate::link::telemetry::name_is(&m.name, "ins_cal") && m.value == 16_800));
        assert!(ints
            .iter()
            .any(|m| crate::link::telemetry::name_is(&m.name, "ins_cal_n") && m.value == 100_000));

        for k in 0..3u64 {
            port.tx.clear();
            let t = 2_000_000 + k * 1000;
            port.rx.extend(
                host.encode(&HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() }).raw_bytes(),
            );
            assert_eq!(app.poll(&mut port, &ticks), 1);
            let sent = frames(&port.tx);
            let (last_id, last) = sent.last().cloned().unwrap_or_default();
            assert_eq!(last_id, HIL_ACTUATOR_CONTROLS_DATA::ID);
            let ctl = HIL_ACTUATOR_CONTROLS_DATA::deser(MavlinkVersion::V2, &last).expect("decodes");
            assert_eq!(ctl.time_usec, t);
            let int_at = |i: usize| {
                let (id, m) = &sent[i];
                assert_eq!(*id, NAMED_VALUE_INT_DATA::ID);
                NAMED_VALUE_INT_DATA::deser(MavlinkVersion::V2, m).expect("decodes")
            };
            let step = int_at(sent.len() - 2);
            assert!(crate::link::telemetry::name_is(&step.name, "ins_step"));
            // The longest masked section of the step comes before `ins_step`: 14 ticks ≈ 83.
            let masked = int_at(sent.len() - 3);
            assert!(crate::link::telemetry::name_is(&masked.name, "ins_masked"));
            assert_eq!(masked.value, 83);
            if k == 0 {
                // The first sample runs the outer loop, timed by its own read pair (7 fake ticks →
                // 7 × 100000 / 16800 ≈ 42, reported as `ins_outer` before `ins_step`); the whole
                // step spans three reads after its start: 21 ticks ≈ 125 instructions.
                let outer = int_at(sent.len() - 4);
                assert!(crate::link::telemetry::name_is(&outer.name, "ins_outer"));
                assert_eq!(outer.value, 42);
                assert_eq!(step.value, 125);
            } else {
                // Inner only: one tick read pair around the step = 7 fake ticks ≈ 42.
                assert_eq!(step.value, 42);
                assert!(!sent.iter().any(|(id, m)| *id == NAMED_VALUE_INT_DATA::ID
                    && NAMED_VALUE_INT_DATA::deser(MavlinkVersion::V2, m)
                        .is_ok_and(|m| crate::link::telemetry::name_is(&m.name, "ins_outer"))));
            }
        }
        assert_eq!(app.autopilot().inner_steps, vec![2_000_000, 2_001_000, 2_002_000]);
        assert_eq!(app.stats().steps, 3);
        assert_eq!(app.stats().max_masked_instructions, 83);
        // Nothing pending: no answer.
        port.tx.clear();
        assert_eq!(app.poll(&mut port, &ticks), 0);
        assert!(port.tx.is_empty());
    }

    /// The host's BATTERY_STATUS (its system and component id, before a step's HIL_SENSOR) is
    /// measured by the cascade's estimator with the parameters as set: SYS_STATUS and the
    /// vehicle's own BATTERY_STATUS report it; an unknown voltage is refused (the state stays),
    /// and a BATTERY_STATUS from another system is no reading.
    #[test]
    fn the_hosts_battery_status_is_measured_and_reported() {
        use crate::app::autopilot::Autopilot;
        use crate::app::cascade::Cascade;
        use crate::link::dialect::{BATTERY_STATUS_DATA, SYS_STATUS_DATA};
        use crate::vehicle::SetupVehicle;
        use parapet_core::battery::BatteryLevel;
        use parapet_core::wire::battery::{battery_to_wire, UNKNOWN_MV};
        use parapet_core::wire::ids::{HOST_COMPONENT_ID, HOST_SYSTEM_ID};

        let mut params = ControllerParams::default();
        params.battery.cells = 3;
        let cascade = Cascade::new(params).expect("default parameters");
        let cal = InstructionCalibration { instructions: 100_000, ticks: 16_800 };
        let mut app = std::boxed::Box::new(PilApp::new(SetupVehicle::new(cascade, params), cal));
        let mut port = FakePort::default();
        let ticks = FakeTicks(Cell::new(1_000_000));
        let mut host = FrameWriter::new(HOST_SYSTEM_ID, HOST_COMPONENT_ID);
        port.rx.extend(host.encode(&HEARTBEAT_DATA::default()).raw_bytes());
        assert!(app.handshake_round(&mut port, &ticks, 700));
        let battery = |v: f32, i: Option<f32>| {
            let w = battery_to_wire(v, i);
            let mut voltages = [UNKNOWN_MV; 10];
            voltages[..2].copy_from_slice(&w.voltages_mv);
            BATTERY_STATUS_DATA { voltages, current_battery: w.current_ca, ..Default::default() }
        };
        let mut t = 2_000_000u64;
        let mut step = |app: &mut PilApp<SetupVehicle<Cascade>>, port: &mut FakePort, extra: &[u8]| {
            port.rx.extend(extra);
            let mut w = FrameWriter::new(HOST_SYSTEM_ID, HOST_COMPONENT_ID);
            port.rx.extend(
                w.encode(&HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() }).raw_bytes(),
            );
            t += 1000;
            assert_eq!(app.poll(port, &ticks), 1);
        };
        step(&mut app, &mut port, &[]);
        assert_eq!(app.autopilot().telemetry().battery, None, "no reading yet");
        step(&mut app, &mut port, host.encode(&battery(11.4, Some(4.5))).raw_bytes());
        let st = app.battery().stats();
        assert_eq!((st.readings, st.refused), (1, 0));
        let b = app.autopilot().telemetry().battery.expect("the cascade took the measurement");
        // Stamped with the firmware time of the step before the one it came with.
        assert_eq!(
            (b.t_us, b.voltage_v, b.current_a, b.level),
            (2_000_000, 11.4, Some(4.5), BatteryLevel::Ok)
        );
        // Unknown voltage: refused by the estimator, the measurement unchanged.
        step(&mut app, &mut port, host.encode(&battery(f32::NAN, Some(4.5))).raw_bytes());
        assert_eq!((app.battery().stats().readings, app.battery().stats().refused), (2, 1));
        assert_eq!(app.autopilot().telemetry().battery, Some(b));
        // Another system's BATTERY_STATUS (a ground station's, a vehicle's) is no reading.
        let mut other = FrameWriter::new(42, 1);
        step(&mut app, &mut port, other.encode(&battery(3.0, Some(1.0))).raw_bytes());
        assert_eq!(app.battery().stats().readings, 2);
        assert_eq!(app.autopilot().telemetry().battery, Some(b));
        // One second on: SYS_STATUS and the vehicle's BATTERY_STATUS carry the measurement.
        port.tx.clear();
        for _ in 0..1000 {
            step(&mut app, &mut port, &[]);
        }
        let sent = frames(&port.tx);
        let sys = sent
            .iter()
            .filter(|(id, _)| *id == SYS_STATUS_DATA::ID)
            .map(|(_, p)| SYS_STATUS_DATA::deser(MavlinkVersion::V2, p).expect("decodes"))
            .next_back()
            .expect("SYS_STATUS at 1 Hz");
        assert_eq!((sys.voltage_battery, sys.current_battery), (11_400, 450));
        let bs = sent
            .iter()
            .filter(|(id, _)| *id == BATTERY_STATUS_DATA::ID)
            .map(|(_, p)| BATTERY_STATUS_DATA::deser(MavlinkVersion::V2, p).expect("decodes"))
            .next_back()
            .expect("BATTERY_STATUS at 1 Hz");
        assert_eq!((bs.voltages[0], bs.current_battery), (11_400, 450));
        assert_eq!(app.link().stats().decode_errors, 0);
    }

    #[test]
    fn onboard_log_is_written_between_steps_and_downloaded_over_the_link() {
        use crate::link::dialect::{
            MavCmd, COMMAND_LONG_DATA, LOG_DATA_DATA, LOG_ENTRY_DATA, LOG_REQUEST_DATA_DATA,
            LOG_REQUEST_LIST_DATA,
        };
        use crate::log::store::LogStore;
        let cal = InstructionCalibration { instructions: 100_000, ticks: 16_800 };
        let store: &'static mut RamLogStore = std::boxed::Box::leak(std::boxed::Box::new(RamLogStore::new()));
        let mut app =
            PilApp::new(RecordingAutopilot::new(), cal).with_log(store, &ControllerParams::default());
        let mut port = FakePort::default();
        let ticks = FakeTicks(Cell::new(1_000_000));
        let mut host = FrameWriter::new(255, 190);
        port.rx.extend(host.encode(&HEARTBEAT_DATA::default()).raw_bytes());
        assert!(app.handshake_round(&mut port, &ticks, 700));
        let arm = |on: bool| COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
            param1: if on { 1.0 } else { 0.0 },
            target_system: 1,
            target_component: 1,
            ..Default::default()
        };
        let mut t = 1_000_000u64;
        let mut step = |app: &mut PilApp<RecordingAutopilot>, port: &mut FakePort, extra: &[u8]| {
            port.rx.extend(extra);
            port.rx.extend(host_step(t));
            t += 1000;
            app.poll(port, &ticks);
        };
        fn host_step(t: u64) -> Vec<u8> {
            let mut w = FrameWriter::new(255, 190);
            w.encode(&HIL_SENSOR_DATA { time_usec: t, zacc: -9.81, ..Default::default() })
                .raw_bytes()
                .to_vec()
        }
        step(&mut app, &mut port, host.encode(&arm(true)).raw_bytes());
        for _ in 0..1000 {
            step(&mut app, &mut port, &[]);
        }
        step(&mut app, &mut port, host.encode(&arm(false)).raw_bytes());
        for _ in 0..10 {
            step(&mut app, &mut port, &[]);
        }
        let st = app.stats();
        assert_eq!(st.log_dropped, 0);
        assert!(st.max_log_instructions > 0 && st.max_log_queue_instructions > 0);
        let log = app.log().expect("log");
        // 1 s armed at 25 Hz and the disarm record.
        assert_eq!(log.logger_stats().logs, 1);
        assert!((25..=27).contains(&log.logger_stats().records), "{:?}", log.logger_stats());
        let size = log.store().info(0).expect("a log").size;
        // The ins_log reports went out with the steps.
        let ins_logs = frames(&port.tx)
            .into_iter()
            .filter(|(id, p)| {
                *id == NAMED_VALUE_INT_DATA::ID
                    && NAMED_VALUE_INT_DATA::deser(MavlinkVersion::V2, p)
                        .is_ok_and(|m| crate::link::telemetry::name_is(&m.name, INS_LOG))
            })
            .count();
        assert!((25..=27).contains(&ins_logs), "{ins_logs}");

        port.tx.clear();
        let list = LOG_REQUEST_LIST_DATA { start: 0, end: 0xFFFF, target_system: 1, target_component: 1 };
        step(&mut app, &mut port, host.encode(&list).raw_bytes());
        let entries: Vec<LOG_ENTRY_DATA> = frames(&port.tx)
            .into_iter()
            .filter(|(id, _)| *id == LOG_ENTRY_DATA::ID)
            .map(|(_, p)| LOG_ENTRY_DATA::deser(MavlinkVersion::V2, &p).expect("decodes"))
            .collect();
        assert_eq!(entries.len(), 1);
        assert_eq!((entries[0].id, entries[0].num_logs, entries[0].size), (0, 1, size));
        port.tx.clear();
        let req =
            LOG_REQUEST_DATA_DATA { id: 0, ofs: 0, count: u32::MAX, target_system: 1, target_component: 1 };
        step(&mut app, &mut port, host.encode(&req).raw_bytes());
        for _ in 0..(size as usize / 90 / REPLIES_PER_POLL + 2) {
            step(&mut app, &mut port, &[]);
        }
        let mut bytes = std::vec![0u8; size as usize];
        let mut got = 0;
        for (_, p) in frames(&port.tx).into_iter().filter(|(id, _)| *id == LOG_DATA_DATA::ID) {
            let d = LOG_DATA_DATA::deser(MavlinkVersion::V2, &p).expect("decodes");
            let n = usize::from(d.count);
            bytes[d.ofs as usize..d.ofs as usize + n].copy_from_slice(&d.data[..n]);
            got += n;
        }
        assert_eq!(got, size as usize);
        let mut stored = std::vec![0u8; size as usize];
        let log = app.log().expect("log");
        let id = log.store().info(0).expect("log").id;
        assert_eq!(log.store().read(id, 0, &mut stored), Ok(size as usize));
        assert_eq!(bytes, stored);
        assert_eq!(&bytes[..8], &parapet_core::wire::ulog::MAGIC);
    }
}

//! Boots the `board-qemu` firmware in `qemu-system-arm -machine netduinoplus2 -icount shift=0`,
//! runs the heartbeat handshake and 2 s of simulated lockstep on a vehicle at rest (arm at
//! 0.5 s), injects corrupted frames and a truncated HIL_SENSOR, and checks the answers.
//!
//! Needs `qemu-system-arm` and the ELF built by
//! `cargo build -p parapet-firmware --release --target thumbv7em-none-eabihf --no-default-features
//!  --features board-qemu --bin parapet-firmware-qemu`; its path in `PARAPET_QEMU_ELF`.
//! Run: `PARAPET_QEMU_ELF=… cargo test -p parapet-firmware --test qemu_pil -- --ignored --nocapture`.

use std::io::{Read, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use mavlink_core::{MavlinkVersion, MessageData};
use parapet_core::controller::ControllerParams;
use parapet_core::wire::ids::EMPTY_BATCH_RANGE;
use parapet_core::wire::names;
use parapet_firmware::app::cascade::Cascade;
use parapet_firmware::link::dialect::{
    MavCmd, MavFrame, MavModeFlag, MavResult, COMMAND_ACK_DATA, COMMAND_LONG_DATA, DEBUG_VECT_DATA,
    HEARTBEAT_DATA, HIL_ACTUATOR_CONTROLS_DATA, HIL_SENSOR_DATA, NAMED_VALUE_INT_DATA,
    OBSTACLE_DISTANCE_3D_DATA, ODOMETRY_DATA, STATUSTEXT_DATA,
};
use parapet_firmware::link::frame_parser::FrameParser;
use parapet_firmware::link::framing::FrameWriter;
use parapet_firmware::link::messages::frame_extra_crc;
use parapet_firmware::link::obstacles::CLEAR_ID;
use parapet_firmware::link::telemetry::name_is;
use parapet_firmware::pil::lockstep::InstructionCalibration;
use parapet_firmware::pil::{BytePort, PilApp, TickCounter};

/// Longest section with interrupts masked that a control step may contain, instructions: the
/// critical section of one mailbox operation, i.e. copying the largest message (the telemetry
/// snapshot, ≈ 150 bytes: ≈ 80 load/store instructions) plus the primitive's bookkeeping and
/// waker check. The outer step alone is ≈ 5 000 instructions, the inner step ≈ 2 000.
const MASKED_BOUND: i32 = 400;

/// Kills QEMU on every exit path.
struct Qemu(Child);
impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

struct Host {
    /// Every byte sent, for the host-side mirror of the firmware.
    sent: Vec<u8>,
    /// QEMU's stdin: the firmware's semihosting console input.
    to_fw: ChildStdin,
    /// Chunks of QEMU's stdout (the console output), read by a thread (pipes have no timeout).
    from_fw: mpsc::Receiver<Vec<u8>>,
    parser: FrameParser,
    writer: FrameWriter,
    inbox: std::collections::VecDeque<(u32, Vec<u8>)>,
}

impl Host {
    fn send<D: MessageData>(&mut self, m: &D) {
        let raw = self.writer.encode(m);
        self.write(raw.raw_bytes());
    }

    fn write(&mut self, b: &[u8]) {
        self.sent.extend_from_slice(b);
        self.to_fw.write_all(b).expect("write to QEMU's stdin");
    }

    fn send_corrupted<D: MessageData>(&mut self, m: &D) {
        let raw = self.writer.encode(m);
        let mut b = raw.raw_bytes().to_vec();
        let n = b.len();
        b[n - 3] ^= 0x5A;
        self.write(&b);
    }

    fn send_truncated<D: MessageData>(&mut self, m: &D) {
        let raw = self.writer.encode(m);
        let b = raw.raw_bytes();
        let half = b[..b.len() / 2].to_vec();
        self.write(&half);
    }

    /// Next frame, or `None` after `timeout`.
    fn next(&mut self, timeout: Duration) -> Option<(u32, Vec<u8>)> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(f) = self.inbox.pop_front() {
                return Some(f);
            }
            let left = end.checked_duration_since(Instant::now())?;
            match self.from_fw.recv_timeout(left.max(Duration::from_millis(1))) {
                Ok(chunk) => {
                    let inbox = &mut self.inbox;
                    self.parser.push_bytes(&chunk, frame_extra_crc, |f| {
                        inbox.push_back((f.msg_id, f.payload.to_vec()))
                    });
                }
                Err(mpsc::RecvTimeoutError::Timeout) => return None,
                Err(mpsc::RecvTimeoutError::Disconnected) => return None,
            }
        }
    }
}

/// In-memory port for the host-side mirror: the same `PilApp` + `Cascade` the firmware runs.
#[derive(Default)]
struct MemPort {
    rx: std::collections::VecDeque<u8>,
    tx: Vec<u8>,
}
impl BytePort for MemPort {
    fn try_read(&mut self) -> Option<u8> {
        self.rx.pop_front()
    }
    fn write(&mut self, bytes: &[u8]) {
        self.tx.extend_from_slice(bytes);
    }
}
struct NoTicks;
impl TickCounter for NoTicks {
    fn now(&self) -> u32 {
        0
    }
    fn since(&self, _start: u32) -> u32 {
        0
    }
}

/// Throttles the mirror answered for simulated time `t`.
fn mirror_step(app: &mut PilApp<Cascade>, port: &mut MemPort, bytes: &[u8], t: u64) -> Option<[f32; 4]> {
    port.rx.extend(bytes);
    port.tx.clear();
    app.poll(port, &NoTicks);
    let mut p = FrameParser::new();
    let mut out = None;
    p.push_bytes(&port.tx, frame_extra_crc, |f| {
        if f.msg_id == HIL_ACTUATOR_CONTROLS_DATA::ID {
            let c: HIL_ACTUATOR_CONTROLS_DATA = de(f.payload);
            if c.time_usec == t {
                out = Some([c.controls[0], c.controls[1], c.controls[2], c.controls[3]]);
            }
        }
    });
    out
}

fn de<D: MessageData>(p: &[u8]) -> D {
    D::deser(MavlinkVersion::V2, p).expect("decodes")
}

#[test]
#[ignore = "needs qemu-system-arm and the board-qemu ELF (PARAPET_QEMU_ELF); run by cargo xtask test"]
fn firmware_boots_handshakes_and_answers_lockstep_in_qemu() {
    let elf = std::env::var("PARAPET_QEMU_ELF").expect("set PARAPET_QEMU_ELF to the board-qemu firmware ELF");
    // The lockstep link is QEMU's stdin/stdout: the firmware's semihosting console (`:tt`).
    // No chardev may use stdio (`-serial null`, `-monitor none`, `-display none`), so the
    // pipes stay blocking and the firmware's SYS_READ waits in read(2) for our bytes.
    let mut child = Command::new("qemu-system-arm")
        .args(["-machine", "netduinoplus2", "-display", "none", "-monitor", "none", "-serial", "null"])
        .args(["-semihosting-config", "enable=on,target=native", "-kernel", &elf])
        .args(["-icount", &std::env::var("PARAPET_QEMU_ICOUNT").unwrap_or_else(|_| "shift=0".into())])
        // Extra QEMU arguments for debugging, e.g. "-d int -D /tmp/qemu.log".
        .args(std::env::var("PARAPET_QEMU_ARGS").unwrap_or_default().split_whitespace())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("qemu-system-arm starts");
    let to_fw = child.stdin.take().expect("QEMU stdin pipe");
    let mut stdout = child.stdout.take().expect("QEMU stdout pipe");
    let _qemu = Qemu(child);
    let (tx, from_fw) = mpsc::channel();
    std::thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok(n) = stdout.read(&mut buf) {
            if n == 0 || tx.send(buf[..n].to_vec()).is_err() {
                break;
            }
        }
    });
    let mut h = Host {
        sent: Vec::new(),
        to_fw,
        from_fw,
        parser: FrameParser::new(),
        writer: FrameWriter::new(255, 190),
        inbox: Default::default(),
    };

    // Handshake: the firmware heartbeats until our first frame.
    let mut heartbeats = 0;
    while heartbeats == 0 {
        match h.next(Duration::from_secs(10)) {
            Some((id, _)) if id == HEARTBEAT_DATA::ID => heartbeats += 1,
            Some(_) => {}
            None => panic!("no HEARTBEAT from the firmware within 10 s"),
        }
    }
    h.send(&HEARTBEAT_DATA::default());
    let cascade = Cascade::new(ControllerParams::default()).expect("default parameters");
    let mut mirror = PilApp::new(cascade, InstructionCalibration { instructions: 1, ticks: 1 });
    let mut mirror_port = MemPort::default();
    let mut mismatches = 0usize;
    let mut max_diff = 0.0f32;
    let mut compared = 0usize;
    let mut varied = std::collections::BTreeSet::new();
    let (mut cal, mut cal_n, mut ready) = (None, None, false);
    while cal.is_none() || cal_n.is_none() || !ready {
        let Some((id, p)) = h.next(Duration::from_secs(5)) else {
            panic!("no calibration after the handshake")
        };
        if id == NAMED_VALUE_INT_DATA::ID {
            let m: NAMED_VALUE_INT_DATA = de(&p);
            if name_is(&m.name, "ins_cal") {
                cal = Some(m.value);
            } else if name_is(&m.name, "ins_cal_n") {
                cal_n = Some(m.value);
            }
        } else if id == STATUSTEXT_DATA::ID {
            ready = true;
        }
    }
    let (cal, cal_n) = (cal.unwrap_or(0), cal_n.unwrap_or(0));
    println!("calibration: {cal_n} instructions = {cal} SysTick ticks");
    assert!(cal > 0 && cal_n > 0);

    // Lockstep: 2 s of simulated time at 1 kHz, vehicle at rest; arm at 0.5 s.
    let steps = 2000u64;
    let mut ins = Vec::new();
    let mut masked = Vec::new();
    let mut acks = Vec::new();
    let mut link_crc_errors = 0.0f32;
    let mut corrupted = 0;
    let mut corrupted_at_link = 0;
    let mut last_ctl = None;
    let mut step_wall: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let wall = Instant::now();
    for k in 0..steps {
        let t = 1_000_000 + k * 1000;
        if k % 4 == 0 {
            let kf = k as f32;
            h.send(&ODOMETRY_DATA {
                time_usec: t,
                x: 0.05 * (0.0031 * kf).sin(),
                y: 0.04 * (0.0023 * kf).cos(),
                z: -0.02 * (0.0017 * kf).sin(),
                vx: 0.02 * (0.0029 * kf).cos(),
                vy: -0.01 * (0.0041 * kf).sin(),
                q: [1.0, 0.0, 0.0, 0.0],
                frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
                ..Default::default()
            });
            if k < 1000 {
                h.send(&OBSTACLE_DISTANCE_3D_DATA {
                    time_boot_ms: (t / 1000) as u32,
                    obstacle_id: CLEAR_ID,
                    frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    // The empty-batch marker is the empty range (id 65535 alone is a point).
                    min_distance: EMPTY_BATCH_RANGE.0,
                    max_distance: EMPTY_BATCH_RANGE.1,
                    ..Default::default()
                });
            } else {
                // A moving obstacle 0.6 m north, 0.3 m up, approaching.
                let mut name = [0u8; 10];
                name[..4].copy_from_slice(b"OBV3");
                h.send(&DEBUG_VECT_DATA { time_usec: t, x: -0.2, y: 0.05, z: 0.0, name: name.into() });
                h.send(&OBSTACLE_DISTANCE_3D_DATA {
                    time_boot_ms: (t / 1000) as u32,
                    x: 0.6 - 0.0002 * (k - 1000) as f32,
                    y: 0.0,
                    z: -0.3,
                    obstacle_id: 3,
                    frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    ..Default::default()
                });
            }
        }
        if k % 50 == 25 {
            h.send_corrupted(&HEARTBEAT_DATA::default());
            corrupted += 1;
        }
        if k == 500 {
            h.send(&COMMAND_LONG_DATA {
                param1: 1.0,
                command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
                target_system: 1,
                target_component: 1,
                ..Default::default()
            });
        }
        if k == 700 {
            // Hold 1 m above the origin: the cascade now flies (no plant moves the vehicle, but
            // every stage of the cascade computes real outputs from the varying inputs).
            h.send(&COMMAND_LONG_DATA {
                param2: 3.0,
                param3: 1.0,
                param7: -1.0,
                command: MavCmd::MAV_CMD_OVERRIDE_GOTO as u16,
                target_system: 1,
                target_component: 1,
                ..Default::default()
            });
        }
        let kf = k as f32;
        let hil = HIL_SENSOR_DATA {
            time_usec: t,
            xgyro: 0.02 * (0.013 * kf).sin(),
            ygyro: 0.02 * (0.007 * kf).cos(),
            zgyro: 0.01 * (0.003 * kf).sin(),
            xacc: 0.1 * (0.011 * kf).sin(),
            yacc: 0.1 * (0.005 * kf).cos(),
            zacc: -9.81 + 0.05 * (0.017 * kf).sin(),
            ..Default::default()
        };
        if k == 1500 {
            // A truncated HIL_SENSOR: no answer may come; the framer must not stall, so the
            // complete one sent next is answered.
            h.send_truncated(&hil);
            assert!(
                !matches!(h.next(Duration::from_millis(300)), Some((id, _)) if id == HIL_ACTUATOR_CONTROLS_DATA::ID),
                "answer to a truncated frame"
            );
        }
        h.send(&hil);
        let t_sent = Instant::now();
        loop {
            let Some((id, p)) = h.next(Duration::from_secs(5)) else {
                panic!("firmware stopped answering at step {k}")
            };
            match id {
                HIL_ACTUATOR_CONTROLS_DATA::ID => {
                    let c: HIL_ACTUATOR_CONTROLS_DATA = de(&p);
                    assert_eq!(c.time_usec, t, "answer for the wrong step");
                    let sent = std::mem::take(&mut h.sent);
                    let m = mirror_step(&mut mirror, &mut mirror_port, &sent, t).expect("mirror answers");
                    compared += 1;
                    for (got, want) in c.controls[..4].iter().zip(m) {
                        if got.to_bits() != want.to_bits() {
                            mismatches += 1;
                        }
                        max_diff = max_diff.max((got - want).abs());
                        varied.insert(got.to_bits());
                    }
                    last_ctl = Some(c);
                    step_wall[(k % 4 == 0) as usize].push(t_sent.elapsed().as_secs_f64());
                    break;
                }
                NAMED_VALUE_INT_DATA::ID => {
                    let m: NAMED_VALUE_INT_DATA = de(&p);
                    if name_is(&m.name, names::INS_STEP) {
                        ins.push(m.value);
                    } else if name_is(&m.name, names::INS_MASKED) {
                        masked.push(m.value);
                    }
                }
                COMMAND_ACK_DATA::ID => acks.push(de::<COMMAND_ACK_DATA>(&p).result),
                DEBUG_VECT_DATA::ID => {
                    let d: DEBUG_VECT_DATA = de(&p);
                    if name_is(&d.name, "LINK") {
                        link_crc_errors = d.y;
                        corrupted_at_link = corrupted;
                    }
                }
                _ => {}
            }
        }
    }
    let wall = wall.elapsed().as_secs_f64();
    let avg = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64 * 1e3;
    println!(
        "wall per step from HIL_SENSOR to answer: {:.2} ms (inner only), {:.2} ms (with outer + odometry + obstacles)",
        avg(&step_wall[0]),
        avg(&step_wall[1])
    );
    assert_eq!(ins.len() as u64, steps);
    let mean = ins.iter().map(|&v| v as f64).sum::<f64>() / ins.len() as f64;
    let max = ins.iter().copied().max().unwrap_or(0);
    println!(
        "{steps} steps in {wall:.2} s wall (real-time factor {:.2}); instructions per control step: mean {mean:.0}, max {max}",
        (steps as f64 * 1e-3) / wall
    );
    assert!(mean > 100.0, "implausible instruction count {mean}");
    // Interrupts masked: only the mailboxes' critical sections (one message copy each), never a
    // control computation.
    assert_eq!(masked.len() as u64, steps);
    let masked_max = masked.iter().copied().max().unwrap_or(0);
    println!("longest section with interrupts masked per control step: max {masked_max} instructions (bound {MASKED_BOUND})");
    assert!(masked_max > 0, "the mailboxes' critical sections must be measured");
    assert!(
        masked_max <= MASKED_BOUND,
        "a control step ran {masked_max} instructions with interrupts masked"
    );
    assert_eq!(acks, vec![MavResult::MAV_RESULT_ACCEPTED; 2], "arm and hold accepted");
    let c = last_ctl.expect("answers");
    assert!(c.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    assert!(c.controls[..4].iter().all(|&x| x > 0.0 && x <= 1.0), "throttles {:?}", &c.controls[..4]);
    // The ARM binary and the host build of the same cascade agree bit for bit (IEEE-754 f32,
    // no FMA contraction, same libm code) on every throttle of every step.
    println!(
        "PIL vs host mirror: {compared} steps, {mismatches} differing throttles, max |diff| {max_diff:e}, {} distinct values",
        varied.len()
    );
    assert_eq!(compared as u64, steps);
    assert!(varied.len() > 100, "the cascade's output must vary for the comparison to mean something");
    assert_eq!(mismatches, 0, "max diff {max_diff}");
    // LINK (1 Hz) counts the corrupted frames sent before it; a resync inside a corrupted frame
    // may add a second CRC error, never fewer.
    assert!(corrupted_at_link >= 20, "{corrupted_at_link}");
    assert!(
        link_crc_errors >= corrupted_at_link as f32,
        "LINK crc errors {link_crc_errors}, injected {corrupted_at_link}"
    );
}

"""The setup services of the QEMU firmware with pymavlink (issue 22): this script is the PIL host
itself: it starts qemu-system-arm with the board-qemu ELF, does the lockstep handshake and
steps the vehicle at rest on the ground (HIL_SENSOR at 1 kHz, ODOMETRY and an empty obstacle
batch at 250 Hz, firmware/README.md "QEMU lockstep protocol"), and in between sends what a
ground station sends:

1. PARAM_SET CBF_MU 2.0 -> PREFLIGHT_STORAGE write -> PARAM_SET CBF_MU 1.0 -> PREFLIGHT_STORAGE
   read -> CBF_MU is 2.0 again (the stored value, read back from the RAM-backed flash);
2. PREFLIGHT_STORAGE reset -> "Params: reset to defaults", CBF_MU default; a read then finds
   nothing stored;
3. the debounced save after a PARAM_SET (1 s later, no command);
4. DO_MOTOR_TEST disarmed: accepted, motor 1 only spins (HIL_ACTUATOR_CONTROLS) until the
   timeout; a second test is stopped by the next command;
5. PREFLIGHT_CALIBRATION level (param5 2) with the board tilted: start / progress / done
   STATUSTEXTs as QGroundControl parses them, CAL_TRIM_PITCH the tilt;
6. armed (ARM on the ground): DO_MOTOR_TEST, PREFLIGHT_STORAGE and PREFLIGHT_CALIBRATION
   DENIED, each with its STATUSTEXT reason; disarm.

Every storage call that used the flash reports NAMED_VALUE_INT ins_store (instructions); the
script prints their maximum. The firmware's stack watermark (NAMED_VALUE_INT stack_free, the
stack never used since boot) must stay >= 1 KiB. usage: pil_setup.py ELF [QEMU]   (exit 0 and "PASS" = every step
passed; the failed step is printed).
"""
import math
import os
import select
import subprocess
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

ELF = sys.argv[1]
QEMU = sys.argv[2] if len(sys.argv) > 2 else "qemu-system-arm"
M = mavlink
CMD_DO_MOTOR_TEST, CMD_CAL, CMD_STORAGE, CMD_ARM = 209, 241, 245, 400
TILT = 0.05  # rad of pitch for the level calibration
G = 9.80665


def fail(why):
    print("FAIL:", why, flush=True)
    if "pil" in globals():
        print("STATUSTEXTs so far:", pil.texts[-12:], flush=True)
    sys.exit(1)


class Pil:
    def __init__(self):
        self.p = subprocess.Popen(
            [QEMU, "-machine", "netduinoplus2", "-display", "none", "-monitor", "none", "-serial", "null",
             "-icount", "shift=0", "-semihosting-config", "enable=on,target=native", "-kernel", ELF],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0)
        self.out = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.inp = mavlink.MAVLink(None)
        self.inp.robust_parsing = True
        self.t = 1_000_000
        self.accel = (0.0, 0.0, -G)
        self.texts = []
        self.ins_store = []
        self.stack_free = []
        self.log_ins = {}
        self.params = {}
        self.acks = []
        self.controls = None

    def close(self):
        try:
            self.p.stdin.close()
            self.p.wait(timeout=5)
        except Exception:
            self.p.kill()

    def read_until(self, done, timeout=10.0):
        """Frames until done(msg) is true; every message is also recorded."""
        end = time.time() + timeout
        while time.time() < end:
            r, _, _ = select.select([self.p.stdout], [], [], 0.5)
            if not r:
                if self.p.poll() is not None:
                    fail(f"qemu exited ({self.p.returncode})")
                continue
            data = os.read(self.p.stdout.fileno(), 65536)
            if not data:
                fail("qemu closed its stdout")
            hit = None
            for m in self.inp.parse_buffer(data) or []:
                self.record(m)
                if hit is None and done(m):
                    hit = m
            if hit is not None:
                return hit
        fail("no answer from the firmware within %.0f s" % timeout)

    def record(self, m):
        ty = m.get_type()
        if ty == "STATUSTEXT":
            self.texts.append(m.text)
        elif ty == "NAMED_VALUE_INT" and m.name == "ins_store":
            self.ins_store.append(m.value)
        elif ty == "NAMED_VALUE_INT" and m.name == "stack_free":
            self.stack_free.append(m.value)
        elif ty == "NAMED_VALUE_INT" and m.name in ("ins_log", "ins_logq", "ins_logm"):
            self.log_ins.setdefault(m.name, []).append(m.value)
        elif ty == "PARAM_VALUE":
            self.params[m.param_id] = m.param_value
        elif ty == "COMMAND_ACK":
            self.acks.append((m.command, m.result))

    def handshake(self):
        self.read_until(lambda m: m.get_type() == "HEARTBEAT", 30)
        self.p.stdin.write(self.out.heartbeat_encode(6, 8, 0, 0, 0).pack(self.out))
        self.read_until(lambda m: m.get_type() == "STATUSTEXT" and "PIL ready" in m.text, 30)

    def step(self, extra=()):
        """One 1 ms period: (fix and empty obstacle batch at the outer rate), extra, HIL_SENSOR."""
        t = self.t
        b = b""
        if (t // 1000) % 4 == 0:
            b += self.out.odometry_encode(t, 1, 1, 0.0, 0.0, 0.0, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0,
                                          [0] * 21, [0] * 21).pack(self.out)
            # The empty batch: id 65535 with the empty range min 1 > max 0 (wire::ids).
            b += self.out.obstacle_distance_3d_encode(t // 1000, 0, 1, 65535, 0, 0, 0, 1.0, 0.0).pack(self.out)
        for m in extra:
            b += m.pack(self.out)
        ax, ay, az = self.accel
        b += self.out.hil_sensor_encode(t, ax, ay, az, 0, 0, 0, 0, 0, 0, 0, 0, 0, 20, 0).pack(self.out)
        self.p.stdin.write(b)
        a = self.read_until(lambda m: m.get_type() == "HIL_ACTUATOR_CONTROLS" and m.time_usec == t)
        self.controls = list(a.controls[:4])
        self.t += 1000
        return a

    def steps(self, n):
        for _ in range(n):
            self.step()

    def command(self, cmd, *p):
        p = list(p) + [0.0] * (7 - len(p))
        n = len(self.acks)
        self.step([self.out.command_long_encode(1, 1, cmd, 0, *p)])
        got = [r for c, r in self.acks[n:] if c == cmd]
        if not got:
            self.step()
            got = [r for c, r in self.acks[n:] if c == cmd]
        if not got:
            fail(f"no COMMAND_ACK for command {cmd}")
        return got[0]

    def param_set(self, name, v):
        self.params.pop(name, None)
        self.step([self.out.param_set_encode(1, 1, name.encode(), v, M.MAV_PARAM_TYPE_REAL32)])
        return self.params.get(name)

    def param(self, name):
        self.params.pop(name, None)
        self.step([self.out.param_request_read_encode(1, 1, name.encode(), -1)])
        if name not in self.params:
            self.step()
        if name not in self.params:
            fail(f"PARAM_REQUEST_READ {name} not answered")
        return self.params[name]

    def text_since(self, n, needle, steps=5):
        for _ in range(steps):
            hit = [t for t in self.texts[n:] if needle in t]
            if hit:
                return hit[0]
            self.step()
        fail(f"no STATUSTEXT containing {needle!r}; got {self.texts[n:]}")


def expect(what, got, want):
    if got != want:
        fail(f"{what}: got {got}, expected {want}")
    print(f"ok: {what}", flush=True)


pil = Pil()
try:
    pil.handshake()
    pil.steps(200)
    default_mu = pil.param("CBF_MU")
    print(f"CBF_MU default {default_mu}", flush=True)

    # 1. Write, change, read back.
    expect("PARAM_SET CBF_MU 2.0 echoed", pil.param_set("CBF_MU", 2.0), 2.0)
    expect("PREFLIGHT_STORAGE write accepted", pil.command(CMD_STORAGE, 1.0), M.MAV_RESULT_ACCEPTED)
    pil.steps(2)
    if not pil.ins_store:
        fail("the write did not use the store (no ins_store)")
    expect("PARAM_SET CBF_MU 1.0 echoed", pil.param_set("CBF_MU", 1.0), 1.0)
    expect("PREFLIGHT_STORAGE read accepted", pil.command(CMD_STORAGE, 0.0), M.MAV_RESULT_ACCEPTED)
    pil.steps(2)
    expect("CBF_MU read back from the store", pil.param("CBF_MU"), 2.0)

    # 2. Reset to defaults; nothing stored after it.
    n = len(pil.texts)
    expect("PREFLIGHT_STORAGE reset accepted", pil.command(CMD_STORAGE, 2.0), M.MAV_RESULT_ACCEPTED)
    pil.text_since(n, "Params: reset to defaults")
    expect("CBF_MU back to its default", pil.param("CBF_MU"), default_mu)
    n = len(pil.texts)
    expect("PREFLIGHT_STORAGE read after reset", pil.command(CMD_STORAGE, 0.0), M.MAV_RESULT_ACCEPTED)
    pil.text_since(n, "Params: nothing stored")

    # 3. The debounced save: a PARAM_SET is written 1 s later without any command.
    k = len(pil.ins_store)
    pil.param_set("CBF_MU", 1.7)
    pil.steps(900)
    if len(pil.ins_store) != k:
        fail("saved before the 1 s debounce")
    pil.steps(150)
    if len(pil.ins_store) == k:
        fail("no debounced save within 1.05 s of the PARAM_SET")
    pil.param_set("CBF_MU", 1.0)
    expect("PREFLIGHT_STORAGE read (debounced value)", pil.command(CMD_STORAGE, 0.0), M.MAV_RESULT_ACCEPTED)
    pil.steps(2)
    expect("the debounced save stored CBF_MU 1.7", round(pil.param("CBF_MU"), 4), 1.7)
    print("ok: debounced save", flush=True)

    # 4. Motor test, disarmed: motor 1 at 10 % for 0.5 s, the others still.
    expect("DO_MOTOR_TEST disarmed accepted", pil.command(CMD_DO_MOTOR_TEST, 1, 0, 10.0, 0.5, 0, 0),
           M.MAV_RESULT_ACCEPTED)
    pil.steps(100)
    c = pil.controls
    if not (0.05 < c[0] <= 0.2 and c[1] == c[2] == c[3] == 0.0):
        fail(f"motor test output {c}, expected motor 1 only at ~10 %")
    print(f"ok: motor test drives motor 1 only: {c}", flush=True)
    pil.steps(450)
    if any(pil.controls):
        fail(f"motor test still running after its 0.5 s timeout: {pil.controls}")
    print("ok: motor test stops at its timeout", flush=True)
    pil.command(CMD_DO_MOTOR_TEST, 2, 0, 10.0, 5.0, 0, 0)
    pil.steps(20)
    if not pil.controls[1] > 0.0:
        fail(f"second motor test not running: {pil.controls}")
    pil.command(CMD_STORAGE, 0.0)
    pil.steps(2)
    if any(pil.controls):
        fail(f"motor test not stopped by another command: {pil.controls}")
    print("ok: any other command stops the motor test", flush=True)

    # 5. Level calibration with the board pitched by TILT.
    pil.accel = (G * math.sin(TILT), 0.0, -G * math.cos(TILT))
    pil.steps(50)
    n = len(pil.texts)
    expect("PREFLIGHT_CALIBRATION level accepted", pil.command(CMD_CAL, 0, 0, 0, 0, 2), M.MAV_RESULT_ACCEPTED)
    pil.steps(2100)
    cal = [t for t in pil.texts[n:] if t.startswith("[cal]")]
    print("calibration texts:", cal, flush=True)
    if not any("calibration started" in t for t in cal):
        fail("no '[cal] calibration started'")
    if not any("progress <" in t for t in cal):
        fail("no '[cal] progress <N>'")
    if not any("calibration done: level" in t for t in cal):
        fail("no '[cal] calibration done: level'")
    trim = pil.param("CAL_TRIM_PITCH")
    if not abs(abs(trim) - TILT) < 0.1 * TILT:
        fail(f"CAL_TRIM_PITCH {trim}, expected {TILT} in magnitude")
    print(f"ok: level calibration, CAL_TRIM_PITCH {trim:.4f} for a {TILT} rad tilt", flush=True)
    pil.steps(1100)  # the calibration result's debounced save

    # 6. Armed: every setup command refused with its reason.
    n = len(pil.texts)
    r = pil.command(CMD_ARM, 1.0)
    if r != M.MAV_RESULT_ACCEPTED:
        pil.steps(5)
        fail(f"ARM refused ({r}): {pil.texts[n:]}")
    pil.steps(1000)  # 1 s armed on the ground: the onboard log records (ins_log)
    for what, cmd, p, reason in [
        ("DO_MOTOR_TEST", CMD_DO_MOTOR_TEST, (1, 0, 10.0, 1.0), "Motor test refused: vehicle armed"),
        ("PREFLIGHT_STORAGE", CMD_STORAGE, (1.0,), "Params: storage denied while armed"),
        ("PREFLIGHT_CALIBRATION", CMD_CAL, (0, 0, 0, 0, 2), "calibration denied: vehicle armed"),
    ]:
        n = len(pil.texts)
        expect(f"{what} armed denied", pil.command(cmd, *p), M.MAV_RESULT_DENIED)
        pil.text_since(n, reason)
        print(f"ok: {what} armed: '{reason}'", flush=True)
    if pil.controls and max(pil.controls) > 0.2:
        fail(f"a refused motor test changed the armed output: {pil.controls}")
    expect("DISARM on the ground", pil.command(CMD_ARM, 0.0), M.MAV_RESULT_ACCEPTED)
    print(f"ins_store: {len(pil.ins_store)} storage calls, max {max(pil.ins_store)} instructions, "
          f"in order {pil.ins_store}", flush=True)
    for k, v in sorted(pil.log_ins.items()):
        print(f"{k}: {len(v)} record sets, max {max(v)}, median {sorted(v)[len(v) // 2]} instructions", flush=True)
    if not pil.log_ins.get("ins_log"):
        fail("no ins_log: the onboard log wrote nothing while armed")
    if not pil.stack_free:
        fail("no stack_free report")
    print(f"stack_free: {min(pil.stack_free)} bytes never used (reports {pil.stack_free})", flush=True)
    if min(pil.stack_free) < 1024:
        fail(f"stack margin {min(pil.stack_free)} B: the stack reached (or nearly) the statics")
    print("PASS", flush=True)
finally:
    pil.close()

"""A QGroundControl-style plan flown by a pymavlink ground station on `parapet pil
--gcs-control`: a plan in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT as QGroundControl uploads it —
NAV_TAKEOFF (here), a NAV_WAYPOINT with a 2 s hold (acceptance radius 0.3 m), a DO_CHANGE_SPEED,
a NAV_LOITER_TIME of 1.5 s at the second point, a NAV_DELAY of 1 s, a CONDITION_YAW to 90°,
NAV_RETURN_TO_LAUNCH — uploaded with the mission protocol (MISSION_COUNT / MISSION_REQUEST_INT /
MISSION_ITEM_INT / MISSION_ACK), downloaded back field for field (seq, frame, command,
autocontinue, param1-4, x, y, z), then ARM and MISSION_START from the ground.
Checks: MISSION_ITEM_REACHED arrives for every uploaded seq, in order (0..6); the waypoint's
hold keeps the vehicle there ≥ 1.8 s (MISSION_ITEM_REACHED 1 → MISSION_CURRENT 3); the loiter
and the delay ≥ 2.3 s (REACHED 3 → REACHED 4); ATTITUDE's yaw within 25° of 90° when the yaw
item is reached (done within 12°, ATTITUDE at 10 Hz lags) and within 3° after; the vehicle returns (Return mode in a HEARTBEAT or its STATUSTEXT), lands and
disarms by itself (the RTL item is reached at the disarm; the host side checks the run ended
landed at the start).

usage: gcs_qgc_plan.py PORT PLAN_JSON   (PLAN_JSON = {"alt": m, "waypoints": [[north, east], ...]},
metres from home). Prints one line per step and PASS (exit 0); FAIL: <why> otherwise (exit 1).
"""
import json
import math
import struct
import sys
import time

from pymavlink.dialects.v20 import common as mav

from gcs_common import connect, fail, heartbeat, waiter

# The firmware's flat-earth scales around home (firmware/src/link/geo.rs): 1e-7 deg per metre.
LAT_E7_PER_M = 89.83153
LON_E7_PER_M = 132.70922
# PX4 custom mode of Return (main mode AUTO = 4, sub mode RTL = 5), HEARTBEAT custom_mode.
PX4_RETURN = (4 << 16) | (5 << 24)

port = int(sys.argv[1])
plan = json.loads(sys.argv[2])
m = connect(port, 255)
wait = waiter(m)
sysid, compid = heartbeat(m)
home = wait("HOME_POSITION", 10)
if home is None:
    fail("no HOME_POSITION in 10 s")
print("home", home.latitude, home.longitude, home.altitude, flush=True)

FRAME = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
alt = float(plan["alt"])


def item(seq, command, north=None, east=None, z=0.0, p=(0.0, 0.0, 0.0, 0.0)):
    x = 0 if north is None else home.latitude + round(north * LAT_E7_PER_M)
    y = 0 if east is None else home.longitude + round(east * LON_E7_PER_M)
    return (seq, FRAME, command, 1 if seq == 0 else 0, 1, p[0], p[1], p[2], p[3], x, y, z)


NAN = float("nan")
(a, b) = plan["waypoints"]
items = [
    item(0, mav.MAV_CMD_NAV_TAKEOFF, z=alt, p=(0.0, 0.0, 0.0, NAN)),
    item(1, mav.MAV_CMD_NAV_WAYPOINT, a[0], a[1], alt, p=(2.0, 0.3, 0.0, NAN)),
    item(2, mav.MAV_CMD_DO_CHANGE_SPEED, p=(1.0, 0.4, -1.0, 0.0)),
    item(3, mav.MAV_CMD_NAV_LOITER_TIME, b[0], b[1], alt, p=(1.5, 0.0, 0.0, NAN)),
    item(4, mav.MAV_CMD_NAV_DELAY, p=(1.0, -1.0, -1.0, -1.0)),
    item(5, mav.MAV_CMD_CONDITION_YAW, p=(90.0, 30.0, 1.0, 0.0)),
    item(6, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH),
]

m.mav.mission_count_send(sysid, compid, len(items), mav.MAV_MISSION_TYPE_MISSION)
while True:
    r = wait(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], 10)
    if r is None:
        fail("upload stalled: no MISSION_REQUEST_INT / MISSION_ACK in 10 s")
    if r.get_type() == "MISSION_ACK":
        if r.type != mav.MAV_MISSION_ACCEPTED:
            fail(f"upload refused: MISSION_ACK {r.type}")
        break
    (seq, frame, cmd, cur, auto, p1, p2, p3, p4, x, y, z) = items[r.seq]
    m.mav.mission_item_int_send(sysid, compid, seq, frame, cmd, cur, auto, p1, p2, p3, p4, x, y, z,
                                mav.MAV_MISSION_TYPE_MISSION)
print("uploaded", len(items), "items", flush=True)

m.mav.mission_request_list_send(sysid, compid, mav.MAV_MISSION_TYPE_MISSION)
c = wait("MISSION_COUNT", 5)
if c is None or c.count != len(items):
    fail(f"download: MISSION_COUNT {c}")


def same(x, y):
    """Equal as float32 (NaN equals NaN: QGroundControl's "unchanged" yaw)."""
    if isinstance(x, float) or isinstance(y, float):
        return (math.isnan(x) and math.isnan(y)) or struct.pack("<f", x) == struct.pack("<f", y)
    return x == y


for sent in items:
    m.mav.mission_request_int_send(sysid, compid, sent[0], mav.MAV_MISSION_TYPE_MISSION)
    d = wait("MISSION_ITEM_INT", 5, lambda i: i.seq == sent[0])
    if d is None:
        fail(f"download of item {sent[0]}: no MISSION_ITEM_INT")
    got = (d.seq, d.frame, d.command, sent[3], d.autocontinue, d.param1, d.param2, d.param3, d.param4,
           d.x, d.y, d.z)
    if not all(same(g, w) for g, w in zip(got, sent)):
        fail(f"download of item {sent[0]}: {got} for {sent}")
m.mav.mission_ack_send(sysid, compid, mav.MAV_MISSION_ACCEPTED, mav.MAV_MISSION_TYPE_MISSION)
print("downloaded: every item field for field", flush=True)


def command(cmd, *p):
    p = list(p) + [0.0] * (7 - len(p))
    m.mav.command_long_send(sysid, compid, cmd, 0, *p)
    a = wait("COMMAND_ACK", 5, lambda a: a.command == cmd)
    if a is None or a.result != mav.MAV_RESULT_ACCEPTED:
        fail(f"command {cmd}: {a}")


# MISSION_CURRENT at 10 Hz, ATTITUDE at 10 Hz: the holds are timed from them.
command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, 42, 100000)
command(mav.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 100000)
command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
print("armed", flush=True)
command(mav.MAV_CMD_MISSION_START)
print("mission started", flush=True)

reached = []
returned = False
at_reached = {}  # seq -> wall time of its MISSION_ITEM_REACHED
current_at = {}  # seq -> wall time MISSION_CURRENT first showed it
yaw_deg = None
yaw_at_turn = None
yaw_after = []  # ATTITUDE yaw after the yaw item, deg
end = time.time() + 120
while time.time() < end:
    msg = m.recv_match(type=["MISSION_ITEM_REACHED", "MISSION_CURRENT", "ATTITUDE", "HEARTBEAT", "STATUSTEXT"],
                       blocking=True, timeout=0.5)
    if msg is None:
        continue
    t = msg.get_type()
    if t == "ATTITUDE":
        yaw_deg = math.degrees(msg.yaw)
        if yaw_at_turn is not None:
            yaw_after.append(yaw_deg)
    elif t == "MISSION_CURRENT":
        if msg.seq not in current_at:
            current_at[msg.seq] = time.time()
            print("current", msg.seq, flush=True)
    elif t == "MISSION_ITEM_REACHED":
        reached.append(msg.seq)
        at_reached.setdefault(msg.seq, time.time())
        print("reached", msg.seq, "yaw", None if yaw_deg is None else round(yaw_deg, 1), flush=True)
        if msg.seq == 5:
            yaw_at_turn = yaw_deg
        if msg.seq == len(items) - 1:
            # The RTL item is reached once the vehicle has landed and disarmed (the firmware's
            # mission executor); `parapet pil` ends the run at the disarm, so the disarmed
            # HEARTBEAT may not get out any more.
            print("landed and disarmed (RTL item reached)", flush=True)
            break
    elif t == "STATUSTEXT":
        print("text:", msg.text, flush=True)
        # The firmware's mode-change text (`MODE Return: <reason>`).
        if msg.text.startswith("MODE Return"):
            returned = True
    elif msg.get_srcSystem() == sysid and msg.get_srcComponent() == compid:
        if msg.custom_mode == PX4_RETURN and not returned:
            returned = True
            print("Return mode", flush=True)
        if not msg.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED:
            print("disarmed", flush=True)
            break
else:
    fail(f"not landed and disarmed within 120 s (reached {reached})")
if reached != list(range(len(items))):
    fail(f"MISSION_ITEM_REACHED {reached}, uploaded seqs {list(range(len(items)))}")
if not returned:
    fail("Return mode never reported for the RTL item")
hold = current_at.get(3, 0.0) - at_reached.get(1, 0.0)
loiter = at_reached.get(4, 0.0) - at_reached.get(3, 0.0)
print(f"waypoint hold {hold:.2f} s (2 s), loiter + delay {loiter:.2f} s (1.5 s + 1 s), "
      f"yaw at the yaw item {yaw_at_turn}", flush=True)
if hold < 1.8:
    fail(f"the waypoint's 2 s hold lasted {hold:.2f} s")
if loiter < 2.3:
    fail(f"the 1.5 s loiter and 1 s delay lasted {loiter:.2f} s")


def off90(y):
    return abs((y - 90.0 + 180.0) % 360.0 - 180.0)


# The item is done within 12° of its heading (PX4's MIS_YAW_ERR); ATTITUDE (10 Hz) lags it.
if yaw_at_turn is None or off90(yaw_at_turn) > 25.0:
    fail(f"CONDITION_YAW 90°: the heading was {yaw_at_turn}° when the item was reached")
settled = min((off90(y) for y in yaw_after), default=180.0)
print(f"heading after the yaw item: within {settled:.1f}° of 90°", flush=True)
if settled > 3.0:
    fail(f"CONDITION_YAW 90°: the heading never came within 3° of 90° (closest {settled:.1f}°)")
print("PASS", flush=True)

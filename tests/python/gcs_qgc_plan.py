"""QGroundControl's default plan flown by a pymavlink ground station on `parapet pil
--gcs-control`: a plan in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT as QGroundControl uploads it —
NAV_TAKEOFF (here), two NAV_WAYPOINTs, a DO_CHANGE_SPEED, NAV_RETURN_TO_LAUNCH — uploaded with
the mission protocol (MISSION_COUNT / MISSION_REQUEST_INT / MISSION_ITEM_INT / MISSION_ACK),
downloaded back (same seq, command, frame, lat/lon), then ARM and MISSION_START from the ground.
Checks: MISSION_ITEM_REACHED arrives for every uploaded seq, in order (0..4), the vehicle
returns (Return mode in a HEARTBEAT or its STATUSTEXT), lands and disarms by itself (the RTL item is
reached at the disarm; the host side checks the run ended landed at the start).

usage: gcs_qgc_plan.py PORT PLAN_JSON   (PLAN_JSON = {"alt": m, "waypoints": [[north, east], ...]},
metres from home). Prints one line per step and PASS (exit 0); FAIL: <why> otherwise (exit 1).
"""
import json
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


(a, b) = plan["waypoints"]
items = [
    item(0, mav.MAV_CMD_NAV_TAKEOFF, z=alt),
    item(1, mav.MAV_CMD_NAV_WAYPOINT, a[0], a[1], alt),
    item(2, mav.MAV_CMD_DO_CHANGE_SPEED, p=(1.0, 0.4, -1.0, 0.0)),
    item(3, mav.MAV_CMD_NAV_WAYPOINT, b[0], b[1], alt),
    item(4, mav.MAV_CMD_NAV_RETURN_TO_LAUNCH),
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
for sent in items:
    m.mav.mission_request_int_send(sysid, compid, sent[0], mav.MAV_MISSION_TYPE_MISSION)
    d = wait("MISSION_ITEM_INT", 5, lambda i: i.seq == sent[0])
    if d is None or (d.command, d.frame, d.x, d.y) != (sent[2], sent[1], sent[9], sent[10]):
        fail(f"download of item {sent[0]}: {d} for {sent}")
m.mav.mission_ack_send(sysid, compid, mav.MAV_MISSION_ACCEPTED, mav.MAV_MISSION_TYPE_MISSION)
print("downloaded: the same seq, command, frame, lat/lon", flush=True)


def command(cmd, *p):
    p = list(p) + [0.0] * (7 - len(p))
    m.mav.command_long_send(sysid, compid, cmd, 0, *p)
    a = wait("COMMAND_ACK", 5, lambda a: a.command == cmd)
    if a is None or a.result != mav.MAV_RESULT_ACCEPTED:
        fail(f"command {cmd}: {a}")


command(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
print("armed", flush=True)
command(mav.MAV_CMD_MISSION_START)
print("mission started", flush=True)

reached = []
returned = False
end = time.time() + 120
while time.time() < end:
    msg = m.recv_match(type=["MISSION_ITEM_REACHED", "HEARTBEAT", "STATUSTEXT"], blocking=True, timeout=0.5)
    if msg is None:
        continue
    t = msg.get_type()
    if t == "MISSION_ITEM_REACHED":
        reached.append(msg.seq)
        print("reached", msg.seq, flush=True)
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
print("PASS", flush=True)

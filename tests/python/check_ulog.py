"""Read a Parapet flight.ulg with pyulog and check the PX4 topics, fields and units.

usage: check_ulog.py FILE START_NED_Z SPEED_MAX
Exit 0 when every check passes; prints what failed otherwise (exit 1).
"""
import math
import sys

from ulog_common import load, require_fields

path, start_z, speed_max = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
u, topics = load(path)
need = {
    "vehicle_local_position": ["timestamp", "x", "y", "z", "vx", "vy", "vz", "heading"],
    "vehicle_attitude": ["timestamp", "q[0]", "q[1]", "q[2]", "q[3]"],
    "vehicle_attitude_setpoint": ["timestamp", "q_d[0]", "thrust_body[2]", "roll_body"],
    "actuator_motors": ["timestamp", "control[0]", "control[3]", "control[4]"],
    "vehicle_status": ["timestamp", "arming_state", "nav_state"],
    "cbf_status": ["timestamp", "h_bar", "region", "active_id", "u_nominal[0]", "u[2]"],
}
require_fields(topics, need)
errors = []
lp = topics["vehicle_local_position"]
n = len(lp["timestamp"])
if n < 100:
    errors.append(f"only {n} samples")
ts = lp["timestamp"]
if any(b <= a for a, b in zip(ts, ts[1:])):
    errors.append("timestamps not increasing")
# Outer rate 250 Hz: 4 ms apart (µs).
dt = (ts[-1] - ts[0]) / (n - 1)
if abs(dt - 4000) > 1:
    errors.append(f"mean sample interval {dt} us, expected 4000 (250 Hz)")
# NED metres: the flight starts at the start's z (negative = above ground), stays above ground.
if abs(lp["z"][0] - start_z) > 0.05:
    errors.append(f"z[0] = {lp['z'][0]} m, expected the start {start_z} (NED, m)")
if max(lp["z"]) > 0:
    errors.append("z > 0: below the ground in NED")
v = max(math.sqrt(a * a + b * b + c * c) for a, b, c in zip(lp["vx"], lp["vy"], lp["vz"]))
if not (0.2 * speed_max < v < 3 * speed_max):
    errors.append(f"max speed {v} m/s, mission speed {speed_max} m/s: not m/s?")
att = topics["vehicle_attitude"]
for i in range(0, n, 97):
    q = [att[f"q[{k}]"][i] for k in range(4)]
    if abs(sum(x * x for x in q) - 1) > 1e-4:
        errors.append(f"|q| != 1 at {i}: {q}")
        break
m = topics["actuator_motors"]
c0 = m["control[0]"]
if not all(0 <= x <= 1 for x in c0) or max(c0) <= 0:
    errors.append("control[0] not a throttle in 0..1")
if not all(math.isnan(x) for x in m["control[4]"]):
    errors.append("unused outputs are not NaN")
st = topics["vehicle_status"]
if 2 not in set(st["arming_state"]):
    errors.append("never armed")
if 3 not in set(st["nav_state"]):
    errors.append("never in AUTO_MISSION (nav_state 3)")
cbf = topics["cbf_status"]
if not any(r == 3 for r in cbf["region"]):
    errors.append("the filter never acted (region 3) in a scene with an obstacle on the path")
if min(cbf["h_bar"]) < 0:
    errors.append(f"h_bar < 0: {min(cbf['h_bar'])}")
if "CBF_MU" not in u.initial_parameters:
    errors.append("parameter CBF_MU missing")
if errors:
    print("\n".join(errors))
    sys.exit(1)
print(f"ulog ok: {n} samples, topics {sorted(topics)}")

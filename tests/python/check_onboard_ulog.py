"""Read an onboard log (the firmware's no_std ULog writer, firmware/src/log/) with pyulog and
check its topics, rate, arming span, parameters and values.

usage: check_onboard_ulog.py FILE RATE_HZ [MIN_RECORDS] [X Y]
  RATE_HZ      the logger's record rate (records per second while armed)
  MIN_RECORDS  at least this many records per topic (default 10)
  X Y          if given: vehicle_local_position.x / .y of every record (m, NED)
Exit 0 when every check passes; prints what failed otherwise (exit 1).
"""
import sys

from ulog_common import load, require_fields

path, rate = sys.argv[1], float(sys.argv[2])
min_records = int(sys.argv[3]) if len(sys.argv) > 3 else 10
xy = (float(sys.argv[4]), float(sys.argv[5])) if len(sys.argv) > 5 else None
u, topics = load(path)
need = {
    "vehicle_local_position": ["timestamp", "x", "y", "z", "vx", "vy", "vz", "heading"],
    "vehicle_attitude": ["timestamp", "q[0]", "q[3]"],
    "vehicle_attitude_setpoint": ["timestamp", "q_d[0]", "thrust_body[2]", "roll_body"],
    "actuator_motors": ["timestamp", "timestamp_sample", "control[0]", "control[3]", "control[11]"],
    "vehicle_status": ["timestamp", "arming_state", "nav_state", "parapet_mode"],
    "cbf_status": ["timestamp", "h_bar_filter", "region", "active_id", "u_nominal[0]", "u[2]"],
}
require_fields(topics, need)
errors = []
if u.msg_info_dict.get("sys_name") != "Parapet":
    errors.append(f"sys_name = {u.msg_info_dict.get('sys_name')!r}")
if "CBF_MU" not in u.initial_parameters:
    errors.append(f"parameter CBF_MU missing (have {len(u.initial_parameters)} parameters)")
lp = topics["vehicle_local_position"]
ts = lp["timestamp"]
n = len(ts)
if n < min_records:
    errors.append(f"only {n} records (at least {min_records})")
for t in need:
    if len(topics[t]["timestamp"]) != n:
        errors.append(f"{t}: {len(topics[t]['timestamp'])} records, vehicle_local_position {n}")
if any(b <= a for a, b in zip(ts, ts[1:])):
    errors.append("timestamps not increasing")
# The rate while armed: every record but the last (the disarm sample) 1/RATE apart.
if n > 2:
    gaps = [b - a for a, b in zip(ts[:-1], ts[1:-1])]
    want = 1e6 / rate
    if gaps and max(abs(g - want) for g in gaps) > 0.1 * want + 1:
        errors.append(f"record interval {min(gaps)}..{max(gaps)} us, expected {want:.0f}")
st = topics["vehicle_status"]["arming_state"]
if any(a != 2 for a in st[:-1]):
    errors.append(f"not armed before the last record: {sorted(set(st[:-1]))}")
if xy is not None:
    for i in range(n):
        if abs(lp["x"][i] - xy[0]) > 1e-6 or abs(lp["y"][i] - xy[1]) > 1e-6:
            errors.append(f"record {i}: x, y = {lp['x'][i]}, {lp['y'][i]}, expected {xy}")
            break
m = topics["actuator_motors"]
if any(v == v for v in m["control[4]"]):  # NaN != NaN: unused outputs are NaN as in PX4
    errors.append("actuator_motors.control[4] is not NaN")
if errors:
    print("\n".join(errors))
    sys.exit(1)
print(f"ok: {n} records per topic, {len(u.initial_parameters)} parameters")

"""Replay a Parapet flight.tlog with pymavlink and check it holds the lockstep traffic.

usage: check_tlog.py FILE
"""
import sys

from pymavlink import mavutil

m = mavutil.mavlink_connection(sys.argv[1])
counts = {}
last_t = 0.0
back = 0
while True:
    msg = m.recv_match()
    if msg is None:
        break
    if msg.get_type() == "BAD_DATA":
        continue
    counts[msg.get_type()] = counts.get(msg.get_type(), 0) + 1
    t = getattr(msg, "_timestamp", 0.0)
    if t < last_t:
        back += 1
    last_t = t
errors = []
for need in ["HEARTBEAT", "HIL_SENSOR", "HIL_ACTUATOR_CONTROLS", "ODOMETRY", "MISSION_ITEM_INT", "COMMAND_ACK", "ATTITUDE"]:
    if counts.get(need, 0) == 0:
        errors.append(f"no {need} in the tlog")
if abs(counts.get("HIL_SENSOR", 0) - counts.get("HIL_ACTUATOR_CONTROLS", 0)) > 5:
    errors.append(f"HIL_SENSOR {counts.get('HIL_SENSOR')} vs HIL_ACTUATOR_CONTROLS {counts.get('HIL_ACTUATOR_CONTROLS')}")
if back:
    errors.append(f"{back} timestamps go backwards")
if errors:
    print("\n".join(errors), counts)
    sys.exit(1)
print("tlog ok:", counts)

"""A ground station on `parapet pil --gcs udp:127.0.0.1:PORT` (pymavlink): heartbeat, fetch
every parameter, set one, download the mission, clear it and check the clear took effect.

usage: gcs_pymavlink.py PORT [basic|full]   (exit 0 = every step passed; the failed step is
printed). `basic`: heartbeat, telemetry, no lockstep frame leaks to the GCS, a PARAM_REQUEST_READ
round trip through the bridge. `full` (default): basic, then the parameter and mission services
and the component metadata by MAVLink FTP (gcs_metadata.py).
`readonly` (`parapet run --gcs`): basic without ATTITUDE, the parameter list and set, the mission
download (the in-process run has no mission clear).
"""
import sys
import time

from pymavlink import mavutil

from gcs_common import connect, fail, heartbeat, waiter
from gcs_metadata import check_component_metadata

port = int(sys.argv[1])
mode = sys.argv[2] if len(sys.argv) > 2 else "full"
m = connect(port, 250)
wait = waiter(m)
sysid, compid = heartbeat(m)
print("heartbeat from", sysid, compid, flush=True)

# Telemetry through the bridge; the host's lockstep frames stay inside the host, and the
# answers to the host's own start-up commands are addressed to the host's ids, not a GCS's.
seen = {}
addressed = set()
end = time.time() + 3
while time.time() < end:
    msg = m.recv_match(blocking=True, timeout=0.5)
    if msg is not None:
        seen[msg.get_type()] = seen.get(msg.get_type(), 0) + 1
        if getattr(msg, "target_system", 0):
            addressed.add((msg.get_type(), msg.target_system, getattr(msg, "target_component", 0)))
if any(t[1:] in [(255, 190), (255, 230), (245, 190)] for t in addressed):
    fail(f"messages addressed to a ground station's ids that never sent them: {sorted(addressed)}")
# A loss-free local link: one gap-free sequence space per component (issue 41: the lockstep
# frames the host keeps took ~94 % of the firmware's numbers and pymavlink counted them lost).
if m.mav_count < 100 or m.mav_loss != 0:
    fail(f"sequence: {m.mav_count} received, {m.mav_loss} lost ({m.packet_loss():.1f} %)")
print(f"sequence: {m.mav_count} received, {m.mav_loss} lost", flush=True)
# Identity: a PX4-class vehicle whose modes pymavlink decodes by name.
hb = m.messages["HEARTBEAT"]
if hb.autopilot != mavutil.mavlink.MAV_AUTOPILOT_PX4 or m.flightmode not in mavutil.px4_map:
    fail(f"HEARTBEAT autopilot {hb.autopilot}, mode {m.flightmode!r} (custom_mode {hb.custom_mode})")
print("autopilot PX4, mode", m.flightmode, flush=True)
for need in ["LOCAL_POSITION_NED"] + ([] if mode == "readonly" else ["ATTITUDE"]):
    if not seen.get(need):
        fail(f"no {need} in 3 s: {seen}")
for leak in ["HIL_ACTUATOR_CONTROLS", "HIL_SENSOR", "ODOMETRY"]:
    if seen.get(leak):
        fail(f"lockstep frame {leak} reached the GCS: {seen}")
m.mav.param_request_read_send(sysid, compid, b"CBF_MU", -1)
r = wait("PARAM_VALUE", 5, lambda p: p.param_id == "CBF_MU")
if r is None:
    fail("PARAM_REQUEST_READ CBF_MU not answered through the bridge")
print("telemetry", seen, "CBF_MU", r.param_value, flush=True)
if mode == "basic":
    print("PASS", flush=True)
    sys.exit(0)

# Parameters: the whole list, each index once.
m.mav.param_request_list_send(sysid, compid)
got, values, count = {}, {}, None
end = time.time() + 20
while time.time() < end and (count is None or len(got) < count):
    p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
    if p is not None:
        count = p.param_count
        got[p.param_index] = p.param_id
        values[p.param_id] = p.param_value
if count is None:
    fail("PARAM_REQUEST_LIST not answered")
if len(got) != count or sorted(got) != list(range(count)):
    fail(f"param list incomplete: {len(got)} of {count}")
print(f"params: {count}", flush=True)
if mode == "full":
    # COMPONENT_METADATA → general.json → parameters.json by MAVLink FTP (pymavlink's client).
    check_component_metadata(m, wait, sysid, compid, values)

# Set one (the velocity margin to its own value + 0: accepted and echoed).
name = "CBF_MU" if "CBF_MU" in got.values() else next(iter(got.values()))
m.mav.param_request_read_send(sysid, compid, name.encode(), -1)
cur = wait("PARAM_VALUE", 5, lambda p: p.param_id == name)
if cur is None:
    fail(f"PARAM_REQUEST_READ {name} not answered")
m.mav.param_set_send(sysid, compid, name.encode(), cur.param_value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
echo = wait("PARAM_VALUE", 5, lambda p: p.param_id == name)
if echo is None or abs(echo.param_value - cur.param_value) > 1e-6:
    fail(f"PARAM_SET {name} not echoed: {echo}")
print(f"set {name} = {echo.param_value}", flush=True)

# A command's ACK is addressed to its sender (COMMAND_ACK's target fields are MAVLink 2
# extensions: a bridge that re-encodes frames without them sends 0/0).
if mode != "readonly":
    m.mav.command_long_send(sysid, compid, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
    ack = wait("COMMAND_ACK", 5, lambda a: a.command == mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE)
    if ack is None:
        fail("REQUEST_MESSAGE(AUTOPILOT_VERSION) not acknowledged")
    if (ack.target_system, ack.target_component) != (250, 190):
        fail(f"COMMAND_ACK addressed to {ack.target_system}/{ack.target_component}, not the sender 250/190")
    print("COMMAND_ACK to", ack.target_system, ack.target_component, flush=True)
    v = wait("AUTOPILOT_VERSION", 5)
    caps = mavutil.mavlink
    need = caps.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | caps.MAV_PROTOCOL_CAPABILITY_MISSION_INT | \
        caps.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    need |= caps.MAV_PROTOCOL_CAPABILITY_FTP  # read-only: the component metadata files
    if v is None or v.uid == 0 or v.capabilities & need != need or \
            v.capabilities & caps.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE:
        fail(f"AUTOPILOT_VERSION: {v}")
    print(f"AUTOPILOT_VERSION uid {v.uid:#x} capabilities {v.capabilities:#x}", flush=True)
    # Home where the vehicle armed (the host arms it at the scene's start, 1 m up; before: the
    # origin, z 0), the origin on request.
    m.mav.command_long_send(sysid, compid, mavutil.mavlink.MAV_CMD_GET_HOME_POSITION, 0, 0, 0, 0, 0, 0, 0, 0)
    home = wait("HOME_POSITION", 5)
    m.mav.command_long_send(sysid, compid, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 49, 0, 0, 0, 0, 0, 0)
    origin = wait("GPS_GLOBAL_ORIGIN", 5)
    if home is None or origin is None or home.z > -0.5:
        fail(f"HOME_POSITION {home}, GPS_GLOBAL_ORIGIN {origin}")
    print(f"home x {home.x:.2f} y {home.y:.2f} z {home.z:.2f}, origin {origin.latitude} {origin.longitude}", flush=True)
    # The standard modes protocol (QGroundControl 4.4+, MAVSDK): every mode listed once, by name,
    # with PX4's custom_mode and its standard mode; CURRENT_MODE streamed.
    m.mav.command_long_send(sysid, compid, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 435, 0, 0, 0, 0, 0, 0)
    modes = {}
    for _ in range(7):
        am = wait("AVAILABLE_MODES", 5)
        if am is None:
            fail(f"AVAILABLE_MODES: {len(modes)} of 7 modes")
        name = am.mode_name.rstrip("\x00") if isinstance(am.mode_name, str) else am.mode_name
        modes[am.mode_index] = (name, am.standard_mode, mavutil.interpret_px4_mode(0, am.custom_mode))
    want = {"Manual": (0, "MANUAL"), "Position": (1, "POSCTL"), "Mission": (6, "MISSION"),
            "Hold": (0, "LOITER"), "Return": (5, "RTL"), "Land": (7, "LAND"), "Offboard": (0, "OFFBOARD")}
    got = {n: (std, px4) for (n, std, px4) in modes.values()}
    if sorted(modes) != list(range(1, 8)) or got != want:
        fail(f"AVAILABLE_MODES {modes}")
    print("AVAILABLE_MODES", ", ".join(f"{n} ({std})" for (n, std, _) in modes.values()), flush=True)
    if wait("CURRENT_MODE", 10) is None:
        fail("no CURRENT_MODE")
    # Mode changes by name (pymavlink's PX4 mode map): LOITER holds, MISSION goes on.
    for name in ["LOITER", "MISSION"]:
        m.set_mode(name)
        if wait("HEARTBEAT", 5, lambda h, n=name: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == n) is None:
            fail(f"set_mode({name}) not shown by the HEARTBEAT (mode {m.flightmode})")
        print("mode", name, flush=True)
    cur = wait("CURRENT_MODE", 10)
    if cur is None or cur.standard_mode != 6 or mavutil.interpret_px4_mode(0, cur.intended_custom_mode) != "MISSION":
        fail(f"CURRENT_MODE after MISSION: {cur}")

# Mission download.
m.mav.mission_request_list_send(sysid, compid, mavutil.mavlink.MAV_MISSION_TYPE_MISSION)
c = wait("MISSION_COUNT", 5)
if c is None:
    fail("MISSION_REQUEST_LIST not answered")
if c.count < 2:
    fail(f"mission count {c.count}, the flown path has at least 2 waypoints")
for seq in range(c.count):
    m.mav.mission_request_int_send(sysid, compid, seq, mavutil.mavlink.MAV_MISSION_TYPE_MISSION)
    it = wait("MISSION_ITEM_INT", 5, lambda x, s=seq: x.seq == s)
    if it is None:
        fail(f"mission item {seq} not sent")
m.mav.mission_ack_send(sysid, compid, mavutil.mavlink.MAV_MISSION_ACCEPTED, mavutil.mavlink.MAV_MISSION_TYPE_MISSION)
print(f"mission: {c.count} items", flush=True)
if mode == "readonly":
    print("PASS", flush=True)
    sys.exit(0)

# Clear, then the mission is empty.
m.mav.mission_clear_all_send(sysid, compid, mavutil.mavlink.MAV_MISSION_TYPE_MISSION)
a = wait("MISSION_ACK", 5)
if a is None or a.type != mavutil.mavlink.MAV_MISSION_ACCEPTED:
    fail(f"MISSION_CLEAR_ALL not accepted: {a}")
m.mav.mission_request_list_send(sysid, compid, mavutil.mavlink.MAV_MISSION_TYPE_MISSION)
c = wait("MISSION_COUNT", 5)
if c is None or c.count != 0:
    fail(f"after MISSION_CLEAR_ALL the count is {None if c is None else c.count}, expected 0")
print("PASS", flush=True)

"""MAVSDK-Python (its bundled mavsdk_server) flies a whole mission on `parapet pil --gcs-control`:
connects over UDP, reads telemetry (on the ground, disarmed, not in air; health flags global/local/
home position ok and armable, gps_info with a 3D fix, raw_gps accuracy, VFR_HUD), uploads the mission,
arms, takes off, starts the mission, watches it reach the last waypoint (mission progress and
position), flies back to the previous waypoint with `action.goto_location` ("Go to location",
DO_REPOSITION) and holds there, lands and disarms. The plan is uploaded with
- `raw` (default): `mission_raw`, MAV_FRAME_LOCAL_NED items (x, y in 1e-4 m, z in m);
- `plugin`: the standard `mission` plugin (as PX4 SITL is flown): MissionItems at latitude/
  longitude = home (from telemetry) + the NED offsets (the firmware's flat-earth scales around
  home), altitude relative to home (MAVSDK uploads NAV_WAYPOINTs in
  MAV_FRAME_GLOBAL_RELATIVE_ALT_INT), downloaded back with the same lat/lon.

usage: mavsdk_mission.py PORT WAYPOINTS_JSON [raw|plugin]   ([[north, east, down], ...] in m, NED)
Prints one line per step and PASS at the end (exit 0); FAIL: <why> otherwise (exit 1).
"""
import asyncio
import json
import math
import os
import socket
import struct
import sys

from mavsdk import System
from mavsdk import mission, mission_raw, telemetry

MAV_FRAME_LOCAL_NED = 1
MAV_CMD_NAV_WAYPOINT = 16
# The firmware's flat-earth scales around home (firmware/src/link/geo.rs): 1e-7 deg per metre.
LAT_E7_PER_M = 89.83153
LON_E7_PER_M = 132.70922


DRONE = None


def done(code):
    """Stop our mavsdk_server and exit at once (its gRPC threads would keep a plain exit waiting)."""
    if DRONE is not None:
        DRONE._stop_mavsdk_server()
    sys.stdout.flush()
    os._exit(code)


def fail(why):
    print("FAIL:", why, flush=True)
    done(1)


def free_tcp_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def first(stream, pred, what, timeout, required=True):
    """The first item of `stream` with pred(item), within `timeout` s (else FAIL, or None when
    not `required`)."""

    async def scan():
        async for x in stream:
            if pred(x):
                return x

    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        if required:
            fail(f"{what} not seen within {timeout} s")
        return None


def speed(p):
    v = p.velocity
    return math.sqrt(v.north_m_s**2 + v.east_m_s**2 + v.down_m_s**2)


async def upload_with_the_mission_plugin(drone, waypoints):
    """The plan as MissionItems at home + the NED offsets; uploaded, downloaded, compared."""
    home = await first(drone.telemetry.home(), lambda h: True, "HOME_POSITION", 10)
    print("home", home.latitude_deg, home.longitude_deg, home.absolute_altitude_m, flush=True)
    nan = float("nan")
    items = [
        mission.MissionItem(
            home.latitude_deg + w[0] * LAT_E7_PER_M * 1e-7,
            home.longitude_deg + w[1] * LON_E7_PER_M * 1e-7,
            -float(w[2]),
            nan,  # speed: none (a DO_CHANGE_SPEED item would shift MISSION_CURRENT's numbering)
            False,
            nan,
            nan,
            mission.MissionItem.CameraAction.NONE,
            nan,
            nan,
            nan,
            nan,
            nan,
            mission.MissionItem.VehicleAction.NONE,
        )
        for w in waypoints
    ]
    await drone.mission.upload_mission(mission.MissionPlan(items))
    print("mission uploaded", len(items), "items", flush=True)
    down = (await drone.mission.download_mission()).mission_items
    if len(down) != len(items):
        fail(f"downloaded {len(down)} items, uploaded {len(items)}")
    for a, b in zip(items, down):
        if (round(a.latitude_deg * 1e7), round(a.longitude_deg * 1e7)) != (
            round(b.latitude_deg * 1e7),
            round(b.longitude_deg * 1e7),
        ) or abs(a.relative_altitude_m - b.relative_altitude_m) > 0.01:
            fail(f"downloaded {b} for uploaded {a}")
    print("mission downloaded: same lat/lon/alt", flush=True)


async def main(port, waypoints, plugin):
    global DRONE
    # Its own gRPC port: another MAVSDK test (or a leftover server) may hold the default 50051.
    drone = DRONE = System(port=free_tcp_port())
    await drone.connect(system_address=f"udpin://0.0.0.0:{port}")
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection", 30)
    print("connected", flush=True)

    pv = await first(drone.telemetry.position_velocity_ned(), lambda p: True, "LOCAL_POSITION_NED", 10)
    print("position NED", pv.position.north_m, pv.position.east_m, pv.position.down_m, flush=True)
    if pv.position.down_m < -0.3:
        fail(f"not on the ground at the start (down_m {pv.position.down_m})")
    armed = await first(drone.telemetry.armed(), lambda a: True, "armed state", 10)
    in_air = await first(drone.telemetry.in_air(), lambda a: True, "landed state", 10)
    print("armed", armed, "in_air", in_air, flush=True)
    if armed or in_air:
        fail("the vehicle must wait disarmed on the ground")

    # What PX4 SITL gives a client before arming (issue 41): the health flags MAVSDK derives
    # from SYS_STATUS (GPS and PREARM_CHECK bits) and HOME_POSITION all true, and gps_info
    # (GPS_RAW_INT) with a 3D fix; VFR_HUD arrives as fixedwing_metrics.
    health = await first(
        drone.telemetry.health(),
        lambda h: h.is_global_position_ok and h.is_local_position_ok and h.is_home_position_ok and h.is_armable,
        "health: global/local/home position ok and armable",
        20,
    )
    print("health", health, flush=True)
    gps = await first(drone.telemetry.gps_info(), lambda g: True, "gps_info", 10)
    print("gps_info", gps, flush=True)
    if gps.fix_type != telemetry.FixType.FIX_3D:
        fail(f"gps_info fix type {gps.fix_type}, expected FIX_3D")
    raw = await first(drone.telemetry.raw_gps(), lambda g: True, "raw_gps", 10)
    print("raw_gps", raw, flush=True)
    # The accuracy the host states for its fix (ODOMETRY's pose covariance: the run's sensor
    # noise, 0 in these noise-free runs); unknown would read hdop 655.35.
    if not (raw.hdop < 0.05 and raw.horizontal_uncertainty_m < 0.05):
        fail(f"raw_gps accuracy {raw.hdop} / {raw.horizontal_uncertainty_m} m: the PIL fix is good to 5 mm")
    hud = await first(drone.telemetry.fixedwing_metrics(), lambda m: True, "VFR_HUD", 10)
    print("VFR_HUD", hud, flush=True)
    if abs(hud.airspeed_m_s) > 0.2 or hud.throttle_percentage != 0.0:
        fail(f"VFR_HUD on the ground, disarmed: {hud}")

    if plugin == "plugin":
        await upload_with_the_mission_plugin(drone, waypoints)
        api = drone.mission
    else:
        items = [
            mission_raw.MissionItem(
                # hold 0 s, acceptance radius 0.25 m + 0.125 per item: distinct params to compare
                i, MAV_FRAME_LOCAL_NED, MAV_CMD_NAV_WAYPOINT, 1 if i == 0 else 0, 1,
                0.0, 0.25 + 0.125 * i, 0.0, float("nan"),
                int(round(w[0] * 1e4)), int(round(w[1] * 1e4)), float(w[2]), 0,
            )
            for i, w in enumerate(waypoints)
        ]
        await drone.mission_raw.upload_mission(items)
        print("mission uploaded", len(items), "items", flush=True)
        down = await drone.mission_raw.download_mission()
        if len(down) != len(items):
            fail(f"downloaded {len(down)} items, uploaded {len(items)}")

        def fields(it):
            # Every field, floats as the float32 on the wire, NaN as NaN (issue 41: param1-4
            # came back 0).
            return tuple(
                ("nan" if math.isnan(v) else struct.unpack("f", struct.pack("f", v))[0]) if isinstance(v, float) else v
                for v in (it.seq, it.frame, it.command, it.current, it.autocontinue, it.param1, it.param2,
                          it.param3, it.param4, it.x, it.y, it.z, it.mission_type)
            )

        for a, b in zip(items, down):
            if fields(a) != fields(b):
                fail(f"downloaded {b} for uploaded {a}")
        print("mission downloaded field for field", flush=True)
        api = drone.mission_raw

    await drone.action.arm()
    await first(drone.telemetry.armed(), lambda a: a, "armed", 10)
    pv = await first(drone.telemetry.position_velocity_ned(), lambda p: True, "LOCAL_POSITION_NED", 10)
    home_ned = (pv.position.north_m, pv.position.east_m, pv.position.down_m)  # where it armed: home
    print("armed at", home_ned, flush=True)
    await drone.action.takeoff()
    await first(drone.telemetry.in_air(), lambda a: a, "in air", 15)
    # MAVSDK's takeoff leaves the height to the vehicle (the firmware's default, capped by its
    # takeoff limit): wait until it holds, settled, at least 0.5 m up.
    pv = await first(
        drone.telemetry.position_velocity_ned(),
        lambda p: p.position.down_m < -0.5 and speed(p) < 0.05,
        "takeoff, settled",
        25,
    )
    print("took off, holding at down", pv.position.down_m, flush=True)

    await api.start_mission()
    print("mission started", flush=True)
    last = len(waypoints) - 1
    prog = await first(
        api.mission_progress(), lambda p: p.current >= last, "the last mission item", 40
    )
    print("mission progress", prog.current, "/", prog.total, flush=True)
    goal = waypoints[-1]

    def at_goal(p):
        d = (p.position.north_m - goal[0], p.position.east_m - goal[1], p.position.down_m - goal[2])
        return math.sqrt(sum(x * x for x in d)) < 0.08 and speed(p) < 0.08

    pv = await first(drone.telemetry.position_velocity_ned(), at_goal, "the goal (within 8 cm, settled)", 30)
    print("reached the goal", pv.position.north_m, pv.position.east_m, pv.position.down_m, flush=True)

    # "Go to location" (issue 41): action.goto_location (DO_REPOSITION in COMMAND_INT, global
    # frame, altitude AMSL) back to the path's previous waypoint, converted around the origin
    # the vehicle reports; it flies there and holds.
    back = waypoints[-2] if len(waypoints) > 1 else waypoints[0]
    home = await first(drone.telemetry.home(), lambda h: True, "HOME_POSITION", 10)
    # Home is where the vehicle armed: the NED offsets are taken from the local position there.
    lat = home.latitude_deg + (back[0] - home_ned[0]) * LAT_E7_PER_M * 1e-7
    lon = home.longitude_deg + (back[1] - home_ned[1]) * LON_E7_PER_M * 1e-7
    amsl = home.absolute_altitude_m - (back[2] - home_ned[2])
    await drone.action.goto_location(lat, lon, amsl, float("nan"))
    print("goto_location", lat, lon, amsl, flush=True)

    def at_back(p):
        d = (p.position.north_m - back[0], p.position.east_m - back[1], p.position.down_m - back[2])
        return math.sqrt(sum(x * x for x in d)) < 0.1 and speed(p) < 0.05

    pv = await first(drone.telemetry.position_velocity_ned(), at_back, "the goto location (within 10 cm, settled)", 40)
    print("holding at the goto location", pv.position.north_m, pv.position.east_m, pv.position.down_m, flush=True)

    await drone.action.land()
    print("landing", flush=True)
    await first(drone.telemetry.in_air(), lambda a: not a, "on the ground", 30)
    print("landed", flush=True)
    # The firmware disarms by itself once landed (as PX4); disarm if it has not yet.
    if await first(drone.telemetry.armed(), lambda a: not a, "auto-disarm", 5, required=False) is None:
        await drone.action.disarm()
        await first(drone.telemetry.armed(), lambda a: not a, "disarmed", 10)
        print("disarmed by the GCS", flush=True)
    else:
        print("disarmed (landed)", flush=True)
    print("PASS", flush=True)
    done(0)


try:
    asyncio.run(asyncio.wait_for(main(int(sys.argv[1]), json.loads(sys.argv[2]), sys.argv[3] if len(sys.argv) > 3 else "raw"), 150))
except asyncio.TimeoutError:
    fail("timeout")

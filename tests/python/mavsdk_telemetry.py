"""MAVSDK-Python (its bundled mavsdk_server) on a Parapet UDP endpoint: connects, reads the
NED position and a parameter.

usage: mavsdk_telemetry.py PORT   (exit 0 and PASS when every step passed)
"""
import asyncio
import sys

from mavsdk import System


async def main(port):
    drone = System()
    await drone.connect(system_address=f"udpin://0.0.0.0:{port}")
    async for st in drone.core.connection_state():
        if st.is_connected:
            print("connected", flush=True)
            break
    async for pv in drone.telemetry.position_velocity_ned():
        print("position NED", pv.position.north_m, pv.position.east_m, pv.position.down_m, flush=True)
        if pv.position.down_m > -0.2:
            print("FAIL: not flying above the ground (down_m", pv.position.down_m, ")", flush=True)
            sys.exit(1)
        break
    mu = await drone.param.get_param_float("CBF_MU")
    print("CBF_MU", mu, flush=True)
    print("PASS", flush=True)


try:
    asyncio.run(asyncio.wait_for(main(int(sys.argv[1])), 45))
except asyncio.TimeoutError:
    print("FAIL: timeout", flush=True)
    sys.exit(1)

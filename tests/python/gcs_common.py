"""What the pymavlink ground-station scripts of tests/python share (gcs_pymavlink.py,
gcs_qgc_plan.py, gcs_log_download.py): listen on the UDP port `parapet pil --gcs` sends to,
fail with the step printed, wait for a message, wait for the vehicle's HEARTBEAT.

Each script is run as `python tests/python/SCRIPT.py ...`, so this module (next to it) is on
its import path. Checked by tests/tests/gcs_clients.rs python_ground_stations_share_gcs_common.
"""
import sys
import time

from pymavlink import mavutil


def connect(port, source_system):
    """A pymavlink connection listening on 127.0.0.1:PORT as system `source_system`, component 190."""
    return mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=source_system,
                                      source_component=190)


def fail(why):
    """Prints FAIL: <why> and exits 1 (the test prints the script's output)."""
    print("FAIL:", why, flush=True)
    sys.exit(1)


def waiter(m):
    """wait(types, timeout, cond): the first message of `types` on `m` for which cond(msg)
    holds within `timeout` s, or None."""
    def wait(types, timeout, cond=lambda msg: True):
        end = time.time() + timeout
        while time.time() < end:
            msg = m.recv_match(type=types, blocking=True, timeout=0.5)
            if msg is not None and cond(msg):
                return msg
        return None
    return wait


def heartbeat(m, timeout=60):
    """Waits for the vehicle's HEARTBEAT (FAIL without one); its (system, component)."""
    if m.wait_heartbeat(timeout=timeout) is None:
        fail(f"no HEARTBEAT within {timeout} s")
    return m.target_system, m.target_component

"""The MAVLink log download with pymavlink on `parapet pil --gcs udp:127.0.0.1:PORT`: list the
onboard logs (LOG_REQUEST_LIST -> LOG_ENTRY), fetch the newest (LOG_REQUEST_DATA -> LOG_DATA,
90-byte chunks placed by ofs, gaps re-requested), end (LOG_REQUEST_END), write OUT and parse it
with pyulog.

usage: gcs_log_download.py PORT OUT [WAIT_S]   (exit 0 = every step passed; the failed step is
printed). WAIT_S (default 4): seconds of flight before the download (the log grows while armed).
"""
import sys
import time

from pyulog import ULog

from gcs_common import connect, fail, heartbeat

port, out = int(sys.argv[1]), sys.argv[2]
wait_s = float(sys.argv[3]) if len(sys.argv) > 3 else 4.0
m = connect(port, 250)
sysid, compid = heartbeat(m)
time.sleep(wait_s)

entries = {}
for attempt in range(3):
    m.mav.log_request_list_send(sysid, compid, 0, 0xFFFF)
    end = time.time() + 3
    while time.time() < end:
        e = m.recv_match(type="LOG_ENTRY", blocking=True, timeout=0.5)
        if e is None:
            continue
        if e.num_logs == 0:
            fail("the vehicle lists no logs (armed flight expected)")
        entries[e.id] = e
        if len(entries) >= e.num_logs:
            break
    if entries:
        break
if not entries:
    fail("no LOG_ENTRY")
newest = entries[max(entries)]
print(f"{len(entries)} log(s); newest id {newest.id}, {newest.size} bytes", flush=True)
if newest.size < 1000:
    fail(f"log of only {newest.size} bytes")

size = newest.size
data = bytearray(size)
have = [False] * ((size + 89) // 90)
request = (0, 0xFFFFFFFF)
for attempt in range(30):
    m.mav.log_request_data_send(sysid, compid, newest.id, request[0], request[1])
    last = time.time()
    while time.time() - last < 1.0 and not all(have):
        d = m.recv_match(type="LOG_DATA", blocking=True, timeout=0.3)
        if d is None or d.id != newest.id:
            continue
        last = time.time()
        # The log grows while armed: the chunk at the listed end may carry bytes beyond the
        # listed size; keep the listed part (the download is of the log as listed).
        if d.count and d.ofs % 90 == 0 and d.ofs < size:
            n = min(d.count, size - d.ofs)
            data[d.ofs:d.ofs + n] = bytes(d.data[:n])
            have[d.ofs // 90] = True
    if all(have):
        break
    first = have.index(False)
    nxt = next((k for k in range(first, len(have)) if have[k]), len(have))
    request = (first * 90, min(nxt * 90, size) - first * 90)
else:
    fail(f"{have.count(False)} of {len(have)} chunks missing after 30 requests")
m.mav.log_request_end_send(sysid, compid)
with open(out, "wb") as f:
    f.write(data)
print(f"fetched {size} bytes in {attempt + 1} request(s)", flush=True)

u = ULog(out)
topics = {d.name: d.data for d in u.data_list}
for t in ["vehicle_local_position", "vehicle_attitude", "vehicle_attitude_setpoint", "actuator_motors",
          "vehicle_status", "cbf_status"]:
    if t not in topics:
        fail(f"topic {t} missing in the fetched log (have {sorted(topics)})")
n = len(topics["vehicle_local_position"]["timestamp"])
if n < 10:
    fail(f"only {n} records")
armed = topics["vehicle_status"]["arming_state"]
if armed[0] != 2:
    fail(f"first record not armed: arming_state {armed[0]}")
if "CBF_MU" not in u.initial_parameters:
    fail("parameter CBF_MU missing")
print(f"ok: pyulog reads {n} records per topic, {len(u.initial_parameters)} parameters", flush=True)

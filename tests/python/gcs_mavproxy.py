"""MAVProxy on `parapet pil --gcs udp:127.0.0.1:PORT`: `param fetch` and `wp list` complete, `ftp
list` and `ftp get` read the component metadata files, `mode 4` and `guided LAT LON ALT` are
accepted.

usage: gcs_mavproxy.py VENV_BIN PORT LOGDIR

MAVProxy runs interactively with its console on a pipe: the commands are typed only after the
vehicle's first heartbeat was seen (a command given with --cmd at start-up goes out before the
vehicle exists and is lost), each waits for its answer, and a time-out fails the test. The
parameter fetch must see its MAVLink FTP request for `@PARAM/param.pck` refused (NAK
FileNotFound), not timed out.
"""
import json
import os
import re
import subprocess
import sys
import threading
import time

venv_bin, port, logdir = sys.argv[1], sys.argv[2], sys.argv[3]
proc = subprocess.Popen(
    [os.path.join(venv_bin, "python"), os.path.join(venv_bin, "mavproxy.py"),
     "--master", f"udpin:127.0.0.1:{port}", "--state-basedir", logdir],
    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
lines = []
T0 = time.time()
lock = threading.Lock()


def reader():
    for line in proc.stdout:
        with lock:
            lines.append((time.time() - T0, line.rstrip()))


threading.Thread(target=reader, daemon=True).start()


def wait_for(pred, timeout, what):
    t0 = time.time()
    seen = 0
    while time.time() - t0 < timeout:
        with lock:
            new = lines[seen:]
            seen = len(lines)
        for line in new:
            if pred(line[1].strip()):
                return line[1]
        time.sleep(0.05)
    print("\n".join(f"{t:6.2f} {l}" for t, l in lines))
    print(f"FAIL: {what} within {timeout} s")
    proc.kill()
    sys.exit(1)


def send(cmd):
    proc.stdin.write(cmd + "\n")
    proc.stdin.flush()


wait_for(lambda l: "Detected vehicle" in l or "online system" in l, 30, "vehicle heartbeat")
# The mode by name (HEARTBEAT autopilot PX4; before: "Mode(67371008)" and ArduCopter's list).
PX4_MODES = ["MANUAL", "POSCTL", "MISSION", "LOITER", "RTL", "LAND", "OFFBOARD", "TAKEOFF"]
mode = wait_for(lambda l: "Mode " in l and l.rsplit("Mode ", 1)[1] in PX4_MODES, 30, "the mode announced by name")
# MAVProxy asks for the parameter file by MAVLink FTP first; the firmware serves only its
# metadata files and answers NAK FileNotFound (firmware/src/link/ftp.rs). With the ftp module's
# debug on, MAVProxy prints "ftp open failed" for that NAK and "FTP: request timed out" if no
# answer comes (before any answer: ~10 s).
send("ftp set debug 1")
send("param fetch")
t_fetch = time.time()
got = wait_for(lambda l: l.startswith("Received ") and "parameters" in l, 30, "param fetch")
t_fetch = time.time() - t_fetch
with lock:
    text = [l for _, l in lines]
if not any("ftp open failed" in l for l in text) or any("request timed out" in l for l in text):
    print("\n".join(text))
    print("FAIL: the FTP request was not refused at once (no 'ftp open failed', or a time-out)")
    proc.kill()
    sys.exit(1)
print(f"param fetch: {t_fetch:.1f} s (FTP refused, then the parameter protocol)")
# MAVProxy's own FTP client on the read-only server: the listing, then general.json downloaded.
send("ftp list /")
wait_for(lambda l: "parameters.json" in l, 20, "ftp list / showing parameters.json")
local = os.path.join(logdir, "general.json")
send(f"ftp get /general.json {local}")
wait_for(lambda l: l.startswith("Wrote ") and "general.json" in l, 20, "ftp get /general.json")
with open(local) as f:
    general = json.load(f)
if general.get("version") != 1 or [e["type"] for e in general.get("metadataTypes", [])] != [1]:
    print(f"FAIL: general.json {general}")
    proc.kill()
    sys.exit(1)
print("ftp get /general.json:", general["metadataTypes"][0]["uri"])
send("wp list")
wp = wait_for(lambda l: ("Requesting" in l and "waypoints" in l) or ("Saved" in l and "waypoints" in l),
              30, "wp list")
wait_for(lambda l: "Saved" in l and "waypoints" in l, 30, "waypoint list saved")
# Mode changes a MAVProxy 1.8.75 user can make on a PX4-identified vehicle: `mode NAME` crashes
# in the client (docs/ground-station.md § MAVProxy and modes), `mode 4` (a number: DO_SET_MODE
# with base mode AUTO, PX4 Commander's base-mode path) selects Mission, and `guided LAT LON ALT`
# sends DO_REPOSITION (MAVProxy's default guided_use_reposition) to fly there and hold.
send("mode 4")
wait_for(lambda l: "COMMAND_ACK" in l and "DO_SET_MODE" in l and "ACCEPTED" in l, 10, "mode 4 accepted")
send("status GLOBAL_POSITION_INT")
pos = wait_for(lambda l: "GLOBAL_POSITION_INT" in l and "lat" in l, 10, "the vehicle's position")
lat = int(re.search(r"lat : (-?\d+)", pos).group(1)) / 1e7
lon = int(re.search(r"lon : (-?\d+)", pos).group(1)) / 1e7
send(f"guided {lat:.7f} {lon:.7f} 1.5")
wait_for(lambda l: "COMMAND_ACK" in l and "DO_REPOSITION" in l and "ACCEPTED" in l, 10, "guided accepted")
# MAVProxy's link statistics on a loss-free local link: 0 lost (before: 93-94 % loss, the
# lockstep frames the host keeps counted as lost).
send("link")
link = wait_for(lambda l: "link " in l and "% loss" in l, 10, "link statistics")
if " 0 lost" not in link or " 0.0% loss" not in link:
    print("\n".join(f"{t:6.2f} {l}" for t, l in lines))
    print(f"FAIL: {link}")
    proc.kill()
    sys.exit(1)
send("exit")
try:
    proc.wait(timeout=5)
except subprocess.TimeoutExpired:
    proc.kill()
with lock:
    print("\n".join(f"{t:6.2f} {l}" for t, l in lines))
print(mode)
print(got)
print(wp)
print(link)
print("PASS")

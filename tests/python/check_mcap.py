"""Reads a run's flight.mcap back with the `mcap` package and checks it message by message
against the run's trajectory.csv (tests/tests/flight_mcap.rs; issue 40).

    check_mcap.py FLIGHT_MCAP TRAJECTORY_CSV OBSTACLES [RANGES_CSV]

* every channel: JSON messages with a JSON schema, the schema named as the topic's
  (foxglove.* for Foxglove's well-known ones, parapet.VehicleState for /vehicle/state) and the
  schema text's title the same name;
* /tf: one message per trajectory.csv row, world -> base_link, its translation equal to the
  row's x, y, z (both ENU) to the CSV's printed digits (printed with 4 decimals it is the row's
  text; a non-finite CSV value must be null), a unit quaternion, timestamp == log time, and log time
  minus the first == t minus the first row's t (to the CSV's digits);
* /vehicle/state: one per row, t, position, velocity, clearance, h_bar, region and mode as
  the row's (the same printed digits);
* /scene: the first message comes first in the file and holds OBSTACLES obstacle entities, the
  path (a line strip) and the goal;
* /ranges (with RANGES_CSV): the returns of every scan, in order, equal to ranges.csv's points
  (rows with x, y, z) to its digits;
* log times never go backwards in the file.

Only the pure-Python reader is needed: the chunks are uncompressed (no lz4 / zstandard).
Prints the message counts; exits non-zero with the first mismatch.
"""

import base64
import csv
import json
import math
import struct
import sys

from mcap.reader import make_reader

EXPECTED = {
    "/scene": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransform",
    "/vehicle/state": "parapet.VehicleState",
    "/ranges": "foxglove.PointCloud",
    "/events": "foxglove.Log",
}

# Half a unit of the CSV's 4th decimal, with room for the binary value of the printed text.
TOL = 0.5e-4 * (1 + 1e-9) + 1e-12


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def same(got, text, what, exact=True):
    """`got` (a JSON number or null) equals the CSV `text` to its printed digits: written with
    as many decimals it is the same text (`exact`, the numbers flight.mcap writes as the CSV
    does), else within half a unit of the last digit (the f32 points of ranges.csv)."""
    want = float(text)
    if not math.isfinite(want):
        if got is not None:
            fail(f"{what}: CSV has {text}, MCAP {got!r} (expected null)")
        return
    if got is None:
        fail(f"{what}: MCAP null, CSV {text}")
    digits = len(text.split(".")[1]) if "." in text else 0
    if exact and f"{got:.{digits}f}" != text:
        fail(f"{what}: MCAP {got!r} is {got:.{digits}f} with {digits} decimals, CSV {text}")
    if abs(got - want) > TOL:
        fail(f"{what}: MCAP {got!r} != CSV {text}")


def main():
    if len(sys.argv) not in (4, 5):
        fail("usage: check_mcap.py FLIGHT_MCAP TRAJECTORY_CSV OBSTACLES [RANGES_CSV]")
    path, csv_path, n_obstacles = sys.argv[1], sys.argv[2], int(sys.argv[3])
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    points = None
    if len(sys.argv) == 5:
        with open(sys.argv[4], newline="") as f:
            points = [r for r in csv.DictReader(f) if r["x"] != ""]
    counts = {t: 0 for t in EXPECTED}
    first_scene = None
    first_topic = None
    last_log = None
    t0 = ns0 = None
    n_points = 0
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        if summary is None:
            fail(f"{path}: no summary section")
        topics = {}
        for ch in summary.channels.values():
            want = EXPECTED.get(ch.topic)
            if want is None:
                fail(f"unexpected topic {ch.topic}")
            schema = summary.schemas.get(ch.schema_id)
            if schema is None or schema.name != want:
                fail(f"{ch.topic}: schema {schema and schema.name!r}, expected {want}")
            if schema.encoding != "jsonschema" or ch.message_encoding != "json":
                fail(f"{ch.topic}: encodings {schema.encoding}/{ch.message_encoding}")
            if json.loads(schema.data).get("title") != want:
                fail(f"{ch.topic}: the schema text's title is not {want}")
            topics[ch.topic] = schema.name
        if set(topics) != set(EXPECTED):
            fail(f"topics {sorted(topics)}, expected {sorted(EXPECTED)}")
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            topic = channel.topic
            if first_topic is None:
                first_topic = topic
            if last_log is not None and message.log_time < last_log:
                fail(f"{topic} #{message.sequence}: log time goes backwards")
            last_log = message.log_time
            msg = json.loads(message.data)
            stamp = msg.get("timestamp")
            if stamp is not None and stamp["sec"] * 10**9 + stamp["nsec"] != message.log_time:
                fail(f"{topic} #{message.sequence}: timestamp {stamp} != log time {message.log_time}")
            i = counts[topic]
            counts[topic] += 1
            if topic == "/tf":
                if i >= len(rows):
                    fail(f"/tf: more messages than the CSV's {len(rows)} rows")
                row = rows[i]
                if (msg["parent_frame_id"], msg["child_frame_id"]) != ("world", "base_link"):
                    fail(f"/tf #{i}: frames {msg['parent_frame_id']} -> {msg['child_frame_id']}")
                for k in "xyz":
                    same(msg["translation"][k], row[k], f"/tf #{i} (t = {row['t']}) {k}")
                q = msg["rotation"]
                if None not in q.values():
                    norm = math.sqrt(sum(v * v for v in q.values()))
                    if abs(norm - 1) > 1e-9:
                        fail(f"/tf #{i}: |q| = {norm}")
                if t0 is None:
                    t0, ns0 = float(row["t"]), message.log_time
                if math.isfinite(float(row["t"])):
                    dt = (message.log_time - ns0) / 1e9
                    if abs(dt - (float(row["t"]) - t0)) > TOL + 1e-6:
                        fail(f"/tf #{i}: log time {dt} s after the first, CSV t - t0 = {float(row['t']) - t0}")
            elif topic == "/vehicle/state":
                if i >= len(rows):
                    fail(f"/vehicle/state: more messages than the CSV's {len(rows)} rows")
                row = rows[i]
                what = f"/vehicle/state #{i} (t = {row['t']})"
                same(msg["t"], row["t"], f"{what} t")
                for k in "xyz":
                    same(msg["position"][k], row[k], f"{what} position.{k}")
                for k in "xyz":
                    same(msg["velocity"][k], row["v" + k], f"{what} velocity.{k}")
                same(msg["clearance"], row["clearance"], f"{what} clearance")
                same(msg["h_bar"], row["h_bar"], f"{what} h_bar")
                same(msg["filter_h_bar"], row["filter_h_bar"], f"{what} filter_h_bar")
                if (msg["region"], msg["mode"]) != (row["region"], row["mode"]):
                    fail(f"{what}: region/mode {msg['region']}/{msg['mode']} != {row['region']}/{row['mode']}")
            elif topic == "/scene" and first_scene is None:
                first_scene = msg
            elif topic == "/ranges" and points is not None:
                data = base64.b64decode(msg["data"])
                if msg["point_stride"] != 12 or len(data) % 12:
                    fail(f"/ranges #{i}: stride {msg['point_stride']}, {len(data)} bytes")
                for x, y, z in struct.iter_unpack("<fff", data):
                    if n_points >= len(points):
                        fail(f"/ranges: more points than ranges.csv's {len(points)}")
                    r = points[n_points]
                    for k, v in zip("xyz", (x, y, z)):
                        same(v, r[k], f"/ranges point {n_points} (t = {r['t']}) {k}", exact=False)
                    n_points += 1
    if counts["/tf"] != len(rows) or counts["/vehicle/state"] != len(rows):
        fail(f"/tf {counts['/tf']}, /vehicle/state {counts['/vehicle/state']} messages, CSV {len(rows)} rows")
    if first_scene is None or first_topic != "/scene":
        fail(f"the first message is on {first_topic}, not /scene")
    ids = [e["id"] for e in first_scene["entities"]]
    obstacles = [i for i in ids if i.startswith("obstacle/")]
    if len(obstacles) != n_obstacles:
        fail(f"first SceneUpdate: {len(obstacles)} obstacles, the scene has {n_obstacles}")
    path = [e for e in first_scene["entities"] if e["id"] == "path"]
    if not path or path[0]["lines"][0]["type"] != 0 or len(path[0]["lines"][0]["points"]) < 2:
        fail("first SceneUpdate: no path line strip")
    if "goal" not in ids:
        fail("first SceneUpdate: no goal")
    if rows and counts["/events"] < 2:
        fail(f"{counts['/events']} /events messages: no start and end")
    if points is not None and n_points != len(points):
        fail(f"/ranges: {n_points} points, ranges.csv {len(points)}")
    print("OK " + ", ".join(f"{t} {n}" for t, n in counts.items()) + f"; {len(rows)} CSV rows, {n_points} points")


if __name__ == "__main__":
    main()

"""Component metadata as QGroundControl fetches it, with pymavlink's MAVLink FTP client: the
COMPONENT_METADATA message (397, on MAV_CMD_REQUEST_MESSAGE), its `mftp://` URI of
general.json downloaded by FTP, its CRC checked, the parameter-metadata URI it lists followed and
that file downloaded and checked (CRC, every parameter of the parameter protocol listed once
with units and a range holding its value). Used by gcs_pymavlink.py `full`
(tests/tests/gcs_clients.rs pymavlink_parameter_and_mission_services).
"""
import json
import os
import re
import struct
import tempfile
import time
import zlib

from pymavlink import mavutil
from pymavlink.mavftp import MAVFTP
from pymavlink.mavutil import x25crc

from gcs_common import fail


def mavlink_crc32(data):
    """MAVLink's CRC32 (https://mavlink.io/en/guide/crc.md): zlib's polynomial, initial value 0,
    no final XOR."""
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


class ComponentMetadata:
    """COMPONENT_METADATA's fields from the raw frame: pymavlink 2.4.50 has no definition of
    message 397 in any dialect (it yields `UNKNOWN_397` with the frame), so the payload is read
    here as the MAVLink XML lays it out: time_boot_ms u32, file_crc u32, uri char[100] (MAVLink 2
    trims trailing zero bytes). The frame's CRC is checked with COMPONENT_METADATA's CRC_EXTRA."""

    CRC_EXTRA = 182

    def __init__(self, frame):
        n = frame[1]
        if frame[0] != 0xFD or int.from_bytes(frame[7:10], "little") != 397 or len(frame) < 12 + n:
            fail(f"not a MAVLink 2 COMPONENT_METADATA frame: {frame[:12].hex()}")
        crc = x25crc(frame[1:10 + n] + bytes([self.CRC_EXTRA])).crc
        if crc != int.from_bytes(frame[10 + n:12 + n], "little"):
            fail(f"COMPONENT_METADATA CRC {crc:#06x} != {frame[10 + n:12 + n].hex()}")
        payload = frame[10:10 + n].ljust(108, b"\0")
        self.time_boot_ms, self.file_crc = struct.unpack("<II", payload[:8])
        self.uri = payload[8:].split(b"\0", 1)[0].decode("ascii")


def component_metadata(msg):
    """COMPONENT_METADATA of pymavlink's `UNKNOWN_397` message."""
    return ComponentMetadata(bytes(msg.get_msgbuf()))


def ftp_path(uri):
    """The FTP path of an `mftp://[;comp=ID]PATH` URI on the autopilot (component 1)."""
    g = re.fullmatch(r"mftp://(?:\[;comp=(\d+)\])?(.+)", uri)
    if g is None or (g.group(1) or "1") != "1":
        fail(f"not an mftp:// URI on component 1: {uri!r}")
    return g.group(2)


def download(ftp, path, tmp):
    """The bytes of `path` by OpenFileRO + BurstReadFile (pymavlink's `ftp get`)."""
    local = os.path.join(tmp, os.path.basename(path))
    t0 = time.time()
    ftp.cmd_get([path, local])
    ret = ftp.process_ftp_reply("OpenFileRO", timeout=20)
    if ret.error_code != 0 or not os.path.exists(local):
        fail(f"FTP get {path}: {ret.operation_name} error {ret.error_code}")
    with open(local, "rb") as f:
        data = f.read()
    print(f"FTP get {path}: {len(data)} bytes in {time.time() - t0:.2f} s", flush=True)
    return data


def check_component_metadata(m, wait, sysid, compid, params):
    """`params`: {name: value} of the whole PARAM_REQUEST_LIST."""
    m.mav.command_long_send(sysid, compid, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 397, 0, 0, 0, 0, 0, 0)
    ack = wait("COMMAND_ACK", 5, lambda a: a.command == mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE)
    raw = wait("UNKNOWN_397", 5)
    if ack is None or ack.result != mavutil.mavlink.MAV_RESULT_ACCEPTED or raw is None:
        fail(f"REQUEST_MESSAGE(COMPONENT_METADATA): {ack}, {raw}")
    meta = component_metadata(raw)
    print(f"COMPONENT_METADATA uri {meta.uri} crc {meta.file_crc:#010x}", flush=True)
    ftp = MAVFTP(m, sysid, compid)
    listing = ftp.cmd_list(["/"])
    names = sorted(e.name for e in ftp.list_result)
    if listing.error_code != 0 or names != ["general.json", "parameters.json"]:
        fail(f"FTP list /: error {listing.error_code}, {names}")
    with tempfile.TemporaryDirectory() as tmp:
        general = download(ftp, ftp_path(meta.uri), tmp)
        if mavlink_crc32(general) != meta.file_crc:
            fail(f"general.json CRC {mavlink_crc32(general):#010x}, COMPONENT_METADATA says {meta.file_crc:#010x}")
        doc = json.loads(general)
        entries = [e for e in doc.get("metadataTypes", []) if e.get("type") == 1]
        if doc.get("version") != 1 or len(entries) != 1:
            fail(f"general.json: {doc}")
        meta_params = download(ftp, ftp_path(entries[0]["uri"]), tmp)
    if mavlink_crc32(meta_params) != entries[0].get("fileCrc"):
        fail(f"parameters.json CRC {mavlink_crc32(meta_params):#010x}, general.json says {entries[0].get('fileCrc')}")
    listed = json.loads(meta_params)["parameters"]
    by_name = {p["name"]: p for p in listed}
    if len(by_name) != len(listed) or sorted(by_name) != sorted(params):
        fail(f"parameter metadata names differ from the parameter protocol's: "
             f"{sorted(set(by_name) ^ set(params))}")
    for name, value in params.items():
        p = by_name[name]
        if "units" not in p or not p["min"] <= p["default"] <= p["max"] or \
                not p["min"] - 1e-4 * abs(p["min"]) <= value <= p["max"] + 1e-4 * abs(p["max"]):
            fail(f"{name} = {value}: metadata {p}")
    print(f"parameter metadata: {len(listed)} parameters, names, units and ranges agree", flush=True)

#!/usr/bin/env python3
"""Writes the seed corpora under tests/fuzz/corpus/<target>/ (committed; re-run to regenerate).

MAVLink v2 frames are built here from the message layouts (wire order: fields by size) and
CRC_EXTRA values of the `ardupilotmega` dialect the firmware uses; the `link` seeds are a PIL
start sequence (parameters, mission upload, odometry, obstacles, HIL_SENSOR steps, arm, start)
in both input modes of the `link` target. Text targets get the shipped scenes and path files
and a few small replay CSVs.
"""
import pathlib
import shutil
import struct

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
EXTRA = {0: 50, 107: 108, 331: 91, 11037: 130, 250: 49, 44: 221, 73: 38, 47: 153, 45: 232,
         76: 152, 23: 168, 20: 214}


def crc16(data, crc=0xFFFF):
    """CRC-16/MCRF4XX (X.25 as MAVLink uses it)."""
    for b in data:
        t = b ^ (crc & 0xFF)
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc


class Writer:
    def __init__(self, sysid=255, compid=190):
        self.seq, self.sysid, self.compid = 0, sysid, compid

    def frame(self, msg_id, payload, signed=False):
        payload = payload.rstrip(b"\0") or b"\0"
        head = bytes([len(payload), 1 if signed else 0, 0, self.seq, self.sysid, self.compid]) + \
            msg_id.to_bytes(3, "little")
        self.seq = (self.seq + 1) & 0xFF
        crc = crc16(head + payload + bytes([EXTRA[msg_id]]))
        out = b"\xfd" + head + payload + struct.pack("<H", crc)
        return out + (bytes(13) if signed else b"")


def heartbeat():
    return 0, struct.pack("<IBBBBB", 0, 6, 8, 0, 0, 3)


def command_long(cmd, p=(0,) * 7):
    return 76, struct.pack("<7fHBBB", *p, cmd, 1, 1, 0)


def param_set(name, value):
    return 23, struct.pack("<fBB16sB", value, 1, 1, name.encode(), 9)


def mission_count(n):
    return 44, struct.pack("<HBBB", n, 1, 1, 0)


def mission_item(seq, x, y, z):
    return 73, struct.pack("<4fiifHHBBBBB", 0, 0, 0, 0, int(x * 1e4), int(y * 1e4), z, seq, 16,
                           1, 1, 1, 0, 1)


def odometry(t_us, x, y, z):
    return 331, struct.pack("<Q3f4f6f21f21fBB", t_us, x, y, z, 1, 0, 0, 0, *([0.0] * 6),
                            *([0.0] * 42), 1, 1)


def obstacle(t_us, oid, x, y, z):
    return 11037, struct.pack("<I5fHBB", t_us // 1000, x, y, z, 0, 10, oid, 0, 1)


def hil_sensor(t_us):
    return 107, struct.pack("<Q13fI", t_us, 0, 0, -9.81, 0, 0, 0, *([0.0] * 7), 0)


def start_sequence(steps=12):
    """(msg_id, payload) of a short PIL session."""
    msgs = [heartbeat(), param_set("CBF_MU", 1.4), param_set("WP_SPEED", 0.5), mission_count(2),
            mission_item(0, 1, 0, -1), mission_item(1, 2, 1, -1)]
    for k in range(steps):
        t = 1000 * (k + 1)
        if k % 4 == 0:
            msgs += [odometry(t, 0, 0, -1), obstacle(t, 3, 1.5, 0.2, -1)]
        if k == 8:
            msgs += [command_long(400, (1, 0, 0, 0, 0, 0, 0)),
                     command_long(252, (0, 3, 1, 0, 0, 0, -1)), command_long(300)]
        msgs.append(hil_sensor(t))
    return msgs


def write(target, name, data):
    d = HERE / "corpus" / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data)


def crc8_dvb_s2(data):
    """CRC-8 DVB-S2 (poly 0xD5, init 0): the CRSF frame check."""
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0xD5) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def pack11(ticks):
    """16 x 11-bit channel values, LSB first (CRSF RC_CHANNELS_PACKED and SBUS)."""
    bits = sum((t & 0x7FF) << (11 * i) for i, t in enumerate(ticks))
    return bits.to_bytes(22, "little")


def crsf(kind, payload, addr=0xC8):
    body = bytes([kind]) + payload
    return bytes([addr, len(body) + 1]) + body + bytes([crc8_dvb_s2(body)])


def timed(data, dt):
    """The rc targets' input: (byte, dt) pairs."""
    return b"".join(bytes([b, dt]) for b in data)


def rc_seeds():
    """crsf / sbus targets (issue 21): recorded frames (sources in core/src/rc/*.rs tests)."""
    rc = crsf(0x16, pack11([992] * 4 + [172, 1811] + [992] * 10))
    link = crsf(0x14, bytes([45, 50, 100, 9, 1, 5, 3, 60, 98, 253]))
    elrs_ee = bytes.fromhex("ee1816e1e3de09c7d78a56800f7ce0031ff8c0073ef0810f7c36")
    betaflight = bytes.fromhex("c81816bd089ff4aef7bdef7deffbadfd452b5a0100000000006c")
    write("crsf", "rc_link_rc", timed(rc, 0) + timed(link, 50) + timed(rc, 50))
    write("crsf", "edgetx_address", timed(elrs_ee, 1))
    write("crsf", "betaflight_capture", timed(betaflight, 1))
    write("crsf", "garbage_false_sync_then_frame", timed(b"\x00\xc8\xff\xc8\x30\x16" + rc, 0))
    write("crsf", "cut_frame_pause_frame", timed(rc[:11], 0) + bytes([rc[11], 200]) + timed(rc[12:] + rc, 0))
    frame = bytes([0x0F]) + pack11([1041, 1024, 1696, 1024, 352, 1696] + [1024] * 10) + b"\x00"
    write("sbus", "sbus2_footers", b"".join(timed(frame + bytes([f]), 5) + b"\x00\xff" for f in (0x14, 0x24, 0x34, 0x04)))
    write("sbus", "failsafe_then_good", timed(frame[:-1] + b"\x0c\x00", 5) + b"\x00\xff" + timed(frame + b"\x00", 5))
    write("sbus", "missing_byte_telemetry", timed(frame[:12] + frame[13:] + b"\x00", 5) + bytes([3, 86, 0xC0, 5, 0x2E, 5]))


def main():
    w = Writer()
    seq = start_sequence()
    wire = b"".join(w.frame(i, p) for i, p in seq)
    # frame_parser: single frames, a stream, a cut frame, noise, a signed frame, an unknown id.
    write("frame_parser", "heartbeat", w.frame(*heartbeat()))
    write("frame_parser", "command_long_arm", w.frame(*command_long(400, (1, 0, 0, 0, 0, 0, 0))))
    write("frame_parser", "odometry", w.frame(*odometry(4000, 1, 2, -3)))
    write("frame_parser", "pil_start_stream", wire[:600])
    mc = w.frame(*mission_count(2))
    write("frame_parser", "cut_header_then_frame", mc[:7] + w.frame(*heartbeat()))
    write("frame_parser", "noise_then_frame", bytes(range(0, 250, 7)) + b"\xfd\x09" + mc)
    write("frame_parser", "signed_frame", w.frame(*heartbeat(), signed=True) + mc)
    unknown = bytearray(w.frame(*heartbeat()))
    unknown[7:10] = b"\x99\x77\x77"
    write("frame_parser", "unknown_id_then_frame", bytes(unknown) + mc)
    # link: raw mode (first byte even) and chunk mode (odd: tag, len, payload; tag >= 0xF0 raw).
    write("link", "raw_pil_start", b"\x00" + wire)
    write("link", "raw_cut_frames", b"\x00" + wire[:40] + wire[45:300])
    inbound = [0, 107, 331, 11037, 250, 44, 73, 47, 45, 76, 23, 20, 107]
    chunks = b"".join(bytes([inbound.index(i), len(p.rstrip(b"\0") or b"\0")]) + (p.rstrip(b"\0") or b"\0")
                      for i, p in seq)
    write("link", "chunks_pil_start", b"\x01" + chunks)
    write("link", "chunks_with_noise", b"\x01" + chunks[:200] + b"\xf3\x05\xfd\x20\x00\x00\x01" + chunks[200:])
    # Text loaders: the shipped files and small hand-made ones.
    for f in sorted((ROOT / "scenes").glob("*.toml")):
        write("scene_toml", f.name, f.read_bytes())
    for f in sorted((ROOT / "scenes").glob("*.json")):
        write("path_json", f.name, f.read_bytes())
    write("path_json", "minimal.json", b'{"scene": "x", "waypoints": [[0, 0, 1], [1, 0, 1]]}\n')
    write("replay_csv", "hover.csv",
          b"t,w1,w2,w3,w4\n0,400,400,400,400\n0.01,400,400,400,400\n0.02,410,390,410,390\n")
    write("replay_csv", "one_row.csv", b"t,w1,w2,w3,w4\n0,0,0,0,0\n")
    write("replay_csv", "spaces_blank_lines.csv", b"t, w1, w2, w3, w4\n\n0.5, 1e2, 2.5e2, 0, 3\n 1, 1, 1, 1, 1 \n")

    rc_seeds()


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Writes firmware/mavlink/parapet.xml: the MAVLink messages the firmware speaks, cut out of the
`ardupilotmega` dialect (with everything it includes: common, standard, minimal, ...) that the
host tools and real ground stations use.

Messages are copied verbatim (fields, extension markers), so their ids, CRC_EXTRA bytes and wire
layout are those of the full dialect (checked by `firmware/tests/dialect.rs`). Enums are those
the copied fields reference, with every entry the full dialect gives them (`MAV_CMD` complete,
as constants). One change: the `command` fields (COMMAND_LONG/INT/ACK/CANCEL, MISSION_ITEM(_INT))
lose their `enum="MAV_CMD"` attribute and stay plain `u16` (the attribute is not part of the
CRC_EXTRA nor of the wire): every command id then decodes and an unknown one is answered
UNSUPPORTED with its own id, and the ~2 KB `MavCmd` from-integer conversion is not linked.
Compare with `MavCmd::X as u16`. Likewise SET_MODE's `base_mode` (a MAV_MODE_FLAG bit set in
practice, not one of the MAV_MODE values) stays a plain `u8`. `firmware/build.rs` turns the file into Rust with
`mavlink-bindgen`.

Usage: python3 firmware/mavlink/extract.py DEFINITIONS_DIR > firmware/mavlink/parapet.xml
where DEFINITIONS_DIR is `mavlink-0.21.0/mavlink/message_definitions/v1.0` of the cargo
registry (`ls ~/.cargo/registry/src/*/mavlink-0.21.0/mavlink/message_definitions/v1.0`).
"""
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

# The firmware's inbound and outbound sets plus what issues 20-22 use (RC input, offboard
# set-points, battery, log transfer, stream rates, ...). A message that is listed but not used
# costs no flash: only the (de)serialisers the code calls are linked.
MESSAGES = """
HEARTBEAT SYS_STATUS SYSTEM_TIME PING SET_MODE PARAM_REQUEST_READ PARAM_REQUEST_LIST PARAM_VALUE PARAM_SET
GPS_RAW_INT SCALED_IMU RAW_IMU SCALED_PRESSURE ATTITUDE ATTITUDE_QUATERNION LOCAL_POSITION_NED
GLOBAL_POSITION_INT RC_CHANNELS_RAW SERVO_OUTPUT_RAW MISSION_REQUEST_PARTIAL_LIST MISSION_ITEM
MISSION_REQUEST MISSION_SET_CURRENT MISSION_CURRENT MISSION_REQUEST_LIST MISSION_COUNT
MISSION_CLEAR_ALL MISSION_ITEM_REACHED MISSION_ACK SET_GPS_GLOBAL_ORIGIN GPS_GLOBAL_ORIGIN
MISSION_REQUEST_INT RC_CHANNELS REQUEST_DATA_STREAM DATA_STREAM MANUAL_CONTROL
RC_CHANNELS_OVERRIDE MISSION_ITEM_INT VFR_HUD COMMAND_INT COMMAND_LONG COMMAND_ACK
COMMAND_CANCEL MANUAL_SETPOINT SET_ATTITUDE_TARGET ATTITUDE_TARGET SET_POSITION_TARGET_LOCAL_NED
POSITION_TARGET_LOCAL_NED SET_POSITION_TARGET_GLOBAL_INT POSITION_TARGET_GLOBAL_INT
HIL_STATE HIL_CONTROLS HIL_ACTUATOR_CONTROLS HIGHRES_IMU HIL_SENSOR HIL_GPS HIL_STATE_QUATERNION
RADIO_STATUS TIMESYNC SCALED_IMU2 LOG_REQUEST_LIST LOG_ENTRY LOG_REQUEST_DATA LOG_DATA LOG_ERASE
LOG_REQUEST_END POWER_STATUS DISTANCE_SENSOR ALTITUDE BATTERY_STATUS AUTOPILOT_VERSION
LANDING_TARGET ESTIMATOR_STATUS VIBRATION HOME_POSITION SET_HOME_POSITION MESSAGE_INTERVAL
EXTENDED_SYS_STATE STATUSTEXT DEBUG_VECT NAMED_VALUE_FLOAT NAMED_VALUE_INT DEBUG
OBSTACLE_DISTANCE ODOMETRY PROTOCOL_VERSION OBSTACLE_DISTANCE_3D FILE_TRANSFER_PROTOCOL
AVAILABLE_MODES CURRENT_MODE AVAILABLE_MODES_MONITOR VISION_POSITION_ESTIMATE GPS_INPUT COMPONENT_METADATA
""".split()

# Enums referenced only from command parameters, kept for the firmware's command handling.
EXTRA_ENUMS = "MAV_CMD MAV_MODE MAV_BOOL PREFLIGHT_STORAGE_PARAMETER_ACTION MOTOR_TEST_THROTTLE_TYPE MOTOR_TEST_ORDER".split()


def load(path, seen, enums, messages, order):
    """Reads `path` and its includes (depth first); merges enum entries by enum name."""
    path = path.resolve()
    if path in seen:
        return
    seen.add(path)
    root = ET.parse(path).getroot()
    for inc in root.findall("include"):
        load(path.parent / inc.text.strip(), seen, enums, messages, order)
    for e in root.findall("enums/enum"):
        name = e.get("name")
        if name in enums:
            have = {x.get("name") for x in enums[name].findall("entry")}
            for entry in e.findall("entry"):
                if entry.get("name") not in have:
                    enums[name].append(entry)
        else:
            enums[name] = e
            order.append(name)
    for m in root.findall("messages/message"):
        messages[m.get("name")] = m


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    defs = Path(sys.argv[1])
    enums, messages, order = {}, {}, []
    load(defs / "ardupilotmega.xml", set(), enums, messages, order)
    missing = [m for m in MESSAGES if m not in messages]
    if missing:
        sys.exit(f"{defs}/ardupilotmega.xml: messages not in the dialect: {missing}")
    wanted = set(EXTRA_ENUMS)
    for name in MESSAGES:
        for f in messages[name].iter("field"):
            if f.get("enum") == "MAV_CMD" or (name, f.get("name")) == ("SET_MODE", "base_mode"):
                del f.attrib["enum"]
            if f.get("enum"):
                wanted.add(f.get("enum"))
    unknown = sorted(w for w in wanted if w not in enums)
    if unknown:
        sys.exit(f"{defs}: enums not in the dialect: {unknown}")
    out = ET.Element("mavlink")
    ET.SubElement(out, "version").text = "3"
    ET.SubElement(out, "dialect").text = "0"
    es = ET.SubElement(out, "enums")
    for name in order:
        if name in wanted:
            es.append(enums[name])
    ms = ET.SubElement(out, "messages")
    for m in sorted((messages[n] for n in MESSAGES), key=lambda m: int(m.get("id"))):
        ms.append(m)
    ET.indent(out, space="  ")
    sys.stdout.write('<?xml version="1.0"?>\n<!-- Generated by firmware/mavlink/extract.py from mavlink 0.21.0 (ardupilotmega.xml and its includes); do not edit. -->\n')
    sys.stdout.write(ET.tostring(out, encoding="unicode"))
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()

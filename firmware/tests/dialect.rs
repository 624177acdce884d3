//! The firmware's generated MAVLink dialect (`parapet_firmware::link::dialect`, from
//! `firmware/mavlink/parapet.xml`) against the `mavlink` crate's full `ardupilotmega` dialect
//! that ground stations and the host tools use: every message of the firmware's set exists
//! there under the same id and name with the same CRC_EXTRA byte (so the same field types and
//! order), and a frame the firmware writes, MAVLink 2 extension fields included, reads back
//! with the full dialect.

use mavlink::dialects::ardupilotmega as full;
use mavlink_core::Message;
use parapet_firmware::link::dialect as fw;
use parapet_firmware::link::framing::FrameWriter;

#[test]
fn every_firmware_message_has_the_full_dialects_id_name_and_crc_extra() {
    let mut n = 0;
    for id in 0..=u16::MAX as u32 {
        let Some(ours) = <fw::MavMessage as Message>::default_message_from_id(id) else {
            continue;
        };
        let theirs = <full::MavMessage as Message>::default_message_from_id(id)
            .unwrap_or_else(|| panic!("message id {id} ({}) is not in ardupilotmega", ours.message_name()));
        assert_eq!(ours.message_name(), theirs.message_name(), "id {id}");
        assert_eq!(
            <fw::MavMessage as Message>::extra_crc(id),
            <full::MavMessage as Message>::extra_crc(id),
            "CRC_EXTRA of {} (id {id})",
            ours.message_name()
        );
        n += 1;
    }
    // The list in firmware/mavlink/extract.py.
    assert_eq!(n, 94, "messages in firmware/mavlink/parapet.xml");
}

#[test]
fn a_firmware_frame_with_extension_fields_reads_back_with_the_full_dialect() {
    let ack = fw::COMMAND_ACK_DATA {
        command: fw::MavCmd::MAV_CMD_COMPONENT_ARM_DISARM as u16,
        result: fw::MavResult::MAV_RESULT_ACCEPTED,
        progress: 7,
        result_param2: -3,
        target_system: 255,
        target_component: 190,
    };
    let raw = FrameWriter::new(1, 1).encode(&ack);
    let mut r = mavlink::MavlinkReader::new(raw.raw_bytes());
    let (hdr, msg) =
        r.read_message::<full::MavMessage>(mavlink::MavlinkVersion::V2).expect("a valid MAVLink 2 frame");
    assert_eq!((hdr.system_id, hdr.component_id), (1, 1));
    let full::MavMessage::COMMAND_ACK(got) = msg else { panic!("not a COMMAND_ACK: {msg:?}") };
    assert_eq!(got.command, full::MavCmd::MAV_CMD_COMPONENT_ARM_DISARM);
    assert_eq!(got.result, full::MavResult::MAV_RESULT_ACCEPTED);
    // The firmware always sends the extensions; the host `mavlink` build has them when the
    // firmware's mavlink-bindgen build-dependency is in the same build (as here).
    let bytes = raw.payload();
    assert!(bytes.len() > 3, "extension bytes on the wire: {bytes:?}");
    assert_eq!((got.progress, got.result_param2, got.target_system, got.target_component), (7, -3, 255, 190));
}

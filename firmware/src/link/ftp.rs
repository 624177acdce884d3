//! MAVLink FTP (FILE_TRANSFER_PROTOCOL, 110), vehicle side: **not served** — every request is
//! answered at once with a NAK `UnknownCommand`, so a client gives up on FTP immediately instead
//! of after its own timeout. MAVProxy's `param fetch` first asks for `@PARAM/param.pck` by FTP
//! and falls back to the parameter protocol only when that fails: without an answer it waited
//! ~10 s (seen in CI, `tests/tests/gcs_clients.rs`); with the NAK its `ftp_callback(None)` runs
//! on the reply and the PARAM_REQUEST_LIST follows. QGroundControl does the same for its
//! parameter cache file.
//!
//! Wire format (<https://mavlink.io/en/services/ftp.html>): the message's 251-byte `payload`
//! starts with a 12-byte header — `seq` u16 LE, `session`, `opcode`, `size`, `req_opcode`,
//! `burst_complete`, padding, `offset` u32 LE — then `size` data bytes. A reply carries
//! `seq + 1`, the request's `session`, opcode `RSP_NAK` (129), `req_opcode` = the request's
//! opcode, `size` 1 and the error code in the first data byte.
//!
//! Only requests are answered (opcodes below 128); a client's ACK/NAK (opcodes 128, 129) is
//! not a request and gets no answer. Kept compact in [`crate::link::outbound::Outbound`]
//! ([`FtpNak`], 6 bytes) instead of the 254-byte message.
//!
//! May import: the dialect. No allocation, no panics.

use crate::link::dialect::FILE_TRANSFER_PROTOCOL_DATA;

/// Opcode of a NAK reply.
pub const RSP_NAK: u8 = 129;
/// Error code: unknown command / opcode (the server implements none).
pub const ERR_UNKNOWN_COMMAND: u8 = 7;

/// The addressing and header fields of an FTP request that a NAK needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FtpRequest {
    /// `target_system` of the message.
    pub target_system: u8,
    /// `target_component` of the message.
    pub target_component: u8,
    /// Header `seq`.
    pub seq: u16,
    /// Header `session`.
    pub session: u8,
    /// Header `opcode`.
    pub opcode: u8,
}

impl FtpRequest {
    /// The request of a FILE_TRANSFER_PROTOCOL payload `p` (MAVLink 2 trims trailing zero bytes:
    /// missing bytes read as 0).
    pub fn parse(p: &[u8]) -> FtpRequest {
        let b = |i: usize| p.get(i).copied().unwrap_or(0);
        FtpRequest {
            target_system: b(1),
            target_component: b(2),
            seq: u16::from_le_bytes([b(3), b(4)]),
            session: b(5),
            opcode: b(6),
        }
    }
}

/// A NAK to send to the requester.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FtpNak {
    /// The requester's system id.
    pub target_system: u8,
    /// The requester's component id.
    pub target_component: u8,
    /// `seq` of the request + 1 (wrapping).
    pub seq: u16,
    /// The request's session.
    pub session: u8,
    /// The request's opcode.
    pub req_opcode: u8,
}

/// The answer to request `r` from (`sys`, `comp`): a NAK `UnknownCommand`, or `None` for an
/// ACK/NAK (opcode ≥ 128), which is not a request.
pub fn answer(r: &FtpRequest, sys: u8, comp: u8) -> Option<FtpNak> {
    (r.opcode < 128).then_some(FtpNak {
        target_system: sys,
        target_component: comp,
        seq: r.seq.wrapping_add(1),
        session: r.session,
        req_opcode: r.opcode,
    })
}

impl FtpNak {
    /// The message.
    pub fn data(&self) -> FILE_TRANSFER_PROTOCOL_DATA {
        let mut payload = [0u8; 251];
        let [s0, s1] = self.seq.to_le_bytes();
        // seq, session, opcode, size, req_opcode, burst_complete, padding, offset (4), data[0].
        let head = [s0, s1, self.session, RSP_NAK, 1, self.req_opcode, 0, 0, 0, 0, 0, 0, ERR_UNKNOWN_COMMAND];
        for (d, h) in payload.iter_mut().zip(head) {
            *d = h;
        }
        FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: self.target_system,
            target_component: self.target_component,
            payload,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// MAVProxy's OpenFileRO of `@PARAM/param.pck` (opcode 4, session 0) with `seq` from
    /// GCS 255/190 to the autopilot 1/1, as its `FTP_OP.pack` lays it out.
    fn open_ro(seq: u16) -> [u8; 28] {
        let mut p = [0u8; 28];
        p[1] = 1;
        p[2] = 1;
        p[3..5].copy_from_slice(&seq.to_le_bytes());
        p[6] = 4;
        p[7] = 15;
        p[15..28].copy_from_slice(b"@PARAM/param.");
        p
    }

    #[test]
    fn a_request_is_naked_with_unknown_command() {
        let r = FtpRequest::parse(&open_ro(0xFFFF));
        assert_eq!((r.target_system, r.target_component, r.seq, r.opcode), (1, 1, 0xFFFF, 4));
        let nak = answer(&r, 255, 190).expect("a request is answered");
        let m = nak.data();
        assert_eq!((m.target_system, m.target_component), (255, 190));
        // seq wraps to 0, session 0, NAK, size 1, req_opcode 4, error 7 (UnknownCommand).
        assert_eq!(&m.payload[..13], &[0, 0, 0, RSP_NAK, 1, 4, 0, 0, 0, 0, 0, 0, ERR_UNKNOWN_COMMAND]);
        assert!(m.payload[13..].iter().all(|&b| b == 0));
    }

    #[test]
    fn replies_and_short_payloads_get_no_answer_or_no_panic() {
        let mut p = open_ro(3);
        p[6] = RSP_NAK;
        assert_eq!(answer(&FtpRequest::parse(&p), 255, 190), None);
        p[6] = 128; // ACK
        assert_eq!(answer(&FtpRequest::parse(&p), 255, 190), None);
        // A payload trimmed to the target fields still parses (opcode 0 = None, a request).
        let r = FtpRequest::parse(&[0, 1]);
        assert_eq!((r.target_system, r.seq, r.opcode), (1, 0, 0));
        assert_eq!(FtpRequest::parse(&[]).target_system, 0);
    }
}

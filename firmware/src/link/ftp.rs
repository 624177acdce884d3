//! MAVLink FTP (FILE_TRANSFER_PROTOCOL, 110), vehicle side: a **read-only** server over the
//! files compiled into flash ([`crate::link::metadata::FILES`]: `general.json` and
//! `parameters.json`, what COMPONENT_METADATA points to). This module owns the wire format
//! (request parsing, reply encoding) and the one-session state machine ([`FtpServer`]).
//!
//! Wire format (<https://mavlink.io/en/services/ftp.html>): the message's 251-byte `payload`
//! starts with a 12-byte header — `seq` u16 LE, `session`, `opcode`, `size`, `req_opcode`,
//! `burst_complete`, padding, `offset` u32 LE — then `size` data bytes (≤ [`MAX_DATA`]). A
//! reply carries `seq + 1`, the request's `session`, opcode [`op::ACK`] or [`op::NAK`],
//! `req_opcode` = the request's opcode; a NAK has `size` 1 and the error code ([`err`]) in its
//! first data byte.
//!
//! | opcode | answer |
//! |---|---|
//! | ResetSessions (2) | ACK; the session closed, a burst stopped |
//! | TerminateSession (1) | ACK when `session` is the open one, else NAK InvalidSession |
//! | OpenFileRO (4) | ACK with the file size (u32 LE, `size` 4); the session id is the request's (MAVProxy picks its own and ignores replies of another session; pymavlink and QGroundControl take the ACK's); an open session is replaced (one session: a client whose open ACK was lost retries the open); unknown path (e.g. MAVProxy's `@PARAM/param.pck`) NAK FileNotFound |
//! | ReadFile (5) | ACK with `min(size, 239, left)` bytes at `offset`; `offset` ≥ file size NAK EOF; another session NAK InvalidSession |
//! | BurstReadFile (15) | ACKs of `size` bytes (0 or > 239: 239) from `offset` to the end of the file, `seq` counting up from the request's + 1, the last with `burst_complete` 1; one per [`FtpServer::next_burst`] (the router's pacing); `offset` ≥ file size NAK EOF (`burst_complete` 1) |
//! | ListDirectory (3) | `/` (or an empty path): ACK with the entries `F<name>\t<size>\0` from entry index `offset`, as many as fit; past the last NAK EOF; other paths NAK FileNotFound |
//! | CalcFileCRC32 (14) | ACK with the file's MAVLink CRC32 (u32 LE, computed at build time) or NAK FileNotFound |
//! | CreateFile, WriteFile, RemoveFile, CreateDirectory, RemoveDirectory, OpenFileWO, TruncateFile, Rename (6–13) | NAK FileProtected: the file system is read-only |
//! | None (0), 16–127 | NAK UnknownCommand |
//! | ACK / NAK (128, 129) | not a request: no answer |
//!
//! Replies are kept compact in [`crate::link::outbound::Outbound`] ([`FtpReply`]: header fields
//! and where the data comes from, ~20 bytes) and their data bytes are copied out of flash when
//! the frame is encoded. No allocation, no panics, O(1) state.
//!
//! May import: the dialect, [`crate::link::metadata`] (the files).

use crate::link::dialect::FILE_TRANSFER_PROTOCOL_DATA;
use crate::link::metadata::{File, FILES};

/// Opcodes (request 0–15, reply 128/129).
pub mod op {
    /// None (ignored by servers: answered UnknownCommand here).
    pub const NONE: u8 = 0;
    /// TerminateSession.
    pub const TERMINATE_SESSION: u8 = 1;
    /// ResetSessions.
    pub const RESET_SESSIONS: u8 = 2;
    /// ListDirectory.
    pub const LIST_DIRECTORY: u8 = 3;
    /// OpenFileRO.
    pub const OPEN_FILE_RO: u8 = 4;
    /// ReadFile.
    pub const READ_FILE: u8 = 5;
    /// CreateFile (first of the write operations, 6–13).
    pub const CREATE_FILE: u8 = 6;
    /// Rename (last of the write operations).
    pub const RENAME: u8 = 13;
    /// CalcFileCRC32.
    pub const CALC_FILE_CRC32: u8 = 14;
    /// BurstReadFile.
    pub const BURST_READ_FILE: u8 = 15;
    /// ACK reply.
    pub const ACK: u8 = 128;
    /// NAK reply.
    pub const NAK: u8 = 129;
}

/// NAK error codes.
pub mod err {
    /// InvalidSession: the session is not open.
    pub const INVALID_SESSION: u8 = 4;
    /// EOF: offset past the end of the file or directory.
    pub const EOF: u8 = 6;
    /// UnknownCommand.
    pub const UNKNOWN_COMMAND: u8 = 7;
    /// FileProtected: the file system is read-only.
    pub const FILE_PROTECTED: u8 = 9;
    /// FileNotFound.
    pub const FILE_NOT_FOUND: u8 = 10;
}

/// Most data bytes in one message (251-byte payload − 12-byte header).
pub const MAX_DATA: usize = 239;
/// Longest path kept from a request (longer ones match no file: FileNotFound).
pub const MAX_PATH: usize = 64;
/// Header length in the payload.
const HDR: usize = 12;

/// An FTP request: the addressing, the header and the path (the data of OpenFileRO,
/// ListDirectory, CalcFileCRC32; up to the first NUL).
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
    /// Header `size` (data length; bytes wanted for reads).
    pub size: u8,
    /// Header `offset`.
    pub offset: u32,
    path: [u8; MAX_PATH],
    path_len: u8,
}

impl FtpRequest {
    /// The request of a FILE_TRANSFER_PROTOCOL payload `p` (MAVLink 2 trims trailing zero bytes:
    /// missing bytes read as 0).
    pub fn parse(p: &[u8]) -> FtpRequest {
        let b = |i: usize| p.get(i).copied().unwrap_or(0);
        let h = |i: usize| b(3 + i);
        let size = h(4);
        let data = p.get(3 + HDR..).unwrap_or(&[]);
        let data = data.get(..usize::from(size)).unwrap_or(data);
        let data = data.split(|&c| c == 0).next().unwrap_or(&[]);
        let mut path = [0u8; MAX_PATH];
        // A path longer than any served one is kept empty: it matches nothing.
        let path_len = if data.len() <= MAX_PATH { data.len() } else { 0 };
        for (d, s) in path.iter_mut().zip(&data[..path_len]) {
            *d = *s;
        }
        FtpRequest {
            target_system: b(1),
            target_component: b(2),
            seq: u16::from_le_bytes([h(0), h(1)]),
            session: h(2),
            opcode: h(3),
            size,
            offset: u32::from_le_bytes([h(8), h(9), h(10), h(11)]),
            path,
            path_len: path_len as u8,
        }
    }

    /// The path bytes.
    pub fn path(&self) -> &[u8] {
        &self.path[..usize::from(self.path_len).min(MAX_PATH)]
    }
}

/// Where a reply's data bytes come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Body {
    /// No data (an ACK of ResetSessions / TerminateSession).
    Empty,
    /// A NAK with this error code.
    Nak(u8),
    /// `len` bytes of file `file` ([`FILES`] index) at the reply's offset.
    File {
        /// Index into [`FILES`].
        file: u8,
        /// Bytes.
        len: u8,
    },
    /// The root directory's entries from index `first` (as many as fit).
    Dir {
        /// First entry.
        first: u8,
    },
    /// A u32, little-endian (a file size, a CRC).
    Word(u32),
}

/// One FTP reply (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FtpReply {
    /// The requester's system id.
    pub target_system: u8,
    /// The requester's component id.
    pub target_component: u8,
    /// Header `seq`.
    pub seq: u16,
    /// Header `session`.
    pub session: u8,
    /// The request's opcode.
    pub req_opcode: u8,
    /// Last packet of a burst.
    pub burst_complete: bool,
    /// Header `offset`.
    pub offset: u32,
    /// The data.
    pub body: Body,
}

impl FtpReply {
    /// The message.
    pub fn data(&self) -> FILE_TRANSFER_PROTOCOL_DATA {
        let mut payload = [0u8; 251];
        let (head, data) = payload.split_at_mut(HDR);
        let (opcode, size) = match self.body {
            Body::Empty => (op::ACK, 0),
            Body::Nak(e) => {
                data[0] = e;
                (op::NAK, 1)
            }
            Body::File { file, len } => {
                let bytes = FILES.get(usize::from(file)).map_or(&[][..], |f| f.bytes);
                let start = (self.offset as usize).min(bytes.len());
                let end = start.saturating_add(usize::from(len)).min(bytes.len());
                let src = &bytes[start..end];
                for (d, s) in data.iter_mut().zip(src) {
                    *d = *s;
                }
                (op::ACK, src.len())
            }
            Body::Dir { first } => (op::ACK, list(usize::from(first), data).1),
            Body::Word(w) => {
                data[..4].copy_from_slice(&w.to_le_bytes());
                (op::ACK, 4)
            }
        };
        let [s0, s1] = self.seq.to_le_bytes();
        let [o0, o1, o2, o3] = self.offset.to_le_bytes();
        let h = [s0, s1, self.session, opcode, size as u8, self.req_opcode, u8::from(self.burst_complete), 0];
        head[..8].copy_from_slice(&h);
        head[8..].copy_from_slice(&[o0, o1, o2, o3]);
        FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: self.target_system,
            target_component: self.target_component,
            payload,
        }
    }
}

/// Writes the root directory's entries from index `first` into `out` (`F<name>\t<size>\0`
/// each, whole entries only): (entries written, bytes written).
fn list(first: usize, out: &mut [u8]) -> (usize, usize) {
    let mut at = 0;
    let mut n = 0;
    for f in FILES.iter().skip(first) {
        let mut digits = [0u8; 10];
        let d = decimal(f.bytes.len() as u32, &mut digits);
        let len = 1 + f.name.len() + 1 + d.len() + 1;
        let Some(dst) = out.get_mut(at..at + len) else { break };
        let parts: [&[u8]; 5] = [b"F", f.name.as_bytes(), b"\t", d, b"\0"];
        for (o, c) in dst.iter_mut().zip(parts.iter().flat_map(|p| p.iter())) {
            *o = *c;
        }
        at += len;
        n += 1;
    }
    (n, at)
}

/// `v` in decimal, in `buf`.
fn decimal(mut v: u32, buf: &mut [u8; 10]) -> &[u8] {
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 || i == 0 {
            break;
        }
    }
    &buf[i..]
}

/// The served file at `path` (with or without a leading `/`): its index.
fn find(path: &[u8]) -> Option<u8> {
    let p = path.strip_prefix(b"/").unwrap_or(path);
    FILES.iter().position(|f: &File| f.name.as_bytes() == p).map(|i| i as u8)
}

/// A running BurstReadFile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Burst {
    to: (u8, u8),
    session: u8,
    seq: u16,
    offset: u32,
    chunk: u8,
    file: u8,
}

/// The server: at most one open session (a file) and one burst.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FtpServer {
    /// The open session: (id, file).
    open: Option<(u8, u8)>,
    burst: Option<Burst>,
}

impl FtpServer {
    /// No session open.
    pub const fn new() -> Self {
        Self { open: None, burst: None }
    }

    /// The answer to request `r` from `sender` (system, component); `None` for a reply (opcode
    /// ≥ 128) and for a BurstReadFile that starts ([`FtpServer::next_burst`] sends it).
    pub fn on_request(&mut self, r: &FtpRequest, sender: (u8, u8)) -> Option<FtpReply> {
        if r.opcode >= op::ACK {
            return None;
        }
        let reply = |session: u8, offset: u32, body: Body| FtpReply {
            target_system: sender.0,
            target_component: sender.1,
            seq: r.seq.wrapping_add(1),
            session,
            req_opcode: r.opcode,
            burst_complete: false,
            offset,
            body,
        };
        let nak = |e: u8| reply(r.session, r.offset, Body::Nak(e));
        let chunk = if r.size == 0 || usize::from(r.size) > MAX_DATA { MAX_DATA as u8 } else { r.size };
        let session_file = self.open.and_then(|(id, file)| (id == r.session).then_some(file));
        Some(match r.opcode {
            op::RESET_SESSIONS => {
                self.open = None;
                self.burst = None;
                reply(r.session, 0, Body::Empty)
            }
            op::TERMINATE_SESSION => match session_file {
                Some(_) => {
                    self.open = None;
                    self.burst = None;
                    reply(r.session, 0, Body::Empty)
                }
                None => nak(err::INVALID_SESSION),
            },
            op::OPEN_FILE_RO => match find(r.path()) {
                Some(file) => {
                    self.open = Some((r.session, file));
                    self.burst = None;
                    reply(r.session, 0, Body::Word(size_of(file)))
                }
                None => nak(err::FILE_NOT_FOUND),
            },
            op::READ_FILE | op::BURST_READ_FILE => {
                let Some(file) = session_file else { return Some(nak(err::INVALID_SESSION)) };
                let left = size_of(file).saturating_sub(r.offset);
                if left == 0 {
                    let mut eof = nak(err::EOF);
                    eof.burst_complete = r.opcode == op::BURST_READ_FILE;
                    return Some(eof);
                }
                if r.opcode == op::BURST_READ_FILE {
                    self.burst = Some(Burst {
                        to: sender,
                        session: r.session,
                        seq: r.seq.wrapping_add(1),
                        offset: r.offset,
                        chunk,
                        file,
                    });
                    return None;
                }
                let len = left.min(u32::from(chunk)) as u8;
                reply(r.session, r.offset, Body::File { file, len })
            }
            op::LIST_DIRECTORY => match r.path() {
                b"" | b"/" if (r.offset as usize) < FILES.len() => {
                    reply(r.session, r.offset, Body::Dir { first: r.offset as u8 })
                }
                b"" | b"/" => nak(err::EOF),
                _ => nak(err::FILE_NOT_FOUND),
            },
            op::CALC_FILE_CRC32 => match find(r.path()) {
                Some(file) => {
                    reply(r.session, 0, Body::Word(FILES.get(usize::from(file)).map_or(0, |f| f.crc)))
                }
                None => nak(err::FILE_NOT_FOUND),
            },
            op::CREATE_FILE..=op::RENAME => nak(err::FILE_PROTECTED),
            _ => nak(err::UNKNOWN_COMMAND),
        })
    }

    /// The next packet of a running burst (the last one has `burst_complete`), or `None`.
    pub fn next_burst(&mut self) -> Option<FtpReply> {
        let b = self.burst?;
        let left = size_of(b.file).saturating_sub(b.offset);
        let len = left.min(u32::from(b.chunk));
        let last = len == left;
        self.burst = (!last).then_some(Burst { seq: b.seq.wrapping_add(1), offset: b.offset + len, ..b });
        Some(FtpReply {
            target_system: b.to.0,
            target_component: b.to.1,
            seq: b.seq,
            session: b.session,
            req_opcode: op::BURST_READ_FILE,
            burst_complete: last,
            offset: b.offset,
            body: Body::File { file: b.file, len: len as u8 },
        })
    }

    /// A burst is running.
    pub fn bursting(&self) -> bool {
        self.burst.is_some()
    }
}

/// Size of served file `file`.
fn size_of(file: u8) -> u32 {
    FILES.get(usize::from(file)).map_or(0, |f| f.bytes.len() as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    const GCS: (u8, u8) = (255, 190);

    /// A request payload as pymavlink's `FTP_OP.pack` lays it out, to the autopilot 1/1.
    fn req(seq: u16, session: u8, opcode: u8, size: u8, offset: u32, data: &[u8]) -> FtpRequest {
        let mut p = [0u8; 254];
        p[1] = 1;
        p[2] = 1;
        p[3..5].copy_from_slice(&seq.to_le_bytes());
        p[5] = session;
        p[6] = opcode;
        p[7] = size;
        p[11..15].copy_from_slice(&offset.to_le_bytes());
        p[15..15 + data.len()].copy_from_slice(data);
        FtpRequest::parse(&p)
    }

    fn path_req(seq: u16, opcode: u8, offset: u32, path: &[u8]) -> FtpRequest {
        req(seq, 0, opcode, path.len() as u8, offset, path)
    }

    /// (opcode, size, req_opcode, burst_complete, offset, data) of a reply's message.
    fn wire(r: &FtpReply) -> (u8, u8, u8, u8, u32, Vec<u8>) {
        let m = r.data();
        let p = &m.payload;
        let size = p[4];
        let offset = u32::from_le_bytes([p[8], p[9], p[10], p[11]]);
        (p[3], size, p[5], p[6], offset, p[HDR..HDR + usize::from(size)].to_vec())
    }

    fn nak_code(r: &FtpReply) -> u8 {
        let (opcode, size, _, _, _, data) = wire(r);
        assert_eq!((opcode, size), (op::NAK, 1), "{r:?}");
        data[0]
    }

    /// Opens `name`: the session id.
    fn open(s: &mut FtpServer, name: &[u8]) -> u8 {
        let r = s.on_request(&path_req(10, op::OPEN_FILE_RO, 0, name), GCS).expect("answered");
        assert_eq!(wire(&r).0, op::ACK, "{r:?}");
        r.session
    }

    #[test]
    fn open_answers_the_size_and_a_session_and_unknown_paths_are_not_found() {
        let mut s = FtpServer::new();
        for (i, f) in FILES.iter().enumerate() {
            let name = std::format!("/{}", f.name);
            let session = 183 + i as u8;
            let open = req(7, session, op::OPEN_FILE_RO, name.len() as u8, 0, name.as_bytes());
            let r = s.on_request(&open, GCS).unwrap();
            let (opcode, size, req_op, _, _, data) = wire(&r);
            assert_eq!((opcode, size, req_op, r.seq), (op::ACK, 4, op::OPEN_FILE_RO, 8));
            assert_eq!(data, (f.bytes.len() as u32).to_le_bytes());
            assert_eq!(r.session, session, "the client's session id (MAVProxy's choice)");
            let read = s.on_request(&req(8, session, op::READ_FILE, 4, 0, &[]), GCS).unwrap();
            assert_eq!(wire(&read).5, &f.bytes[..4], "read in that session");
            assert_eq!((r.target_system, r.target_component), GCS);
        }
        // Without the leading slash and NUL-terminated (QGroundControl's older URIs) too.
        let mut name = FILES[0].name.as_bytes().to_vec();
        name.push(0);
        assert_eq!(wire(&s.on_request(&path_req(1, op::OPEN_FILE_RO, 0, &name), GCS).unwrap()).0, op::ACK);
        for missing in [&b"@PARAM/param.pck"[..], b"/", b"", b"/general.jsonx", &[b'a'; 100]] {
            let r = s.on_request(&path_req(1, op::OPEN_FILE_RO, 0, missing), GCS).unwrap();
            assert_eq!(nak_code(&r), err::FILE_NOT_FOUND, "{missing:?}");
        }
    }

    #[test]
    fn read_file_returns_the_bytes_eof_past_the_end_and_checks_the_session() {
        let mut s = FtpServer::new();
        let id = open(&mut s, b"/parameters.json");
        let bytes = FILES[1].bytes;
        let n = bytes.len() as u32;
        // A whole chunk, a short tail, and the request's size capped at 239.
        for (offset, size, want) in [(0, 80, 80), (n - 5, 80, 5), (3, 0, 239), (3, 250, 239)] {
            let r = s.on_request(&req(20, id, op::READ_FILE, size, offset, &[]), GCS).unwrap();
            let (opcode, len, req_op, _, off, data) = wire(&r);
            assert_eq!((opcode, len as usize, req_op, off), (op::ACK, want, op::READ_FILE, offset));
            assert_eq!(data, &bytes[offset as usize..offset as usize + want]);
        }
        for past in [n, n + 1, u32::MAX] {
            let r = s.on_request(&req(21, id, op::READ_FILE, 80, past, &[]), GCS).unwrap();
            assert_eq!(nak_code(&r), err::EOF);
        }
        let bad = s.on_request(&req(22, id.wrapping_add(1), op::READ_FILE, 80, 0, &[]), GCS).unwrap();
        assert_eq!(nak_code(&bad), err::INVALID_SESSION);
        // Terminated: the session is gone; terminating it again is InvalidSession.
        let t = s.on_request(&req(23, id, op::TERMINATE_SESSION, 0, 0, &[]), GCS).unwrap();
        assert_eq!(wire(&t).0, op::ACK);
        for o in [op::READ_FILE, op::BURST_READ_FILE, op::TERMINATE_SESSION] {
            let r = s.on_request(&req(24, id, o, 80, 0, &[]), GCS).unwrap();
            assert_eq!(nak_code(&r), err::INVALID_SESSION, "opcode {o}");
        }
    }

    #[test]
    fn a_burst_streams_the_file_to_its_end_with_counting_seqs() {
        let mut s = FtpServer::new();
        let id = open(&mut s, b"/parameters.json");
        let bytes = FILES[1].bytes;
        assert_eq!(s.on_request(&req(100, id, op::BURST_READ_FILE, 200, 17, &[]), GCS), None);
        let mut got = Vec::new();
        let mut seq = 101u16;
        let mut offset = 17u32;
        while let Some(r) = s.next_burst() {
            let (opcode, len, req_op, complete, off, data) = wire(&r);
            assert_eq!(
                (opcode, req_op, off, r.seq, r.session),
                (op::ACK, op::BURST_READ_FILE, offset, seq, id)
            );
            assert!(len == 200 || complete == 1, "only the last packet is short");
            got.extend_from_slice(&data);
            seq += 1;
            offset += u32::from(len);
            assert!(got.len() <= bytes.len(), "bounded");
            if complete == 1 {
                assert!(!s.bursting());
            }
        }
        assert_eq!(got, &bytes[17..]);
        // At the end (a client continuing after a full last packet): EOF with burst_complete.
        let r = s.on_request(&req(300, id, op::BURST_READ_FILE, 239, bytes.len() as u32, &[]), GCS).unwrap();
        assert_eq!(nak_code(&r), err::EOF);
        assert!(r.burst_complete);
        // A reset stops a burst; so does a new open.
        assert_eq!(s.on_request(&req(301, id, op::BURST_READ_FILE, 239, 0, &[]), GCS), None);
        assert!(s.next_burst().is_some());
        assert_eq!(wire(&s.on_request(&req(302, 0, op::RESET_SESSIONS, 0, 0, &[]), GCS).unwrap()).0, op::ACK);
        assert_eq!(s.next_burst(), None);
        let r = s.on_request(&req(303, id, op::READ_FILE, 1, 0, &[]), GCS).unwrap();
        assert_eq!(nak_code(&r), err::INVALID_SESSION, "reset closed the session");
    }

    #[test]
    fn list_directory_lists_the_files_then_eof() {
        let mut s = FtpServer::new();
        let r = s.on_request(&path_req(5, op::LIST_DIRECTORY, 0, b"/"), GCS).unwrap();
        let (opcode, _, _, _, _, data) = wire(&r);
        assert_eq!(opcode, op::ACK);
        let want: Vec<u8> = FILES
            .iter()
            .flat_map(|f| std::format!("F{}\t{}\0", f.name, f.bytes.len()).into_bytes())
            .collect();
        assert_eq!(data, want);
        let r = s.on_request(&path_req(6, op::LIST_DIRECTORY, 1, b"/"), GCS).unwrap();
        assert_eq!(wire(&r).5, std::format!("F{}\t{}\0", FILES[1].name, FILES[1].bytes.len()).into_bytes());
        let r = s.on_request(&path_req(7, op::LIST_DIRECTORY, FILES.len() as u32, b"/"), GCS).unwrap();
        assert_eq!(nak_code(&r), err::EOF);
        let r = s.on_request(&path_req(8, op::LIST_DIRECTORY, 0, b"/fs/microsd"), GCS).unwrap();
        assert_eq!(nak_code(&r), err::FILE_NOT_FOUND);
        assert_eq!(decimal(0, &mut [0; 10]), b"0");
        assert_eq!(decimal(u32::MAX, &mut [0; 10]), b"4294967295");
    }

    #[test]
    fn crc_write_ops_unknown_opcodes_and_replies() {
        let mut s = FtpServer::new();
        for f in FILES.iter() {
            let name = std::format!("/{}", f.name);
            let r = s.on_request(&path_req(1, op::CALC_FILE_CRC32, 0, name.as_bytes()), GCS).unwrap();
            assert_eq!(wire(&r).5, f.crc.to_le_bytes());
        }
        let r = s.on_request(&path_req(1, op::CALC_FILE_CRC32, 0, b"/nope"), GCS).unwrap();
        assert_eq!(nak_code(&r), err::FILE_NOT_FOUND);
        for o in op::CREATE_FILE..=op::RENAME {
            let r = s.on_request(&path_req(2, o, 0, b"/general.json"), GCS).unwrap();
            assert_eq!((nak_code(&r), r.req_opcode, r.seq), (err::FILE_PROTECTED, o, 3), "opcode {o}");
        }
        for o in [op::NONE, 16, 42, 127] {
            let r = s.on_request(&req(0xFFFF, 3, o, 0, 0, &[]), GCS).unwrap();
            assert_eq!((nak_code(&r), r.seq, r.session), (err::UNKNOWN_COMMAND, 0, 3), "opcode {o}");
        }
        for o in [op::ACK, op::NAK, 200, 255] {
            assert_eq!(s.on_request(&req(1, 0, o, 0, 0, &[]), GCS), None, "opcode {o}: not a request");
        }
        // Short and empty payloads parse (MAVLink 2 trims zeros) without a panic.
        let r = FtpRequest::parse(&[0, 1]);
        assert_eq!((r.target_system, r.seq, r.opcode, r.path()), (1, 0, 0, &b""[..]));
        let r = FtpRequest::parse(&[]);
        assert_eq!(r.target_system, 0);
        // A size larger than the data present reads what is there.
        let mut p = [0u8; 20];
        p[7] = 200;
        p[15..20].copy_from_slice(b"/abcd");
        assert_eq!(FtpRequest::parse(&p).path(), b"/abcd");
    }
}

//! ULog encoding (PX4's flight-log format, version 1), `no_std` and allocation-free: the one
//! writer of the firmware's onboard log (`firmware/src/log/logger.rs`) and the host's
//! `flight.ulg` (`host-sim/src/report/ulog.rs`). The topics of a flight and their records are
//! [`super::log_topics`].
//!
//! Layout (docs.px4.io, "ULog File Format"): header (magic `ULog\x01\x12\x35`, version 1, start
//! timestamp µs), the `B` flag bits (no compat/incompat flags, no appended data), definitions
//! (`F` formats with `timestamp` first, `I` infos, `P` float parameters), then `A`
//! subscriptions (multi id 0) and `D` data messages. Little-endian, fields packed without
//! padding. Every message is built in a [`Message`] of [`MESSAGE_CAPACITY`] bytes on the
//! caller's stack and handed to a [`ULogSink`] in one piece; a message that does not fit is
//! refused ([`TooLong`]), never truncated.
//!
//! Written by hand: crates.io has ULog readers (`ulog-rs`, `px4-ulog`, `yule_log`) but no
//! writer, and none `no_std` (the format is small). [`messages`] reads the messages back (for
//! tests and tools). May import: nothing of the crate.

use core::fmt;

/// ULog file magic (7 bytes) and the version byte.
pub const MAGIC: [u8; 8] = [0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35, 0x01];
/// Largest message (header + payload) this writer builds, bytes.
pub const MESSAGE_CAPACITY: usize = 320;
/// Largest data record (timestamp included), bytes.
pub const RECORD_CAPACITY: usize = 64;

/// A message or record longer than this writer's buffers, or a topic with an unknown type or
/// without `timestamp` first (a programming error in a topic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooLong;

impl fmt::Display for TooLong {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ULog message longer than {MESSAGE_CAPACITY} bytes or topic with a bad format")
    }
}

impl core::error::Error for TooLong {}

/// Where ULog bytes go: a log store's open log (firmware), a file (host).
pub trait ULogSink {
    /// The sink's error; a refused message ([`TooLong`]) converts into it.
    type Error: From<TooLong>;
    /// Appends `bytes` (one whole message, or the 16-byte file header).
    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error>;
}

/// One topic: its name and fields as `(type, name)`; the first field is
/// `("uint64_t", "timestamp")`. Types: `uint8_t int8_t uint16_t int16_t uint32_t int32_t
/// uint64_t int64_t float double bool char`, each optionally as an array `T[N]`.
#[derive(Clone, Copy, Debug)]
pub struct Topic {
    /// uORB-style name, e.g. `vehicle_local_position`.
    pub name: &'static str,
    /// `(type, field)` pairs, `timestamp` first.
    pub fields: &'static [(&'static str, &'static str)],
}

fn type_size(t: &str) -> Option<usize> {
    let (base, n) = match t.split_once('[') {
        Some((b, rest)) => (b, rest.strip_suffix(']')?.parse::<usize>().ok()?),
        None => (t, 1),
    };
    let s: usize = match base {
        "uint8_t" | "int8_t" | "bool" | "char" => 1,
        "uint16_t" | "int16_t" => 2,
        "uint32_t" | "int32_t" | "float" => 4,
        "uint64_t" | "int64_t" | "double" => 8,
        _ => return None,
    };
    s.checked_mul(n)
}

impl Topic {
    /// Bytes of one record; `None` for an unknown type or when `timestamp` is not first.
    pub fn size(&self) -> Option<usize> {
        if self.fields.first() != Some(&("uint64_t", "timestamp")) {
            return None;
        }
        self.fields.iter().try_fold(0usize, |acc, (t, _)| acc.checked_add(type_size(t)?))
    }
}

/// One ULog message being built: 2-byte size, 1-byte type, payload.
pub struct Message {
    buf: [u8; MESSAGE_CAPACITY],
    len: usize,
    overflow: bool,
}

impl Message {
    /// An empty message of type `ty` (`b'F'`, `b'I'`, …).
    pub fn new(ty: u8) -> Self {
        let mut buf = [0u8; MESSAGE_CAPACITY];
        buf[2] = ty;
        Self { buf, len: 3, overflow: false }
    }

    /// Appends bytes (an overflow is remembered and makes [`Message::bytes`] fail).
    pub fn push(&mut self, b: &[u8]) -> &mut Self {
        match self.buf.get_mut(self.len..self.len + b.len()) {
            Some(dst) => {
                dst.copy_from_slice(b);
                self.len += b.len();
            }
            None => self.overflow = true,
        }
        self
    }

    /// Appends a string's bytes.
    pub fn push_str(&mut self, s: &str) -> &mut Self {
        self.push(s.as_bytes())
    }

    /// Appends `v` in decimal ASCII.
    pub fn push_decimal(&mut self, mut v: u32) -> &mut Self {
        let mut digits = [0u8; 10];
        let mut n = 0;
        // u32::MAX has 10 digits: the loop ends by `v == 0` before `get_mut` fails.
        while let Some(d) = digits.get_mut(n) {
            *d = b'0' + (v % 10) as u8;
            n += 1;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        let digits = digits.get_mut(..n).unwrap_or(&mut []);
        digits.reverse();
        self.push(digits)
    }

    /// The finished message (size field filled in).
    pub fn bytes(&mut self) -> Result<&[u8], TooLong> {
        let payload = self.len - 3;
        if self.overflow || payload > usize::from(u16::MAX) {
            return Err(TooLong);
        }
        self.buf[..2].copy_from_slice(&(payload as u16).to_le_bytes());
        Ok(&self.buf[..self.len])
    }

    /// Writes the finished message to `sink`.
    pub fn write_to<S: ULogSink>(&mut self, sink: &mut S) -> Result<(), S::Error> {
        let b = self.bytes()?;
        sink.write(b)
    }
}

/// One data record, built field by field in the topic's order (little-endian).
#[derive(Clone, Copy)]
pub struct Record {
    buf: [u8; RECORD_CAPACITY],
    len: usize,
    overflow: bool,
}

impl Record {
    /// A record starting with its timestamp (µs).
    pub fn at(timestamp_us: u64) -> Self {
        let mut r = Self { buf: [0; RECORD_CAPACITY], len: 0, overflow: false };
        r.push(&timestamp_us.to_le_bytes());
        r
    }
    fn push(&mut self, b: &[u8]) {
        match self.buf.get_mut(self.len..self.len + b.len()) {
            Some(dst) => {
                dst.copy_from_slice(b);
                self.len += b.len();
            }
            None => self.overflow = true,
        }
    }
    /// `float` fields.
    pub fn f32s(mut self, v: &[f32]) -> Self {
        for x in v {
            self.push(&x.to_le_bytes());
        }
        self
    }
    /// A `uint8_t` / `bool` field.
    pub fn u8(mut self, v: u8) -> Self {
        self.push(&[v]);
        self
    }
    /// An `int32_t` field.
    pub fn i32(mut self, v: i32) -> Self {
        self.push(&v.to_le_bytes());
        self
    }
    /// A `uint64_t` field.
    pub fn u64(mut self, v: u64) -> Self {
        self.push(&v.to_le_bytes());
        self
    }
    /// The record's bytes; `None` after an overflow.
    pub fn bytes(&self) -> Option<&[u8]> {
        (!self.overflow).then(|| &self.buf[..self.len])
    }
}

/// File header (magic, version, start time `t0_us`) and the `B` flag bits.
pub fn write_header<S: ULogSink>(sink: &mut S, t0_us: u64) -> Result<(), S::Error> {
    let mut h = [0u8; 16];
    h[..8].copy_from_slice(&MAGIC);
    h[8..].copy_from_slice(&t0_us.to_le_bytes());
    sink.write(&h)?;
    Message::new(b'B').push(&[0u8; 40]).write_to(sink)
}

/// `F` message of `topic` (`name:type field;…`).
pub fn write_format<S: ULogSink>(sink: &mut S, topic: &Topic) -> Result<(), S::Error> {
    if topic.size().is_none() {
        return Err(TooLong.into());
    }
    let mut m = Message::new(b'F');
    m.push_str(topic.name).push(b":");
    for (t, n) in topic.fields {
        m.push_str(t).push(b" ").push_str(n).push(b";");
    }
    m.write_to(sink)
}

fn key_value(ty: u8, key_type: &str, key_len: Option<u32>, key: &str, value: &[u8]) -> Message {
    let mut m = Message::new(ty);
    let mut k = Message::new(0);
    k.push_str(key_type);
    if let Some(n) = key_len {
        k.push(b"[").push_decimal(n).push(b"]");
    }
    k.push(b" ").push_str(key);
    let key_bytes = k.len - 3;
    if k.overflow || key_bytes > 255 {
        m.overflow = true;
        return m;
    }
    m.push(&[key_bytes as u8]).push(&k.buf[3..k.len]).push(value);
    m
}

/// `I` message: string info `key` (e.g. `sys_name`).
pub fn write_info<S: ULogSink>(sink: &mut S, key: &str, value: &str) -> Result<(), S::Error> {
    let n = u32::try_from(value.len()).map_err(|_| TooLong)?;
    key_value(b'I', "char", Some(n), key, value.as_bytes()).write_to(sink)
}

/// `I` message: `uint32_t` info `key`.
pub fn write_info_u32<S: ULogSink>(sink: &mut S, key: &str, value: u32) -> Result<(), S::Error> {
    key_value(b'I', "uint32_t", None, key, &value.to_le_bytes()).write_to(sink)
}

/// `P` message: a `float` parameter.
pub fn write_param_f32<S: ULogSink>(sink: &mut S, name: &str, value: f32) -> Result<(), S::Error> {
    key_value(b'P', "float", None, name, &value.to_le_bytes()).write_to(sink)
}

/// `A` message: subscription `msg_id` of topic `name` (multi id 0).
pub fn write_subscription<S: ULogSink>(sink: &mut S, msg_id: u16, name: &str) -> Result<(), S::Error> {
    Message::new(b'A').push(&[0]).push(&msg_id.to_le_bytes()).push_str(name).write_to(sink)
}

/// `D` message of subscription `msg_id` with `record` (which must match the topic's format).
pub fn write_data<S: ULogSink>(sink: &mut S, msg_id: u16, record: &Record) -> Result<(), S::Error> {
    let b = record.bytes().ok_or(TooLong)?;
    Message::new(b'D').push(&msg_id.to_le_bytes()).push(b).write_to(sink)
}

/// `L` message: a logged string (`log_level` ASCII '0'..'7' as in syslog, timestamp µs).
pub fn write_logging<S: ULogSink>(sink: &mut S, level: u8, t_us: u64, text: &str) -> Result<(), S::Error> {
    Message::new(b'L').push(&[level]).push(&t_us.to_le_bytes()).push_str(text).write_to(sink)
}

/// The messages of a ULog file, `(type, payload)` in file order ([`messages`]); ends at the
/// end of the bytes or at a truncated message.
pub struct Messages<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Messages<'a> {
    type Item = (u8, &'a [u8]);
    fn next(&mut self) -> Option<Self::Item> {
        let [a, b, ty, rest @ ..] = self.rest else { return None };
        let n = usize::from(u16::from_le_bytes([*a, *b]));
        let payload = rest.get(..n)?;
        self.rest = rest.get(n..).unwrap_or(&[]);
        Some((*ty, payload))
    }
}

/// The messages after the 16-byte header of `bytes`; `None` when the magic is not ULog's.
pub fn messages(bytes: &[u8]) -> Option<Messages<'_>> {
    if bytes.get(..8) != Some(&MAGIC[..]) {
        return None;
    }
    Some(Messages { rest: bytes.get(16..)? })
}

#[cfg(test)]
pub(crate) mod tests {
    extern crate std;
    use super::*;
    use std::string::String;
    use std::vec::Vec;

    /// A sink into a vector (refused messages convert into [`TooLong`]).
    pub(crate) struct VecSink(pub(crate) Vec<u8>);
    impl ULogSink for VecSink {
        type Error = TooLong;
        fn write(&mut self, bytes: &[u8]) -> Result<(), TooLong> {
            self.0.extend_from_slice(bytes);
            Ok(())
        }
    }

    /// (type, payload) of every message after the header; asserts they tile the file.
    pub(crate) fn parse(bytes: &[u8]) -> Vec<(u8, Vec<u8>)> {
        let msgs: Vec<(u8, Vec<u8>)> =
            messages(bytes).expect("ULog magic").map(|(t, p)| (t, p.to_vec())).collect();
        let total: usize = msgs.iter().map(|m| 3 + m.1.len()).sum();
        assert_eq!(16 + total, bytes.len(), "messages tile the file");
        msgs
    }

    #[test]
    fn layout_follows_the_spec() {
        let t =
            Topic { name: "t", fields: &[("uint64_t", "timestamp"), ("float[2]", "v"), ("uint8_t", "k")] };
        assert_eq!(t.size(), Some(17));
        let mut s = VecSink(Vec::new());
        write_header(&mut s, 7).unwrap();
        write_format(&mut s, &t).unwrap();
        write_info(&mut s, "sys_name", "X").unwrap();
        write_param_f32(&mut s, "CBF_MU", 1.5).unwrap();
        write_subscription(&mut s, 0, "t").unwrap();
        write_data(&mut s, 0, &Record::at(9).f32s(&[1.0, 2.0]).u8(3)).unwrap();
        let bytes = s.0;
        assert_eq!(u64::from_le_bytes(bytes[8..16].try_into().unwrap()), 7);
        let msgs = parse(&bytes);
        let types: Vec<u8> = msgs.iter().map(|m| m.0).collect();
        assert_eq!(types, b"BFIPAD".to_vec());
        assert_eq!(msgs[0].1.len(), 40);
        assert_eq!(
            String::from_utf8(msgs[1].1.clone()).unwrap(),
            "t:uint64_t timestamp;float[2] v;uint8_t k;"
        );
        assert_eq!(msgs[2].1, [b"\x10char[1] sys_nameX".as_slice()].concat());
        assert_eq!(&msgs[3].1[..13], b"\x0cfloat CBF_MU");
        assert_eq!(msgs[4].1, [0u8, 0, 0, b't']);
        let d = &msgs[5].1;
        assert_eq!(d.len(), 2 + 17);
        assert_eq!(f32::from_le_bytes(d[14..18].try_into().unwrap()), 2.0);
        assert_eq!(d[18], 3);
        // A truncated file ends the messages; a foreign magic is refused.
        assert_eq!(messages(&bytes[..bytes.len() - 1]).unwrap().count(), 5);
        assert!(messages(b"NotULog\x01").is_none());
    }

    #[test]
    fn oversized_messages_and_bad_topics_are_refused() {
        let mut s = VecSink(Vec::new());
        let long = "x".repeat(400);
        assert_eq!(write_info(&mut s, "k", &long), Err(TooLong));
        assert_eq!(write_info(&mut s, &"k".repeat(300), "v"), Err(TooLong));
        assert_eq!(write_format(&mut s, &Topic { name: "a", fields: &[("float", "x")] }), Err(TooLong));
        let bad = Topic { name: "b", fields: &[("uint64_t", "timestamp"), ("quat", "q")] };
        assert_eq!(write_format(&mut s, &bad), Err(TooLong));
        let r = Record::at(0).f32s(&[0.0; 20]);
        assert!(r.bytes().is_none());
        assert_eq!(write_data(&mut s, 0, &r), Err(TooLong));
        assert!(s.0.is_empty(), "nothing written for refused messages");
        let mut m = Message::new(b'I');
        m.push_decimal(0).push(b",").push_decimal(4_294_967_295);
        assert_eq!(&m.bytes().unwrap()[3..], b"0,4294967295");
    }
}

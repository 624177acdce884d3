//! One parameter-set record of the store ([`super::ParamStore`]): its fixed layout, its
//! words and its CRC. Pure functions, no flash access.
//!
//! Layout, little-endian 32-bit words, [`RECORD_LEN`] bytes at a fixed position of a slot:
//!
//! | word | content |
//! |---|---|
//! | 0 | [`MAGIC`] (the store's format) |
//! | 1 | sequence number (the newest valid record wins; one more than any valid record's) |
//! | 2 | layout version ([`super::LAYOUT_VERSION`] of the firmware that wrote it) |
//! | 3 | number of values ([`COUNT`]) |
//! | 4 .. 4 + COUNT | the values, `f32` bits, in table order |
//! | then up to the last word | `0xFFFF_FFFF` (erased, never written) |
//! | last ([`CRC_OFFSET`]) | CRC-32 (IEEE 802.3, as zlib's `crc32`) of every byte before it |
//!
//! The size is fixed (not `COUNT`-dependent) so that a record of a firmware with another
//! table still sits where this firmware looks, is recognised (magic, CRC) and reported as
//! foreign. May import `parapet_core`'s table size only.
//!
//! The CRC-32 is written here (a 16-entry nibble table, 64 B) rather than taken from
//! `crc-any` (already linked for the log card's CRC-16): its `CRCu32::crc32()` links a
//! 256-entry table, 1 KiB of the F405's flash budget (firmware/README.md § Budgets), for a
//! CRC computed once per 512-byte record. Checked against zlib's value in `crc32_is_zlibs`.

use parapet_core::params::COUNT;

/// Bytes of a record; a slot holds `slot bytes / RECORD_LEN` positions.
pub const RECORD_LEN: usize = 512;
/// Bytes read or written at a time: a multiple of the flash word of every board (F405 4,
/// H743 32, the RAM flash 4) and a divisor of [`RECORD_LEN`].
pub const CHUNK: usize = 64;
/// Words before the values: magic, sequence number, layout version, value count.
const HEADER_WORDS: usize = 4;
/// Byte offset of the CRC, the record's last word.
pub const CRC_OFFSET: usize = RECORD_LEN - 4;
/// First word of every record: "PPS" and the format number 2 (format 1 was the
/// sequential-storage map before 2026-12-03).
pub const MAGIC: u32 = u32::from_le_bytes(*b"PPS2");

const _: () = assert!(4 * (HEADER_WORDS + COUNT) <= CRC_OFFSET, "the table outgrew RECORD_LEN");
const _: () = assert!(RECORD_LEN.is_multiple_of(CHUNK) && CHUNK.is_multiple_of(4));

/// Word `i` of the record with sequence number `seq`, layout `version` and the values
/// `value(k)`; after the values `0xFFFF_FFFF` (erased), also at [`CRC_OFFSET`], whose word
/// [`chunk`] replaces with the CRC.
pub fn word(i: usize, seq: u32, version: u32, value: &impl Fn(usize) -> u32) -> u32 {
    match i {
        0 => MAGIC,
        1 => seq,
        2 => version,
        3 => COUNT as u32,
        _ if i < HEADER_WORDS + COUNT => value(i - HEADER_WORDS),
        _ => u32::MAX,
    }
}

/// Byte offset of value `k` in a record.
pub const fn value_offset(k: usize) -> usize {
    4 * (HEADER_WORDS + k)
}

/// CRC-32 of every 4-bit value (reflected polynomial 0xEDB88320; zlib's nibble table).
const NIBBLE: [u32; 16] = [
    0x0000_0000,
    0x1db7_1064,
    0x3b6e_20c8,
    0x26d9_30ac,
    0x76dc_4190,
    0x6b6b_51f4,
    0x4db2_6158,
    0x5005_713c,
    0xedb8_8320,
    0xf00f_9344,
    0xd6d6_a3e8,
    0xcb61_b38c,
    0x9b64_c2b0,
    0x86d3_d2d4,
    0xa00a_e278,
    0xbdbd_f21c,
];

/// CRC-32 (reflected polynomial 0xEDB88320) of `bytes` continued from `crc` (start with
/// `!0`, finish with `!`); a 16-entry table, two look-ups per byte.
pub fn crc32_update(mut crc: u32, bytes: &[u8]) -> u32 {
    let t = |c: u32| NIBBLE.get((c & 15) as usize).copied().unwrap_or(0);
    for &b in bytes {
        crc ^= u32::from(b);
        crc = (crc >> 4) ^ t(crc);
        crc = (crc >> 4) ^ t(crc);
    }
    crc
}

/// The CRC word of the record [`word`] describes.
pub fn crc(seq: u32, version: u32, value: &impl Fn(usize) -> u32) -> u32 {
    let mut crc = !0;
    for i in 0..CRC_OFFSET / 4 {
        crc = crc32_update(crc, &word(i, seq, version, value).to_le_bytes());
    }
    !crc
}

/// The bytes `c·CHUNK .. (c + 1)·CHUNK` of that record, CRC included (`crc` from [`crc`]).
pub fn chunk(c: usize, seq: u32, version: u32, value: &impl Fn(usize) -> u32, crc: u32) -> [u8; CHUNK] {
    let mut out = [0u8; CHUNK];
    for (j, b) in out.chunks_exact_mut(4).enumerate() {
        let i = (c * CHUNK) / 4 + j;
        let w = if 4 * i == CRC_OFFSET { crc } else { word(i, seq, version, value) };
        b.copy_from_slice(&w.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_zlibs() {
        // The CRC-32 check value (zlib.crc32(b"123456789")).
        assert_eq!(!crc32_update(!0, b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn chunks_are_the_words_and_the_crc_last() {
        let value = |k: usize| 1000 + k as u32;
        let crc = crc(7, 0xABCD, &value);
        let bytes: std::vec::Vec<u8> =
            (0..RECORD_LEN / CHUNK).flat_map(|c| chunk(c, 7, 0xABCD, &value, crc)).collect();
        let w = |i: usize| {
            u32::from_le_bytes([bytes[4 * i], bytes[4 * i + 1], bytes[4 * i + 2], bytes[4 * i + 3]])
        };
        assert_eq!((w(0), w(1), w(2), w(3)), (MAGIC, 7, 0xABCD, COUNT as u32));
        assert_eq!(w(value_offset(5) / 4), 1005);
        assert_eq!(w(CRC_OFFSET / 4 - 1), u32::MAX);
        assert_eq!(w(CRC_OFFSET / 4), !crc32_update(!0, &bytes[..CRC_OFFSET]));
    }
}

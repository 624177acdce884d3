// The MAVLink CRC32 (https://mavlink.io/en/guide/crc.md: reflected polynomial 0xEDB88320,
// initial value 0, no final XOR; not zlib's). One definition, `include!`d by `firmware/build.rs`
// (the files' CRCs at build time) and by the tests of `firmware/src/link/metadata.rs`.

/// MAVLink CRC32 of `bytes`.
pub fn mavlink_crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    crc
}

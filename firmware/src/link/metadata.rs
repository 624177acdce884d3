//! Component metadata (<https://mavlink.io/en/services/component_information.html>): the files
//! the vehicle serves by MAVLink FTP ([`FILES`], compiled into flash, served by
//! [`crate::link::ftp`]) and the COMPONENT_METADATA message (397) that points a ground station
//! to them.
//!
//! - `general.json` (COMP_METADATA_TYPE_GENERAL, written by `firmware/build.rs`): `version` 1,
//!   vendor/model/firmware names and `metadataTypes` with one entry: type 1 (PARAMETER), `uri`
//!   [`PARAMETERS_URI`] and its `fileCrc`.
//! - `parameters.json` (COMP_METADATA_TYPE_PARAMETER, PX4/QGroundControl's schema):
//!   `firmware/metadata/parameters.json`, the output of `cargo xtask params --firmware` from the
//!   parameter table (`parapet_core::params::TABLE`); the xtask test
//!   `the_firmwares_parameter_metadata_is_not_stale` fails when it no longer matches the table.
//!
//! CRCs are the MAVLink CRC32 (`firmware/metadata/crc32.rs`), computed at build time. The files
//! are not xz-compressed: ~24 KB of flash on a 1 MB part, and no xz encoder crate is needed.
//!
//! May import: the dialect.

use crate::link::dialect::COMPONENT_METADATA_DATA;

include!(concat!(env!("OUT_DIR"), "/metadata.rs"));

/// MAVLink message id of COMPONENT_METADATA (MAV_CMD_REQUEST_MESSAGE param1).
pub const COMPONENT_METADATA_ID: f32 = 397.0;
/// COMPONENT_METADATA's `uri`: `general.json` on this component (the autopilot, 1), by FTP.
pub const GENERAL_URI: &str = "mftp://[;comp=1]/general.json";

/// A file served by MAVLink FTP.
#[derive(Debug)]
pub struct File {
    /// Name in the root directory.
    pub name: &'static str,
    /// Contents.
    pub bytes: &'static [u8],
    /// MAVLink CRC32 of `bytes`.
    pub crc: u32,
}

/// The served files (FTP root directory, in listing order).
pub static FILES: [File; 2] = [
    File { name: "general.json", bytes: GENERAL_JSON, crc: GENERAL_CRC },
    File { name: "parameters.json", bytes: PARAMETERS_JSON, crc: PARAMETERS_CRC },
];

/// COMPONENT_METADATA at firmware time `time_boot_ms`.
pub fn component_metadata(time_boot_ms: u32) -> COMPONENT_METADATA_DATA {
    COMPONENT_METADATA_DATA {
        time_boot_ms,
        file_crc: GENERAL_CRC,
        uri: crate::link::dialect::name(GENERAL_URI),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    include!("../../metadata/crc32.rs");

    /// The CRCs are those of the bytes served; the MAVLink CRC32 is not zlib's (check value of
    /// "123456789": 0x2DFD2D88 with initial value 0 and no final XOR, zlib's 0xCBF43926).
    #[test]
    fn crcs_match_the_served_bytes() {
        assert_eq!(mavlink_crc32(b"123456789"), 0x2DFD_2D88);
        for f in &FILES {
            assert_eq!(f.crc, mavlink_crc32(f.bytes), "{}", f.name);
        }
        let m = component_metadata(1234);
        assert_eq!((m.time_boot_ms, m.file_crc), (1234, GENERAL_CRC));
        assert_eq!(m.uri.to_str().unwrap_or(""), GENERAL_URI);
    }

    /// general.json points to parameters.json by an mftp URI on this component with its CRC, in
    /// the COMP_METADATA_TYPE_GENERAL schema QGroundControl reads (version 1, metadataTypes).
    #[test]
    fn general_json_points_to_the_parameter_metadata() {
        let g = core::str::from_utf8(GENERAL_JSON).unwrap();
        assert!(g.starts_with("{\"version\":1,"), "{g}");
        let entry = std::format!(
            "\"metadataTypes\":[{{\"type\":1,\"uri\":\"{PARAMETERS_URI}\",\"fileCrc\":{PARAMETERS_CRC}}}]"
        );
        assert!(g.contains(&entry), "{g}");
        assert_eq!(PARAMETERS_URI, "mftp://[;comp=1]/parameters.json");
        let p = core::str::from_utf8(PARAMETERS_JSON).unwrap();
        assert!(p.starts_with("{\"parameters\":[") || p.starts_with("{\"version\":1"), "{}", &p[..40]);
        for param in &parapet_core::params::TABLE {
            assert!(p.contains(&std::format!("\"name\":\"{}\"", param.name)), "{}", param.name);
        }
    }
}

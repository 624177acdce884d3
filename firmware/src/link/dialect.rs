//! The firmware's MAVLink message set: Rust types generated at build time (`build.rs`,
//! `mavlink-bindgen`) from `firmware/mavlink/parapet.xml`, the messages the firmware speaks cut
//! verbatim out of the `ardupilotmega` dialect that ground stations use (regenerate the XML
//! with `firmware/mavlink/extract.py`). Same message ids, CRC_EXTRA bytes and wire layout as
//! the full dialect (`firmware/tests/dialect.rs` compares them with the `mavlink` crate's), with
//! the MAVLink 2 extension fields on every target.
//!
//! The generated serialisers hold a `panic!` for a buffer shorter than the message (the lints
//! are allowed on the generated module): the firmware serialises only into
//! `MAVLinkV2MessageRaw`'s 255-byte payload, which every message fits, as it did with
//! `mavlink`'s own generated code.
//!
//! Why not `mavlink`'s `dialect-ardupilotmega`: its `MavMessage` covers ~300 messages and its
//! tables and enum conversions cost flash on the F405; a message listed here but not used costs
//! nothing. Imports nothing but `mavlink_core`, `bitflags` and `num_traits` (from the generated
//! code). Also the one text-field helper every message builder uses ([`name`]), here so that
//! the modules that build messages need nothing above the dialect.

include!(concat!(env!("OUT_DIR"), "/mod.rs"));

pub use parapet::*;

/// A NUL-padded MAVLink name/text field from `s` (truncated to `N` bytes).
pub fn name<const N: usize>(s: &str) -> mavlink_core::types::CharArray<N> {
    let mut b = [0u8; N];
    for (d, c) in b.iter_mut().zip(s.bytes()) {
        *d = c;
    }
    b.into()
}

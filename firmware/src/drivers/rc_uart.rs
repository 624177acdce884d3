//! RC receiver on a UART: the line settings of each protocol and the byte-chunk → [`RcFrame`]
//! step of the receiver task. Hardware-independent: the board opens the UART with
//! [`RcProtocol::line`] (`board::f405`), its task reads chunks (DMA ring buffer, returns on an
//! idle line, so one chunk ≈ one frame), stamps them with the controller clock and hands them
//! to [`RcPort::on_bytes`]; each decoded frame goes to the outer stage, which maps it with the
//! live `RC_*` parameters (`parapet_core::rc::map::RcFrame::input`).
//!
//! | protocol | line | receivers |
//! |---|---|---|
//! | CRSF | 420 000 Bd, 8N1, not inverted | ExpressLRS, TBS Crossfire / Tracer |
//! | SBUS | 100 000 Bd, 8E2, **inverted** (the MATEKF405's SBUS pad has a hardware inverter in front of UART2 RX; the F405's USART cannot invert) | Futaba, FrSky, most SBUS receivers |
//!
//! The chunk timestamp is what the decoders' gap rules use (CRSF 5 ms, SBUS 3 ms): a chunk read
//! late by the task still carries the time it was read, never an earlier one, so a frame is
//! never joined across a real gap; a frame split over two reads more than 3 ms apart (SBUS) is
//! dropped and the next one decodes. Bounded: work per byte is the decoders' bound. No
//! allocation, no panics.
//!
//! May import: `parapet_core::rc`.

use parapet_core::rc::crsf::CrsfStats;
use parapet_core::rc::map::{CrsfReceiver, RcFrame, SbusReceiver};
use parapet_core::rc::sbus::SbusStats;

/// CRSF baud rate.
pub const CRSF_BAUD: u32 = 420_000;
/// SBUS baud rate.
pub const SBUS_BAUD: u32 = 100_000;
/// DMA ring buffer of a receiver UART, bytes (≥ 2 frames of either protocol; the task drains
/// it at least every frame).
pub const RC_RX_RING: usize = 128;

/// Which protocol a receiver UART speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RcProtocol {
    /// CRSF (ExpressLRS / Crossfire).
    Crsf,
    /// SBUS.
    Sbus,
}

/// Line settings of a protocol (the board turns them into its UART configuration).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineSettings {
    /// Baud rate.
    pub baud: u32,
    /// Even parity (else none); 8 data bits either way.
    pub even_parity: bool,
    /// Two stop bits (else one).
    pub two_stop_bits: bool,
    /// The signal is inverted on the wire (the board must invert it, in hardware on the F405).
    pub inverted: bool,
}

impl RcProtocol {
    /// The protocol's line (see the module docs).
    pub const fn line(self) -> LineSettings {
        match self {
            RcProtocol::Crsf => {
                LineSettings { baud: CRSF_BAUD, even_parity: false, two_stop_bits: false, inverted: false }
            }
            RcProtocol::Sbus => {
                LineSettings { baud: SBUS_BAUD, even_parity: true, two_stop_bits: true, inverted: true }
            }
        }
    }
}

/// Decoder counters of a port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortStats {
    /// CRSF decoder counters.
    Crsf(CrsfStats),
    /// SBUS decoder counters.
    Sbus(SbusStats),
}

/// One receiver UART's decoding state.
#[derive(Clone, Debug)]
pub enum RcPort {
    /// A CRSF receiver.
    Crsf(CrsfReceiver),
    /// An SBUS receiver.
    Sbus(SbusReceiver),
}

impl RcPort {
    /// A port for `protocol`, nothing received.
    pub fn new(protocol: RcProtocol) -> Self {
        match protocol {
            RcProtocol::Crsf => RcPort::Crsf(CrsfReceiver::default()),
            RcProtocol::Sbus => RcPort::Sbus(SbusReceiver::default()),
        }
    }

    /// A chunk of bytes read at `now_us`; `f` gets every frame it completes.
    pub fn on_bytes(&mut self, bytes: &[u8], now_us: u64, f: impl FnMut(RcFrame)) {
        match self {
            RcPort::Crsf(r) => r.push_frames(bytes, now_us, f),
            RcPort::Sbus(r) => r.push_frames(bytes, now_us, f),
        }
    }

    /// Decoder counters.
    pub fn stats(&self) -> PortStats {
        match self {
            RcPort::Crsf(r) => PortStats::Crsf(r.decoder.stats()),
            RcPort::Sbus(r) => PortStats::Sbus(r.decoder.stats()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parapet_core::rc::map::RcParams;
    use parapet_core::rc::{crsf, sbus, RcSource};

    #[test]
    fn line_settings() {
        assert_eq!(RcProtocol::Crsf.line().baud, 420_000);
        let s = RcProtocol::Sbus.line();
        assert!(s.baud == 100_000 && s.even_parity && s.two_stop_bits && s.inverted);
    }

    #[test]
    fn chunks_become_frames_mapped_with_the_live_parameters() {
        let mut port = RcPort::new(RcProtocol::Crsf);
        let mut got = std::vec::Vec::new();
        let f = crsf::encode_channels(&[1811; 16]);
        port.on_bytes(&f[..7], 100, |fr| got.push(fr));
        port.on_bytes(&f[7..], 150, |fr| got.push(fr));
        assert_eq!(got.len(), 1);
        assert_eq!((got[0].t_us, got[0].source), (150, RcSource::Crsf));
        let i = got[0].input(&RcParams::default());
        assert_eq!((i.roll, i.throttle, i.arm), (1.0, 1.0, true));
        // Remapped roll on channel 2 (all channels equal here) still full right.
        assert_eq!(got[0].input(&RcParams { map_roll: 2, ..RcParams::default() }).roll, 1.0);
        let mut port = RcPort::new(RcProtocol::Sbus);
        let mut n = 0;
        port.on_bytes(&sbus::encode(&[1024; 16], sbus::FLAG_FAILSAFE, 0), 0, |fr| {
            assert!(fr.raw.failsafe && fr.link_quality == 0);
            n += 1;
        });
        assert_eq!(n, 1);
        assert!(matches!(port.stats(), PortStats::Sbus(s) if s.failsafe_flags == 1));
    }
}

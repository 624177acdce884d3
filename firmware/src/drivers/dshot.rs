//! DShot600 frame encoding (hardware-independent part of the motor driver).
//!
//! A DShot frame is 16 bits, MSB first: 11-bit value, 1 telemetry-request bit, 4-bit CRC
//! (`(v ^ v>>4 ^ v>>8) & 0xF` of the 12 leading bits). Value 0 = motor stop (disarmed), 1..47 =
//! special commands (unused here), 48..2047 = throttle. On the wire each bit is one PWM period of
//! the timer (DShot600: 1.667 µs); a `1` is high for 3/4 of the period, a `0` for 3/8. The timer
//! streams one compare value per bit and channel by DMA burst; two trailing zero slots keep the
//! line low between frames.

/// Lowest DShot throttle value.
pub const THROTTLE_MIN: u16 = 48;
/// Highest DShot throttle value.
pub const THROTTLE_MAX: u16 = 2047;
/// Bits per frame.
pub const FRAME_BITS: usize = 16;
/// Compare slots per channel: 16 bits + 2 idle slots.
pub const SLOTS: usize = FRAME_BITS + 2;
/// Motor channels.
pub const CHANNELS: usize = 4;
/// DMA burst buffer length (slots × channels, row-major: one row per bit, one column per channel).
pub const BURST_LEN: usize = SLOTS * CHANNELS;
/// DShot600 bit rate, bit/s.
pub const BITRATE_HZ: u32 = 600_000;

/// DShot value for a normalised throttle: disarmed → 0 (stop); armed → 48..2047 linearly over
/// 0..1 (clamped; a non-finite throttle → 0, motor stop).
pub fn throttle_to_value(throttle: f32, armed: bool) -> u16 {
    if !armed || !throttle.is_finite() {
        return 0;
    }
    let t = throttle.clamp(0.0, 1.0);
    let span = f32::from(THROTTLE_MAX - THROTTLE_MIN);
    THROTTLE_MIN + libm::roundf(t * span) as u16
}

/// The four motors' frames (no telemetry request) for normalised throttles, [`throttle_to_value`]
/// each.
pub fn frames(throttle: [f32; CHANNELS], armed: bool) -> [u16; CHANNELS] {
    throttle.map(|t| frame(throttle_to_value(t, armed), false))
}

/// The 16-bit frame for `value` (0..2047) with the telemetry bit `telemetry`.
pub fn frame(value: u16, telemetry: bool) -> u16 {
    let v = ((value & 0x07FF) << 1) | u16::from(telemetry);
    let crc = (v ^ (v >> 4) ^ (v >> 8)) & 0x0F;
    (v << 4) | crc
}

/// Fills the DMA burst buffer for four frames with the timer's `period` (max compare value + 1).
pub fn fill_burst(frames: [u16; CHANNELS], period: u16, out: &mut [u16; BURST_LEN]) {
    let one = ((u32::from(period) * 3) / 4) as u16;
    let zero = ((u32::from(period) * 3) / 8) as u16;
    for (bit, row) in out.chunks_exact_mut(CHANNELS).enumerate() {
        for (ch, slot) in row.iter_mut().enumerate() {
            *slot = if bit < FRAME_BITS {
                if frames[ch] & (0x8000 >> bit) != 0 {
                    one
                } else {
                    zero
                }
            } else {
                0
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values() {
        assert_eq!(throttle_to_value(0.5, false), 0);
        assert_eq!(throttle_to_value(0.0, true), 48);
        assert_eq!(throttle_to_value(1.0, true), 2047);
        assert_eq!(throttle_to_value(2.0, true), 2047);
        assert_eq!(throttle_to_value(f32::NAN, true), 0);
        assert_eq!(throttle_to_value(0.5, true), 48 + 1000);
    }

    #[test]
    fn crc_matches_reference_frames() {
        // Independent reference (computed by hand from the DShot spec): value 1046 → 0x82C6.
        assert_eq!(frame(1046, false), 0x82C6);
        // Motor stop is all zeros including the CRC.
        assert_eq!(frame(0, false), 0);
        // Telemetry bit sits just above the CRC.
        assert_eq!(frame(0, true) & 0x10, 0x10);
    }

    #[test]
    fn frames_per_motor_and_disarmed_stop() {
        // Value 1046 (throttle ≈ 0.4995) → 0x82C6, as above; disarmed → all motor-stop frames.
        let t = (1046.0 - 48.0) / 1999.0;
        assert_eq!(frames([t, 0.0, 1.0, f32::NAN], true), [0x82C6, frame(48, false), frame(2047, false), 0]);
        assert_eq!(frames([t, 0.0, 1.0, 0.5], false), [0; CHANNELS]);
    }

    #[test]
    fn burst_layout() {
        let mut buf = [0u16; BURST_LEN];
        fill_burst([0x8000, 0x0001, 0xFFFF, 0], 280, &mut buf);
        // Row 0 (MSB): ch0 one, ch1 zero, ch2 one, ch3 zero.
        assert_eq!(&buf[0..4], &[210, 105, 210, 105]);
        // Row 15 (LSB): ch1 one.
        assert_eq!(&buf[60..64], &[105, 210, 210, 105]);
        // Idle rows.
        assert!(buf[64..].iter().all(|&d| d == 0));
    }
}

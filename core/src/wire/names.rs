//! Names of the telemetry and instrumentation values (`DEBUG_VECT.name`, `NAMED_VALUE_INT.name`,
//! at most 10 bytes). What each carries is tabulated in `firmware/src/link/telemetry.rs`.

/// DEBUG_VECT: x = h̄ (m²), y = region code, z = active obstacle id (−1 none).
pub const CBF: &str = "CBF";
/// NAMED_VALUE_INT: filter flags ([`crate::wire::codes::CbfFlags`]).
pub const CBF_FLAGS: &str = "CBF_FLAGS";
/// DEBUG_VECT: the speed governor ([`crate::wire::codes::governor_to_wire`]): x = limit along the
/// motion (m/s, −1 none), y = cause code, z = 1 when it acted.
pub const GOV: &str = "GOV";
/// DEBUG_VECT: nominal acceleration u* (NED, m/s²).
pub const U_NOM: &str = "U_NOM";
/// DEBUG_VECT: inner-loop timing (mean period, max period, max execution; µs).
pub const LOOP_IN: &str = "LOOP_IN";
/// DEBUG_VECT: outer-loop timing.
pub const LOOP_OUT: &str = "LOOP_OUT";
/// NAMED_VALUE_INT: inner-loop overruns since boot.
pub const OVR_IN: &str = "OVR_IN";
/// NAMED_VALUE_INT: outer-loop overruns since boot.
pub const OVR_OUT: &str = "OVR_OUT";
/// DEBUG_VECT: frames ok, CRC errors, malformed frames.
pub const LINK: &str = "LINK";
/// DEBUG_VECT: replies dropped, inputs rejected, obstacle points rejected.
pub const LINK_DROP: &str = "LINK_DROP";
/// DEBUG_VECT: IMU read errors, UART receive errors.
pub const HW_ERR: &str = "HW_ERR";
/// NAMED_VALUE_INT: failsafe code on every transition ([`crate::wire::codes::failsafe`]).
pub const FAILSAFE: &str = "FAILSAFE";
/// NAMED_VALUE_INT (1 Hz, with the HEARTBEAT): flight phase code ([`crate::wire::codes::FlightPhase`];
/// the HEARTBEAT's `custom_mode` carries the PX4 flight mode).
pub const PHASE: &str = "PHASE";
/// Prefix of the DEBUG_VECT carrying an obstacle's velocity: `OBV<id>` (NED, m/s).
pub const OBSTACLE_VELOCITY_PREFIX: &str = "OBV";

/// NAMED_VALUE_INT (PIL, after the handshake): instructions of the calibration loop.
pub const INS_CAL_N: &str = "ins_cal_n";
/// NAMED_VALUE_INT (PIL, after the handshake): SysTick ticks the calibration loop took.
pub const INS_CAL: &str = "ins_cal";
/// NAMED_VALUE_INT (PIL, every step): instructions of the whole control step.
pub const INS_STEP: &str = "ins_step";
/// NAMED_VALUE_INT (PIL, steps that ran the outer loop, before `ins_step`): instructions of the
/// outer step alone.
pub const INS_OUTER: &str = "ins_outer";
/// NAMED_VALUE_INT (PIL, every step, before `ins_step`): longest section with interrupts masked
/// during this step, instructions.
pub const INS_MASKED: &str = "ins_masked";
/// NAMED_VALUE_INT (PIL, after a step batch in which the on-board replanner served a request;
/// issue 38): instructions of that plan.
pub const INS_REPLAN: &str = "ins_rpl";

/// STATUSTEXT the PIL firmware sends once it is ready for the lockstep.
pub const PIL_READY_TEXT: &str = "parapet PIL ready";
/// STATUSTEXT (substring) the firmware sends from its panic handler.
pub const PANIC_TEXT: &str = "PANIC";

/// `true` when the NUL-padded MAVLink name field `field` spells `name`.
pub fn name_is(field: &[u8], name: &str) -> bool {
    let n = field.iter().position(|&b| b == 0).unwrap_or(field.len());
    field.get(..n) == Some(name.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_fit_the_ten_byte_field_and_compare_padded() {
        for n in [
            CBF, CBF_FLAGS, U_NOM, LOOP_IN, LOOP_OUT, OVR_IN, OVR_OUT, LINK, LINK_DROP, HW_ERR, FAILSAFE,
            PHASE, INS_CAL_N, INS_CAL, INS_STEP, INS_OUTER, INS_MASKED, INS_REPLAN,
        ] {
            assert!(n.len() <= 10, "{n}");
        }
        assert!(name_is(b"CBF\0\0\0\0\0\0\0", CBF));
        assert!(!name_is(b"CBF_FLAGS\0", CBF));
        assert!(name_is(b"ins_cal_n\0", INS_CAL_N));
        assert!(name_is(b"LINK_DROP0", "LINK_DROP0"));
    }
}

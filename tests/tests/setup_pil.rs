//! The setup services of the QEMU firmware with a pymavlink ground station (issue 22):
//! `tests/python/pil_setup.py` is itself the PIL host (it starts QEMU with the board-qemu ELF,
//! steps the vehicle at rest on the ground in lockstep) and checks, through the MAVLink link:
//! PARAM_SET → PREFLIGHT_STORAGE write → read back from the (RAM-backed) flash; reset to
//! defaults; the debounced save; DO_MOTOR_TEST accepted disarmed (motor 1 only, stops at the
//! timeout and on the next command); PREFLIGHT_CALIBRATION level with its progress STATUSTEXTs
//! and the trim of a known tilt; armed, every setup command DENIED with its STATUSTEXT reason.
//!
//! Needs QEMU and the board-qemu ELF (`parapet_tests::pil_support`) and the venv's python with
//! pymavlink (`cargo xtask venv`); without them the test SKIPs loudly, except with `CI` or
//! `PARAPET_PYTHON` set, where it fails (as `onboard_log.rs`).

use std::process::Command;

use parapet_tests::pil_support::{firmware, venv_python, workspace_root};

/// pymavlink drives PREFLIGHT_STORAGE, DO_MOTOR_TEST and PREFLIGHT_CALIBRATION against the QEMU
/// firmware (see the module docs); every step must pass.
#[test]
fn pymavlink_storage_motor_test_and_calibration_on_the_qemu_firmware() {
    let Some(py) = venv_python("pymavlink", "the setup services over MAVLink") else { return };
    let Some(elf) = firmware() else { return };
    let o = Command::new(&py)
        .arg(workspace_root().join("tests/python/pil_setup.py"))
        .arg(&elf)
        .output()
        .expect("run pil_setup.py");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success() && text.contains("PASS"), "setup services over MAVLink:\n{text}");
    // The store's work was measured in the firmware (ins_store, instructions per call).
    assert!(text.contains("ins_store:"), "{text}");
}

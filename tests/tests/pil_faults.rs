//! Processor-in-the-loop fault handling: corrupted, dropped and lost frames on the host →
//! firmware link are counted and survived; a stopped (SIGSTOP) or killed firmware is detected
//! within the link timeout, never a hang; a missing QEMU gives the install command.
//!
//! Needs `qemu-system-arm` and the QEMU firmware ELF (see `pil_flight.rs`).

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use parapet_sim::fc::pil::{run_pil, FaultInjection, PilLink, PilOptions};
use parapet_sim::flight::runner::run_with;
use parapet_tests::pil_support::{config, firmware, scene};

#[test]
fn corrupted_dropped_and_lost_frames_are_counted_and_survived() {
    let Some(elf) = firmware() else { return };
    let scene = scene();
    // pil_flight's scene (≈ 16 s to the goal with the governor) plus the faults' retries.
    let cfg = config(&scene, 20.0);
    let mut opts = PilOptions::new(elf);
    opts.resend_after = Duration::from_millis(300);
    opts.faults =
        FaultInjection { corrupt_rate: 0.02, drop_rate: 0.02, lose_trigger_every: Some(2000), seed: 7 };
    let (out, fig) = run_pil(&scene, &cfg, opts, &mut |_| {}).expect("PIL flight with faults");
    let s = &out.summary;
    println!(
        "faults: injected {} corrupted + {} dropped; firmware CRC errors {} malformed {}; re-sent steps {}; \
         frames_dropped {}; RTF {:.3}; end {} at {:.2} s, min clearance {:.3} m",
        fig.injected_corrupted,
        fig.injected_dropped,
        fig.firmware_crc_errors,
        fig.firmware_malformed,
        fig.steps_resent,
        fig.frames_dropped,
        fig.real_time_factor,
        s.end_reason,
        s.sim_time_s,
        s.min_clearance_m
    );
    assert!(!s.collided, "collision with faults: {:?}", s.collision_with);
    assert!(s.reached_goal, "goal not reached with faults: {} m left", s.final_distance_to_goal_m);
    assert!(fig.injected_corrupted >= 20 && fig.injected_dropped >= 20, "{fig:?}");
    // Every lost HIL_SENSOR was re-sent (and answered).
    let lost_triggers = fig.flight_steps / 2000;
    assert!(lost_triggers >= 3 && fig.steps_resent >= lost_triggers, "{fig:?}");
    // The firmware counted the corrupted frames (its LINK report is 1 Hz, so the last second's
    // corruptions may be missing; a re-scan inside a corrupted frame may count more, never fewer).
    let seen = fig.firmware_crc_errors + fig.firmware_malformed;
    assert!(seen as f64 >= 0.7 * fig.injected_corrupted as f64, "{fig:?}");
    assert!(fig.frames_dropped >= seen);
}

fn stop_run(signal: &str, at_s: f64, timeout: Duration) -> (String, Duration, u32) {
    let elf = firmware().expect("firmware");
    let scene = scene();
    let cfg = config(&scene, 3.0);
    let mut opts = PilOptions::new(elf);
    opts.timeout = timeout;
    opts.resend_after = Duration::from_millis(500);
    let mut link = PilLink::spawn(&scene, &cfg, opts).expect("QEMU starts");
    let pid = link.qemu_pid();
    let mut stopped_at = None;
    let r = run_with(&scene, &cfg, &mut link, &mut |t| {
        if t >= at_s && stopped_at.is_none() {
            let ok =
                Command::new("kill").args([signal, &pid.to_string()]).status().is_ok_and(|s| s.success());
            assert!(ok, "kill {signal} {pid}");
            stopped_at = Some(Instant::now());
        }
    });
    let detected = stopped_at.expect("signal sent").elapsed();
    let fault = link.fault().map(str::to_string).expect("the link failure is reported");
    // The run itself ended (zero throttle after the failure → ground contact), no hang.
    let out = r.expect("run ends");
    assert_ne!(out.summary.end_reason, "goal");
    drop(link);
    (fault, detected, pid)
}

#[test]
fn a_stopped_firmware_is_detected_within_the_timeout() {
    if firmware().is_none() {
        return;
    }
    let timeout = Duration::from_secs(2);
    let (fault, detected, pid) = stop_run("-STOP", 0.5, timeout);
    println!("SIGSTOP detected after {:.2} s: {fault}", detected.as_secs_f64());
    assert!(fault.contains("stopped answering"), "{fault}");
    assert!(detected >= timeout && detected < timeout + Duration::from_secs(3), "{detected:?}");
    // QEMU was killed and reaped by the link's guard.
    assert!(!Path::new(&format!("/proc/{pid}")).exists(), "QEMU {pid} still exists");
}

#[test]
fn a_killed_emulator_is_detected_at_once() {
    if firmware().is_none() {
        return;
    }
    let (fault, detected, _) = stop_run("-KILL", 0.3, Duration::from_secs(3));
    println!("SIGKILL detected after {:.2} s: {fault}", detected.as_secs_f64());
    assert!(fault.contains("closed the link") || fault.contains("stopped answering"), "{fault}");
    assert!(detected < Duration::from_secs(4), "{detected:?}");
}

#[test]
fn missing_qemu_names_the_package_and_command() {
    let scene = scene();
    let cfg = config(&scene, 1.0);
    let mut opts = PilOptions::new(std::env::current_exe().expect("test binary path"));
    opts.qemu = "/nonexistent/qemu-system-arm".into();
    let err = match PilLink::spawn(&scene, &cfg, opts) {
        Ok(_) => panic!("spawned a nonexistent QEMU"),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains("apt-get install -y qemu-system-arm"), "{err}");
}

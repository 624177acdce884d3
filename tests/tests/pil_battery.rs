//! The scene's battery in the processor-in-the-loop: the host samples the simulated pack
//! (`[battery]`, host-sim/src/sim/battery.rs) exactly as `parapet run` does and sends each raw
//! reading to the `board-qemu` firmware as BATTERY_STATUS from the host's id (mV, cA;
//! `parapet_core::wire::battery`), where `firmware/src/pil/battery.rs` runs it through the
//! cascade's battery estimator into `set_battery`. A 3S pack at 5 % charge (3.61 V/cell resting,
//! below BAT_LOW_V 3.5 V/cell under the hover current's sag) reaches Low after the estimator's
//! 2 s debounce, so within a few seconds:
//!
//! * the firmware's BATTERY_STATUS (1 Hz) and SYS_STATUS carry the measurement, the charge
//!   state goes LOW;
//! * the firmware enters the battery failsafe: STATUSTEXT "MODE Return: battery-low";
//! * `parapet run` of the same scene and seed returns too, at the same time within one battery
//!   sample (100 ms at the model's 10 Hz; the link quantises the reading to 1 mV / 10 mA and the
//!   PIL flight differs from the in-process one by ≈ 1 mm, `pil_flight`); the firmware twin
//!   (`run_twin`: the firmware's sequence on the host with the same quantised readings) returns
//!   in the same outer step and flies the same path (< 1 mm).
//!
//! Without the host's readings the firmware has no measurement: no BATTERY_STATUS, SYS_STATUS
//! "no battery", no Return — each assertion below then fails.
//!
//! ELF and QEMU as `pil_flight` (`PARAPET_FIRMWARE_QEMU_ELF`, else built; SKIP without QEMU
//! outside CI). `cargo test -p parapet-tests --release --test pil_battery -- --nocapture`.

use parapet_sim::fc::control::run;
use parapet_sim::fc::pil::{max_deviation, run_pil, run_twin, PilOptions};
use parapet_sim::flight::runner::{RunConfig, RunOutput};
use parapet_sim::world::scene::Scene;
use parapet_tests::pil_support::firmware;

/// Simulated flight, s: the Return comes at ≈ 2.5 s (measured), then ≥ 3 BATTERY_STATUS.
const DURATION: f64 = 5.0;

/// `tests/tests/battery_flight.rs`'s obstacle-free 6 m flight at 0.3 m/s with a 3S pack at 5 %.
fn scene() -> Scene {
    let src = "name = \"pil_battery\"\n[bounds]\nmin = [-2.0, -2.0, 0.0]\nmax = [8.0, 2.0, 3.0]\n\
               [mission]\nstart = [0.0, 0.0, 1.0]\ngoal = [6.0, 0.0, 1.0]\nspeed = 0.3\n\
               [battery]\ncells = 3\ninitial_soc = 0.02\n";
    Scene::parse(src, "pil_battery.toml").unwrap_or_else(|e| panic!("{e:?}"))
}

fn first(out: &RunOutput, mode: &str) -> Option<f64> {
    out.samples.iter().find(|x| x.mode.as_str() == mode).map(|x| x.t)
}

#[test]
fn a_low_pack_reports_and_returns_in_the_pil_as_in_parapet_run() {
    let Some(elf) = firmware() else { return };
    let s = scene();
    let mut cfg = RunConfig::for_scene(&s, vec![s.start, s.goal]).unwrap_or_else(|e| panic!("{e}"));
    cfg.seed = 5;
    cfg.duration = DURATION;
    let (pil, fig) = run_pil(&s, &cfg, PilOptions::new(elf), &mut |_| {}).expect("PIL flight");
    let host = run(&s, &cfg, &mut |_| {}).expect("host flight");
    let twin = run_twin(&s, &cfg).expect("host twin flight");
    let (dev, n) = max_deviation(&pil, &twin);
    let b = &fig.battery;
    let pil_return = fig.mode_changes.iter().find(|m| m.text == "MODE Return: battery-low").map(|m| m.t_s);
    let host_return = first(&host, "Return");
    println!("PIL battery: {}", serde_json::to_string_pretty(b).unwrap_or_default());
    println!("PIL mode changes: {:?}", fig.mode_changes);
    let twin_return = first(&twin, "Return");
    println!(
        "Return: PIL {pil_return:?} s, parapet run {host_return:?} s, firmware twin {twin_return:?} s; \
         PIL vs twin max deviation {dev:.2e} m over {n} samples; real-time factor {:.2}",
        fig.real_time_factor
    );

    // The host sent every reading of the model (10 Hz over the flight).
    let expected = (DURATION * 10.0).round() as u64;
    assert!(
        b.readings_sent.abs_diff(expected) <= 1,
        "{} readings sent, expected {expected}",
        b.readings_sent
    );
    // The firmware measured them: BATTERY_STATUS at 1 Hz from its first measurement on.
    let first_status = b.first_status_s.expect("no BATTERY_STATUS from the firmware");
    assert!(first_status < 1.1, "first BATTERY_STATUS at {first_status} s");
    assert!(b.status_received >= (DURATION - first_status) as u64, "{} BATTERY_STATUS", b.status_received);
    // 3S at 5 %: 3 × 3.61 V resting, sagging under the hover current.
    let v = b.last_voltage_v.expect("BATTERY_STATUS voltage");
    assert!((9.5..11.0).contains(&v), "pack voltage {v} V");
    assert!(b.last_current_a.is_some_and(|a| a > 1.0), "current {:?}", b.last_current_a);
    assert!(
        b.last_remaining_pct.is_some_and(|r| (0..=10).contains(&r)),
        "remaining {:?}",
        b.last_remaining_pct
    );
    // SYS_STATUS carries the same measurement (not "no battery").
    let sv = b.sys_status_voltage_v.expect("SYS_STATUS says no battery");
    assert!((sv - v).abs() < 0.3, "SYS_STATUS {sv} V, BATTERY_STATUS {v} V");
    assert!(b.sys_status_current_a.is_some() && b.sys_status_remaining_pct.is_some());
    // Low, and the battery failsafe's Return, as in `parapet run`.
    let low = b.low_s.expect("the charge state never went LOW");
    assert_eq!(b.last_charge_state.as_deref(), Some("MAV_BATTERY_CHARGE_STATE_LOW"));
    let pil_return = pil_return.expect("no \"MODE Return: battery-low\" from the firmware");
    let host_return = host_return.expect("parapet run did not return");
    assert!(
        low >= pil_return && low <= pil_return + 1.0 + 1e-6,
        "LOW reported at {low} s, Return at {pil_return} s"
    );
    assert!(
        (pil_return - host_return).abs() <= 0.1 + 1e-6,
        "Return at {pil_return} s in the PIL, {host_return} s in parapet run"
    );
    assert!(pil_return > 2.0, "Return at {pil_return} s: before the 2 s debounce");
    // The firmware's sequence on the host, fed the same quantised readings in the same step
    // slot (`FirmwareTwin::battery`): the same Return outer step and the same flight.
    let twin_return = twin_return.expect("the firmware twin did not return");
    assert!((pil_return - twin_return).abs() <= 0.004 + 1e-6, "PIL {pil_return} s, twin {twin_return} s");
    assert!(n > 1000 && dev < 1e-3, "PIL and firmware twin differ by {dev} m over {n} samples");
    assert!(!pil.summary.reached_goal && !pil.summary.collided, "{:?}", pil.summary);
}

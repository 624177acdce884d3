//! The onboard flight log through the PIL link (issue 22): the QEMU firmware keeps its logs in
//! RAM (`firmware/src/log/`); a pymavlink ground station on `parapet pil --gcs` lists them,
//! fetches the newest with the MAVLink log protocol and pyulog parses it
//! (`tests/python/gcs_log_download.py`); then `parapet log`'s client (`parapet_sim::cli::log`)
//! pulls it through the second (`--api`) endpoint, and the pulled log's
//! `vehicle_status.nav_state` is checked with pyulog against PX4's numbers for the modes flown
//! (`tests/python/check_ulog_modes.py`; issue 37: the nav_state check in PIL).
//!
//! Needs QEMU and the board-qemu ELF (`parapet_tests::pil_support`) and the venv's python with
//! pymavlink and pyulog (`cargo xtask venv`); without them the test SKIPs loudly, except with
//! `CI` or `PARAPET_PYTHON` set, where it fails (as `gcs_clients.rs`).

use std::process::{Command, Stdio};
use std::time::Duration;

use parapet_sim::cli::log::Conn;
use parapet_sim::cli::sitl::{bridge, run_pil_bridged, SitlArgs};
use parapet_sim::fc::pil::PilOptions;
use parapet_tests::pil_support::{config, firmware, scene, venv_python, workspace_root};

/// PX4 `nav_state` values the onboard log holds in this order: AUTO_MISSION (3) for the
/// straight mission of `pil_support::config`, from arming (the guidance waits on the ground in
/// the selected Mission mode) on. Every record is also checked against PX4's number for the
/// guidance mode logged beside it (`parapet_mode`).
const MODES_FLOWN: &str = "3";

/// pymavlink lists and fetches the QEMU firmware's onboard log during a PIL flight; the file
/// parses with pyulog with every topic, armed records and the parameter table. Later in the
/// flight `parapet log`'s client lists and pulls the same log, byte-exact ULog, whose
/// `vehicle_status.nav_state` is PX4's for every record (pyulog): AUTO_MISSION (3) for the
/// mission flown.
#[test]
fn pymavlink_fetches_the_onboard_log_through_the_pil_link_and_pyulog_parses_it() {
    let Some(py) = venv_python("pymavlink, pyulog", "the onboard log download") else { return };
    let Some(elf) = firmware() else { return };
    let port = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr").port();
    let dir = std::env::temp_dir().join(format!("parapet-onboard-log-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("out dir");
    let fetched = dir.join("fetched.ulg");
    let client = Command::new(&py)
        .arg(workspace_root().join("tests/python/gcs_log_download.py"))
        .arg(port.to_string())
        .arg(&fetched)
        .arg("4")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("client");
    let api = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr").port();
    let mut cli =
        Conn::open(&format!("udpin:127.0.0.1:{api}"), None, Duration::from_secs(10)).expect("listen");
    // `parapet log` after the pymavlink download (which starts 4 s after the first heartbeat):
    // the vehicle streams one download at a time (a new LOG_REQUEST_DATA replaces the running
    // one, as PX4's), so two overlapping downloads would keep cancelling each other. The
    // pymavlink client writes its file when its download is complete; wait for that (on a loaded
    // machine the download can take longer than a fixed delay).
    let done = fetched.clone();
    let cli_pull = std::thread::spawn(move || -> Result<(usize, u32, Vec<u8>), String> {
        cli.connect("api endpoint").map_err(|x| x.to_string())?;
        let t0 = std::time::Instant::now();
        while !done.exists() && t0.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(100));
        }
        std::thread::sleep(Duration::from_millis(500)); // the log grows past the first download
        let entries = cli.list().map_err(|x| x.to_string())?;
        let newest = entries.last().cloned().ok_or_else(|| "no logs listed".to_string())?;
        let bytes = cli.pull(newest.id, newest.size).map_err(|x| x.to_string())?;
        Ok((entries.len(), newest.size, bytes))
    });
    std::thread::sleep(Duration::from_millis(500)); // the client listens
    let s = scene();
    let cfg = config(&s, 16.0);
    let sitl = SitlArgs {
        gcs: Some(format!("udp:127.0.0.1:{port}")),
        api: Some(format!("udp:127.0.0.1:{api}")),
        realtime: true,
    };
    let b = bridge(&sitl, &dir, true).expect("bridge");
    let r = run_pil_bridged(&s, &cfg, PilOptions::new(elf), b.clone(), &mut |_| {});
    b.borrow_mut().finish().expect("tlog");
    r.expect("PIL flight with a GCS attached");
    let o = client.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success(), "log download failed:\n{text}");
    assert!(text.contains("ok: pyulog reads"), "{text}");
    let (n, size, bytes) =
        cli_pull.join().expect("cli thread").expect("parapet log pull through the api endpoint");
    println!("parapet log: {n} log(s), pulled {} of {size} bytes", bytes.len());
    assert_eq!(bytes.len(), size as usize);
    assert_eq!(&bytes[..7], b"ULog\x01\x12\x35");
    // The same log as pymavlink's download: the same start, and more records since — unless the
    // first download already held the whole of the QEMU store's 26 KiB (`RAM_LOG_BYTES` of
    // firmware/src/log/service.rs: a longer log is cut there, ≈ 4 s of armed flight), which a
    // loaded machine reaches before the first download (CI 2026-12-06 with the governor's two
    // more `cbf_status` fields: 32,750 B both times).
    const RAM_LOG_BYTES: usize = 26 * 1024;
    let first = std::fs::read(&fetched).expect("pymavlink's file");
    let cut = first.len() + 1024 > RAM_LOG_BYTES;
    assert!(bytes.len() >= first.len() && bytes[..first.len()] == first[..], "not the same log");
    assert!(
        bytes.len() > first.len() || cut,
        "the log did not grow ({} B) and was not at the store's cut",
        first.len()
    );
    // The firmware's log names PX4's modes (the host's: tests/tests/ulog_modes.rs).
    let pulled = dir.join("pulled.ulg");
    std::fs::write(&pulled, &bytes).expect("write the pulled log");
    let o = Command::new(&py)
        .arg(workspace_root().join("tests/python/check_ulog_modes.py"))
        .arg(&pulled)
        .arg(MODES_FLOWN)
        .output()
        .expect("run check_ulog_modes.py");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success() && text.contains("nav_state changes"), "nav_state check failed:\n{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

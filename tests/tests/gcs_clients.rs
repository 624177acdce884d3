//! Real ground-station and log clients against Parapet (issue 20): pyulog reads the ULog of a
//! run and checks PX4's topics and units; pymavlink talks to `parapet pil --gcs` through the
//! UDP bridge and replays the `.tlog`; the parameter/mission services and MAVProxy.
//!
//! The clients are Python packages (`tests/python/requirements.txt`) in the venv that
//! `cargo xtask test` creates (`target/venv`, passed as `PARAPET_PYTHON`). Without it the tests
//! SKIP loudly, except with `CI` set (or `PARAPET_PYTHON` set), where they fail — the rule of
//! `parapet_tests::pil_support` for QEMU.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use parapet_sim::cli::sitl::{bridge, run_inprocess_bridged, run_pil_bridged, SitlArgs};
use parapet_sim::fc::control::run;
use parapet_sim::fc::pil::PilOptions;
use parapet_sim::flight::runner::{controller_params, RunConfig, RunOutput};
use parapet_sim::flight::stack::clock_us;
use parapet_sim::report::ulog::write_flight_ulog;
use parapet_tests::pil_support::{config, firmware, is_ci, scene};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root").to_path_buf()
}

fn script(name: &str) -> PathBuf {
    root().join("tests/python").join(name)
}

/// The venv's python with the clients, or `None` (SKIP) outside CI.
fn python() -> Option<PathBuf> {
    python_of("PARAPET_PYTHON", "venv", "import pymavlink, pyulog, mavsdk", "requirements.txt")
}

/// The python of `$ENV` or `<target>/VENV` that runs `check`, or `None` (SKIP) outside CI
/// (`cargo xtask test` creates the venv from `tests/python/REQUIREMENTS`).
fn python_of(env_name: &str, venv: &str, check: &str, requirements: &str) -> Option<PathBuf> {
    let env = std::env::var_os(env_name).map(PathBuf::from);
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root().join("target"));
    let py = env.clone().unwrap_or_else(|| target.join(venv).join("bin/python"));
    let ok = Command::new(&py)
        .args(["-c", check])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(py);
    }
    let why = format!(
        "no python that can `{check}` at {} (cargo xtask test creates it: python3 -m venv target/{venv} \
         && target/{venv}/bin/pip install -r tests/python/{requirements})",
        py.display()
    );
    if is_ci(std::env::var_os("CI").as_deref()) || env.is_some() {
        panic!("{why}; CI or {env_name} is set: the ground-station clients cannot be skipped here");
    }
    eprintln!("\n*** SKIP: {why}: ground-station clients NOT TESTED ***\n");
    None
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("parapet-gcs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("out dir");
    d
}

fn check(py: &Path, args: &[&str]) {
    let o = Command::new(py).args(args).output().expect("python runs");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success(), "{args:?} failed:\n{text}");
}

/// pyulog (`ulog_info` and `ULog`) reads the in-process run's `flight.ulg`: the PX4 topics
/// with their fields, NED metres (the start's z), m/s, unit quaternions, throttles 0..1 with
/// NaN for unused outputs, armed and in mission, the filter acting at the sphere.
#[test]
fn pyulog_reads_the_run_log_with_px4_topics_and_units() {
    let Some(py) = python() else { return };
    let s = scene();
    let cfg = config(&s, 12.0);
    let out = run(&s, &cfg, &mut |_| {}).expect("flight");
    let dir = out_dir("ulog");
    let path = dir.join("flight.ulg");
    let params = controller_params(&s, &cfg, cfg.cbf_params().expect("cbf"), cfg.variant);
    write_flight_ulog(&path, &out.samples, &params, &[("parapet_stack", "run".into())], clock_us)
        .expect("ulog");
    let start_z = format!("{}", s.start.z);
    let speed = format!("{}", s.speed);
    check(
        &py,
        &[script("check_ulog.py").to_str().expect("utf-8"), path.to_str().expect("utf-8"), &start_z, &speed],
    );
}

/// The pymavlink ground-station scripts share their connect / fail / wait / heartbeat helpers
/// (`tests/python/gcs_common.py`): every pymavlink script that listens for the bridge imports
/// them and defines none of its own (MAVProxy's and MAVSDK's scripts are other clients). Before: gcs_pymavlink.py, gcs_qgc_plan.py and
/// gcs_log_download.py each repeated them. (A source check: it needs no venv.)
#[test]
fn python_ground_stations_share_gcs_common() {
    let dir = root().join("tests/python");
    let mut listeners = Vec::new();
    for e in std::fs::read_dir(&dir).expect("tests/python") {
        let path = e.expect("entry").path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("").to_string();
        if !name.ends_with(".py") || name == "gcs_common.py" {
            continue;
        }
        let text = std::fs::read_to_string(&path).expect("script");
        if !text.contains("mavlink_connection(f\"udpin:") && !text.contains("from gcs_common import") {
            continue;
        }
        listeners.push(name.clone());
        assert!(text.contains("from gcs_common import"), "{name} does not import gcs_common");
        for own in ["def fail(", "def wait(", "mavlink_connection(f\"udpin:", "wait_heartbeat("] {
            assert!(!text.contains(own), "{name} repeats gcs_common's `{own}`");
        }
    }
    listeners.sort();
    assert_eq!(listeners, ["gcs_log_download.py", "gcs_metadata.py", "gcs_pymavlink.py", "gcs_qgc_plan.py"]);
}

/// A free UDP port on localhost (bound and released).
fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr").port()
}

/// Fly the PIL scene with `--gcs udp:127.0.0.1:PORT --realtime` while `client` (a python
/// script with its arguments, the port appended) talks to it; returns the client's output and
/// the report dir (flight.tlog, flight.ulg).
fn pil_with_client(py: &Path, client: &[&str], duration: f64, name: &str) -> Option<(bool, String, PathBuf)> {
    let elf = firmware()?;
    let port = free_port();
    let mut args: Vec<String> = client.iter().map(|s| s.to_string()).collect();
    args.insert(1, port.to_string());
    let child =
        Command::new(py).args(&args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("client");
    std::thread::sleep(Duration::from_millis(500)); // the client listens
    let dir = out_dir(name);
    let s = scene();
    let cfg = config(&s, duration);
    let sitl = SitlArgs { gcs: Some(format!("udp:127.0.0.1:{port}")), api: None, realtime: true };
    let b = bridge(&sitl, &dir, true).expect("bridge");
    let r = run_pil_bridged(&s, &cfg, PilOptions::new(elf), b.clone(), &mut |_| {});
    b.borrow_mut().finish().expect("tlog");
    r.expect("PIL flight with a GCS attached");
    let o = child.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    Some((o.status.success(), text, dir))
}

/// pymavlink as a GCS on `parapet pil --gcs`: HEARTBEAT, ATTITUDE and LOCAL_POSITION_NED
/// arrive, none of the lockstep frames does, a PARAM_REQUEST_READ goes through the bridge and
/// is answered; the `.tlog` replays with pymavlink (both directions, in time order).
#[test]
fn pymavlink_gcs_through_the_bridge_and_tlog_replay() {
    let Some(py) = python() else { return };
    let sc = script("gcs_pymavlink.py");
    let Some((ok, text, dir)) = pil_with_client(&py, &[sc.to_str().expect("utf-8"), "basic"], 10.0, "basic")
    else {
        return;
    };
    assert!(ok && text.contains("PASS"), "pymavlink GCS:\n{text}");
    check(
        &py,
        &[script("check_tlog.py").to_str().expect("utf-8"), dir.join("flight.tlog").to_str().expect("utf-8")],
    );
}

/// The parameter and mission microservices as a GCS uses them (issue 20's defects): the whole
/// PARAM_REQUEST_LIST, PARAM_SET echo, mission download, MISSION_CLEAR_ALL and count 0 after;
/// and the component metadata (issue 41, `tests/python/gcs_metadata.py`): COMPONENT_METADATA's
/// `mftp://` URI, general.json and the parameter metadata it points to downloaded with pymavlink's
/// MAVLink FTP client, their CRCs checked, every parameter of the list there with units and range.
#[test]
fn pymavlink_parameter_and_mission_services() {
    let Some(py) = python() else { return };
    let sc = script("gcs_pymavlink.py");
    let Some((ok, text, _)) = pil_with_client(&py, &[sc.to_str().expect("utf-8"), "full"], 20.0, "full")
    else {
        return;
    };
    assert!(ok && text.contains("PASS"), "pymavlink parameter/mission services:\n{text}");
}

/// MAVProxy (`mavproxy.py --master udpin:…`, `param fetch` then `wp list` typed once the
/// vehicle is seen) completes both without timeouts (`Received N parameters`, the waypoint list).
#[test]
fn mavproxy_param_fetch_and_wp_list() {
    let Some(py) = python() else { return };
    let bin = py.parent().expect("venv bin").to_path_buf();
    let logdir = out_dir("mavproxy-state");
    let sc = script("gcs_mavproxy.py");
    let Some(elf) = firmware() else { return };
    let port = free_port();
    let child = Command::new(&py)
        .arg(&sc)
        .arg(&bin)
        .arg(port.to_string())
        .arg(&logdir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mavproxy");
    std::thread::sleep(Duration::from_millis(1500));
    let dir = out_dir("mavproxy");
    let s = scene();
    // Start → goal twice, 60 s at most (real time). MAVProxy asks for the parameters by MAVLink
    // FTP first; the firmware answers NAK (firmware/src/link/ftp.rs) and the parameter protocol
    // follows at once (2026-12-04: 74 parameters 2.1 s after `param fetch`, the whole script
    // done by 4 s). Before the NAK MAVProxy waited ~10 s for FTP, and on a single leg the run
    // ended at the goal before the fallback finished when CI's 2 cores were loaded (heartbeat
    // at 3.6 s, FTP time-out at 14.6 s, link gone at 21.2 s): the second leg keeps that margin.
    let mut cfg = config(&s, 60.0);
    cfg.path = vec![s.start, s.goal, s.start, s.goal];
    let sitl = SitlArgs { gcs: Some(format!("udp:127.0.0.1:{port}")), api: None, realtime: true };
    let b = bridge(&sitl, &dir, true).expect("bridge");
    run_pil_bridged(&s, &cfg, PilOptions::new(elf), b, &mut |_| {})
        .expect("PIL flight with MAVProxy attached");
    let o = child.wait_with_output().expect("mavproxy ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success() && text.contains("PASS"), "MAVProxy:\n{text}");
}

/// `parapet run --gcs`: pymavlink gets heartbeat and LOCAL_POSITION_NED from the in-process
/// controller, the whole parameter list (each index once), a PARAM_SET echo and the flown
/// path as a mission download.
#[test]
fn pymavlink_on_the_in_process_run() {
    let Some(py) = python() else { return };
    let port = free_port();
    let child = Command::new(&py)
        .arg(script("gcs_pymavlink.py"))
        .arg(port.to_string())
        .arg("readonly")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("client");
    std::thread::sleep(Duration::from_millis(500));
    let s = scene();
    let cfg = config(&s, 12.0);
    let sitl = SitlArgs { gcs: Some(format!("udp:127.0.0.1:{port}")), api: None, realtime: true };
    let b = bridge(&sitl, &out_dir("run-gcs"), false).expect("bridge");
    let (out, note) = run_inprocess_bridged(&s, &cfg, b, &mut |_| {}).expect("run with a GCS");
    println!("{note}");
    // The bridge does not change the flight: the same samples as without it.
    let plain = run(&s, &cfg, &mut |_| {}).expect("flight");
    assert_eq!(parapet_sim::fc::pil::max_deviation(&out, &plain), (0.0, plain.samples.len()));
    assert_eq!(out.samples.len(), plain.samples.len());
    let o = child.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success() && text.contains("PASS"), "pymavlink on parapet run --gcs:\n{text}");
}

/// MAVSDK-Python (mavsdk 3.x with its bundled mavsdk_server) on `parapet run --api
/// --realtime`: connects over UDP, reads the NED position (above the ground) and a parameter.
#[test]
fn mavsdk_connects_reads_telemetry_and_a_parameter() {
    let Some(py) = python() else { return };
    let port = free_port();
    let child = Command::new(&py)
        .arg(script("mavsdk_telemetry.py"))
        .arg(port.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("client");
    std::thread::sleep(Duration::from_millis(500));
    let s = scene();
    let cfg = config(&s, 12.0);
    let sitl = SitlArgs { gcs: None, api: Some(format!("udp:127.0.0.1:{port}")), realtime: true };
    let b = bridge(&sitl, &out_dir("run-api"), false).expect("bridge");
    let (_, note) = run_inprocess_bridged(&s, &cfg, b, &mut |_| {}).expect("run with MAVSDK");
    println!("{note}");
    let o = child.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(o.status.success() && text.contains("PASS"), "MAVSDK on parapet run --api:\n{text}");
}

/// The MAVSDK-Python **4** snippet of `docs/ground-station.md` (the ```python block after the
/// marker `mavsdk4-snippet`) runs as written against `parapet run --api --realtime`, with only
/// its port 14540 replaced by a free one (tests run in parallel): it connects, prints the NED
/// position and CBF_MU. Run with MAVSDK-Python 4.1.0 (`target/venv-mavsdk4`,
/// `PARAPET_MAVSDK4_PYTHON`); issue 41: the 3.x snippet the docs had failed with mavsdk 4
/// (TypeError).
#[test]
fn mavsdk4_snippet_of_the_docs_runs_as_written() {
    let Some(py) = python_of(
        "PARAPET_MAVSDK4_PYTHON",
        "venv-mavsdk4",
        "import mavsdk.asyncio",
        "requirements-mavsdk4.txt",
    ) else {
        return;
    };
    let doc = std::fs::read_to_string(root().join("docs/ground-station.md")).expect("docs");
    let after = doc.split_once("mavsdk4-snippet").expect("the snippet's marker").1;
    let code = after.split_once("```python\n").expect("its python block").1;
    let code = code.split_once("```").expect("the block's end").0;
    assert!(code.contains("udpin://0.0.0.0:14540"), "the snippet connects as the docs say:\n{code}");
    let port = free_port();
    let dir = out_dir("mavsdk4-snippet");
    let file = dir.join("snippet.py");
    std::fs::write(&file, code.replace("14540", &port.to_string())).expect("snippet");
    let child =
        Command::new(&py).arg(&file).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("client");
    std::thread::sleep(Duration::from_millis(500));
    let s = scene();
    let cfg = config(&s, 12.0);
    let sitl = SitlArgs { gcs: None, api: Some(format!("udp:127.0.0.1:{port}")), realtime: true };
    let b = bridge(&sitl, &dir, false).expect("bridge");
    run_inprocess_bridged(&s, &cfg, b, &mut |_| {}).expect("run with MAVSDK 4");
    let o = child.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    assert!(
        o.status.success() && text.contains("position PositionNed(") && text.contains("CBF_MU 1.39"),
        "the docs' MAVSDK 4 snippet on parapet run --api:\n{text}"
    );
}

/// MAVSDK-Python (`tests/python/mavsdk_mission.py`) flies the whole mission on `parapet pil
/// --gcs-control --api --realtime` (the real firmware in QEMU): the vehicle waits disarmed on the
/// ground; MAVSDK connects, reads telemetry, uploads the mission (mission_raw, LOCAL_NED), arms,
/// takes off, starts it, watches it reach the goal, lands and the vehicle disarms. Before issue 20's
/// fixes MAVSDK's progress never advanced (MISSION_CURRENT seq 0, no MISSION_ITEM_REACHED),
/// `start_mission` (DO_SET_MODE AUTO.MISSION) left the vehicle holding, and the host always flew.
#[test]
fn mavsdk_flies_a_mission_on_the_pil() {
    fly_mavsdk_mission_on_the_pil("raw", "mavsdk-mission");
}

/// MAVSDK-Python's standard `mission` plugin (`tests/python/mavsdk_mission.py … plugin`) flies a
/// global-frame plan, as QGroundControl and PX4 SITL users do: MissionItems at the telemetry home
/// position + the path's offsets, uploaded as NAV_WAYPOINTs in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
/// downloaded back with the same lat/lon, flown to the goal and landed. Before the global-frame
/// conversion (now core/src/wire/geo.rs) the upload was refused MAV_MISSION_UNSUPPORTED_FRAME.
#[test]
fn mavsdk_mission_plugin_flies_a_global_plan_on_the_pil() {
    fly_mavsdk_mission_on_the_pil("plugin", "mavsdk-global-mission");
}

/// `mavsdk_mission.py` (PORT WAYPOINTS_JSON `upload`: `raw` or `plugin`) flies the office path on `parapet pil
/// --gcs-control --api --realtime`; the run must reach the goal, end when the vehicle disarmed
/// and end landed.
fn fly_mavsdk_mission_on_the_pil(upload: &str, dir_name: &str) {
    let s = scene();
    let cfg = config(&s, 90.0);
    let wps: Vec<[f64; 3]> = cfg.path.iter().map(|w| [w.x, w.y, w.z]).collect();
    let wps = serde_json::to_string(&wps).expect("json");
    let Some(out) = fly_client_on_the_pil("mavsdk_mission.py", &[&wps, upload], &cfg, dir_name) else {
        return;
    };
    let sm = &out.summary;
    assert!(sm.reached_goal && !sm.collided, "{sm:?}");
    let last = out.samples.last().expect("samples");
    assert!(last.pos.z > -0.1, "landed at the end: {:?}", last.pos);
}

/// Runs the python client `script` (PORT then `args`) against the PIL scene on `parapet pil
/// --gcs-control --api udp:127.0.0.1:PORT --realtime` until the vehicle disarms; asserts the
/// client printed PASS and the run ended before `cfg.duration` (disarmed, not the limit).
/// Returns the flight; `None` when the prerequisites SKIP.
fn fly_client_on_the_pil(
    script_name: &str,
    args: &[&str],
    cfg: &RunConfig,
    dir_name: &str,
) -> Option<RunOutput> {
    let py = python()?;
    let elf = firmware()?;
    let port = free_port();
    let s = scene();
    let child = Command::new(&py)
        .arg(script(script_name))
        .arg(port.to_string())
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("client");
    std::thread::sleep(Duration::from_millis(500)); // the client listens
    let dir = out_dir(dir_name);
    let sitl = SitlArgs { gcs: None, api: Some(format!("udp:127.0.0.1:{port}")), realtime: true };
    let b = bridge(&sitl, &dir, true).expect("bridge");
    let mut opts = PilOptions::new(elf);
    opts.gcs_control = true;
    let r = run_pil_bridged(&s, cfg, opts, b.clone(), &mut |_| {});
    b.borrow_mut().finish().expect("tlog");
    let o = child.wait_with_output().expect("client ends");
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    println!("{text}");
    let (out, fig) = r.expect("PIL flight flown by the ground station");
    for x in out.samples.iter().step_by(250) {
        println!(
            "t {:5.1} pos {:6.2} {:6.2} {:6.2} ref {:6.2} {:6.2} {:6.2} {}",
            x.t,
            x.pos.x,
            x.pos.y,
            x.pos.z,
            x.ref_pos.x,
            x.ref_pos.y,
            x.ref_pos.z,
            x.mode.as_str()
        );
    }
    let sm = &out.summary;
    println!(
        "PIL: {} steps, real-time factor {:.2}; end {} at {:.1} s; reached goal {} at {:?}; min clearance {:.3} m",
        fig.flight_steps, fig.real_time_factor, sm.end_reason, sm.sim_time_s, sm.reached_goal, sm.time_to_goal_s,
        sm.min_clearance_m
    );
    assert!(
        o.status.success() && text.contains("PASS"),
        "{script_name} on parapet pil --gcs-control:\n{text}"
    );
    assert!(
        sm.sim_time_s < cfg.duration,
        "the run ended when the vehicle disarmed, not at the limit: {sm:?}"
    );
    Some(out)
}

/// A QGroundControl-style plan from a pymavlink ground station (`tests/python/gcs_qgc_plan.py`):
/// NAV_TAKEOFF (here, 1 m), a NAV_WAYPOINT beside the sphere held 2 s, a DO_CHANGE_SPEED, a
/// NAV_LOITER_TIME of 1.5 s past the sphere, a NAV_DELAY of 1 s, a CONDITION_YAW to 90°,
/// NAV_RETURN_TO_LAUNCH, in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT; downloaded field for field; ARM and
/// MISSION_START from the ground. MISSION_ITEM_REACHED must come for seqs 0..6 as uploaded, the
/// holds must last (the script times them), the heading must be 90° at the yaw item, the vehicle
/// must report Return, come back, land within 0.3 m of its start and disarm by itself; no
/// collision. Before: the upload was refused MAV_MISSION_UNSUPPORTED (the TAKEOFF item, then
/// issue 41: LOITER_TIME, NAV_DELAY, CONDITION_YAW), the hold time and the speed were ignored.
#[test]
fn pymavlink_flies_qgroundcontrols_default_plan_and_returns() {
    let s = scene();
    let cfg = config(&s, 120.0);
    let plan = r#"{"alt": 1.0, "waypoints": [[1.2, -0.6], [2.4, 0.0]]}"#;
    let Some(out) = fly_client_on_the_pil("gcs_qgc_plan.py", &[plan], &cfg, "qgc-plan") else { return };
    let sm = &out.summary;
    assert!(!sm.collided, "{sm:?}");
    let start = out.samples.first().expect("samples").pos;
    let far = out.samples.iter().map(|x| x.pos.x).fold(f64::MIN, f64::max);
    assert!(far > 2.2, "flew to the second waypoint (north {far:.2} m)");
    let last = out.samples.last().expect("samples").pos;
    let d = ((last.x - start.x).powi(2) + (last.y - start.y).powi(2)).sqrt();
    assert!(d < 0.3 && last.z > -0.1, "landed back at the start {start:?}: {last:?} ({d:.2} m away)");
}

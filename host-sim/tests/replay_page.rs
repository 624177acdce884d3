//! The replay page, looked at (issue 40): a short flight's `replay.html` opened in headless
//! Chromium at a given time (`#t=…`); the page's probe (`<pre id="probe">`, see
//! `parapet_sim::report::replay`) must show the scene's obstacle count in the scene graph, the
//! vehicle at the `trajectory.csv` row of that time to the printed digit and on screen, the
//! row's texts, `summary.json`'s texts, and no error. A run that ended at once and a report
//! without samples still give pages without errors that say so.
//!
//! Chromium: `$PARAPET_CHROMIUM` (set by `cargo xtask test`, which installs Debian's
//! `chromium`), else `chromium` on PATH. Missing, the tests fail when `CI` or
//! `PARAPET_CHROMIUM` is set and are skipped loudly otherwise (the rule of the PIL tests,
//! `tests/src/pil_support.rs`).
//!
//! `cargo test -p parapet-sim --test replay_page -- --ignored office_screenshot` flies the
//! default office scene and writes `docs/figures/replay_office.png` (`docs/simulator.md`).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::parapet;

const SCENE: &str = include_str!("data/scenes/replay_page.toml");

/// Obstacles of [`SCENE`].
const OBSTACLES: usize = 4;

/// What a test that needs Chromium does.
#[derive(Debug, PartialEq)]
enum Need {
    Run(PathBuf),
    Skip(String),
    Fail(String),
}

fn is_ci(v: Option<&std::ffi::OsStr>) -> bool {
    v.and_then(|v| v.to_str()).is_some_and(|v| {
        let v = v.trim();
        !v.is_empty() && v != "0" && !v.eq_ignore_ascii_case("false")
    })
}

/// The rule: `env` is `$PARAPET_CHROMIUM`, `runs` says whether a binary answers `--version`.
fn chromium_rule(env: Option<PathBuf>, runs: &dyn Fn(&Path) -> bool, ci: bool) -> Need {
    let install = "sudo apt-get update && sudo apt-get install -y chromium";
    let bin = env.clone().unwrap_or_else(|| PathBuf::from("chromium"));
    if runs(&bin) {
        return Need::Run(bin);
    }
    if env.is_some() || ci {
        let why = if env.is_some() { "PARAPET_CHROMIUM is set" } else { "CI is set" };
        return Need::Fail(format!(
            "{} does not run and {why}: the replay page cannot go unlooked-at here; install it: {install}",
            bin.display()
        ));
    }
    Need::Skip(format!(
        "chromium not installed, PARAPET_CHROMIUM and CI unset: the replay page is NOT LOOKED AT \
         (cargo xtask test installs it; or: {install})"
    ))
}

fn chromium() -> Option<PathBuf> {
    let runs = |p: &Path| {
        Command::new(p)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    let env = std::env::var_os("PARAPET_CHROMIUM").map(PathBuf::from);
    match chromium_rule(env, &runs, is_ci(std::env::var_os("CI").as_deref())) {
        Need::Run(p) => Some(p),
        Need::Fail(why) => panic!("{why}"),
        Need::Skip(why) => {
            use std::io::Write;
            let _ = writeln!(std::io::stderr(), "\n*** SKIP: {why} ***\n");
            None
        }
    }
}

#[test]
fn chromium_missing_fails_in_ci_and_with_the_variable_and_skips_otherwise() {
    let yes = |_: &Path| true;
    let no = |_: &Path| false;
    let env = Some(PathBuf::from("/x/chromium"));
    assert_eq!(chromium_rule(None, &yes, false), Need::Run(PathBuf::from("chromium")));
    assert_eq!(chromium_rule(env.clone(), &yes, true), Need::Run(PathBuf::from("/x/chromium")));
    assert!(matches!(chromium_rule(None, &no, false), Need::Skip(w) if w.contains("NOT LOOKED AT")));
    for (e, ci) in [(None, true), (env.clone(), false), (env, true)] {
        let d = chromium_rule(e, &no, ci);
        assert!(matches!(&d, Need::Fail(w) if w.contains("apt-get install -y chromium")), "{d:?}");
    }
    assert!(is_ci(Some("true".as_ref())) && !is_ci(Some("0".as_ref())) && !is_ci(None));
}

/// A fresh directory for this test.
fn tmp(name: &str) -> common::TmpDir {
    common::tmp("replay", name)
}

/// `file://` URL of `path` (absolute) with `fragment`.
fn file_url(path: &Path, fragment: &str) -> String {
    let abs = std::fs::canonicalize(path).expect("page exists");
    let mut url = String::from("file://");
    for c in abs.to_string_lossy().chars() {
        match c {
            'A'..='Z' | 'a'..='z' | '0'..='9' | '/' | '-' | '_' | '.' | '~' => url.push(c),
            c => {
                let mut b = [0u8; 4];
                for byte in c.encode_utf8(&mut b).bytes() {
                    url.push_str(&format!("%{byte:02X}"));
                }
            }
        }
    }
    url + "#" + fragment
}

/// Run headless Chromium on `url` with `what` (`--dump-dom` or `--screenshot=…`); stdout.
fn chromium_run(bin: &Path, work: &Path, url: &str, what: &str) -> String {
    let profile = work.join("chromium-profile");
    let out_path = work.join("chromium-stdout.html");
    let out = std::fs::File::create(&out_path).unwrap();
    let mut child = Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--no-default-browser-check",
            "--hide-scrollbars",
            "--window-size=1280,800",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(what)
        .arg(url)
        .current_dir(work)
        .stdout(out)
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromium");
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        match child.try_wait().expect("wait chromium") {
            Some(_) => break,
            None if Instant::now() > deadline => {
                let _ = child.kill();
                let _ = child.wait();
                panic!("chromium did not finish within 120 s on {url}");
            }
            None => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    std::fs::read_to_string(&out_path).unwrap_or_default()
}

/// The probe JSON of a dumped page.
fn probe(dom: &str) -> serde_json::Value {
    let start =
        dom.find("<pre id=\"probe\"").unwrap_or_else(|| panic!("no probe in the page: {}", dom.len()));
    let rest = &dom[start..];
    let body = &rest[rest.find('>').unwrap() + 1..rest.find("</pre>").expect("probe closed")];
    let text = body.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("probe is not JSON ({e}): {text}"))
}

/// Every leaf of `summary.json` as `(dotted key, text)`: numbers and literals as the file
/// writes them, strings without quotes.
fn summary_leaves(prefix: &str, v: &serde_json::Value, out: &mut Vec<(String, String)>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                summary_leaves(&key, x, out);
            }
        }
        serde_json::Value::String(s) => out.push((prefix.into(), s.clone())),
        x => out.push((prefix.into(), x.to_string())),
    }
}

/// Fly `SCENE` (straight, `duration` s) into `dir/out`; the report directory.
fn fly(dir: &Path, duration: &str) -> PathBuf {
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let out = dir.join("out");
    let o = parapet(&[
        "run",
        "--scene",
        scene.to_str().unwrap(),
        "--straight",
        // Facing the direction of travel: the vehicle turns from north to east, so the drawn
        // attitude's axes are checked away from the identity.
        "--yaw-mode",
        "travel",
        "--duration",
        duration,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

fn csv_rows(report: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(report.join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(String::from).collect()).collect())
}

fn assert_no_errors(p: &serde_json::Value) {
    assert_eq!(p["errors"], serde_json::json!([]), "errors in the page: {p}");
    assert_eq!(p["webgl"], true, "no WebGL: {p}");
}

/// The probe's moving obstacles (the cylinder, the ball) are where the simulator puts them at the
/// shown time (`SceneObstacle::at`), to float32 rounding of the drawn geometry.
fn assert_moving_obstacles_where_the_simulator_has_them(p: &serde_json::Value) {
    use parapet_core::obstacle::Shape;
    let scene = parapet_sim::world::scene::Scene::parse(SCENE, "replay_page.rs").unwrap();
    let t: f64 = p["t_shown"].as_str().unwrap().parse().unwrap();
    let moving = p["moving"].as_array().expect("moving");
    assert_eq!(moving.len(), 2, "{p}");
    for m in moving {
        let i = m[0].as_u64().unwrap() as usize;
        let (shape, _) = scene.obstacles[i].at(t);
        // NED → ENU (x ↔ y, z → −z); the mesh origin of a cylinder is its axis midpoint.
        let ned = match shape {
            Shape::Sphere { center, .. } => [center[0], center[1], center[2]],
            Shape::Cylinder { base, height, .. } => [base[0], base[1], base[2] - height / 2.0],
            other => panic!("unexpected moving shape {other:?}"),
        };
        let want = [ned[1] as f64, ned[0] as f64, -ned[2] as f64];
        for k in 0..3 {
            let got = m[k + 1].as_f64().unwrap();
            assert!((got - want[k]).abs() < 1e-4, "obstacle {i} at t {t}: {got} vs {} ({p})", want[k]);
        }
    }
}

/// The probe's sample: its texts are its `trajectory.csv` row's, the vehicle in the scene graph
/// is at the row's position to the printed digit, on screen. Returns the row index.
fn assert_at_row(p: &serde_json::Value, header: &[String], rows: &[Vec<String>]) -> usize {
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let i = p["sample_index"].as_u64().expect("sample_index") as usize;
    let row = &rows[i];
    assert_eq!(p["t_shown"], row[col("t")], "{p}");
    let world: Vec<&str> =
        p["vehicle_world"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(world, [&row[col("x")], &row[col("y")], &row[col("z")]], "vehicle in the scene graph: {p}");
    let now = &p["now"];
    assert_eq!(now["t [s]"], row[col("t")]);
    assert_eq!(now["x, y, z [m]"], format!("{}, {}, {}", row[col("x")], row[col("y")], row[col("z")]));
    assert_eq!(now["clearance [m]"], row[col("clearance")]);
    assert_eq!(now["h̄ [m²]"], row[col("h_bar")]);
    assert_eq!(now["region"], row[col("region")]);
    assert_eq!(now["mode"], row[col("mode")]);
    assert_eq!(now["barriers enforced"], row[col("n_constraints")]);
    let active = if row[col("active_obstacle")].is_empty() { "-" } else { &row[col("active_obstacle")] };
    assert!(now["active obstacle"].as_str().unwrap().starts_with(active), "{p}");
    // The body as drawn: FRD → NED is Rz(yaw) Ry(pitch) Rx(roll) of the row; forward is its
    // first column, down its third, in ENU (x ↔ y, z → −z). The page's angles have 4 decimals.
    let a = |name: &str| row[col(name)].parse::<f64>().unwrap();
    let (r, q, y) = (a("roll"), a("pitch"), a("yaw"));
    let fwd_ned = [q.cos() * y.cos(), q.cos() * y.sin(), -q.sin()];
    let down_ned = [
        r.cos() * q.sin() * y.cos() + r.sin() * y.sin(),
        r.cos() * q.sin() * y.sin() - r.sin() * y.cos(),
        r.cos() * q.cos(),
    ];
    let enu = |v: [f64; 3]| [v[1], v[0], -v[2]];
    for (key, want) in [("body_forward", enu(fwd_ned)), ("body_down", enu(down_ned))] {
        for (k, w) in want.iter().enumerate() {
            let got = p[key][k].as_f64().unwrap();
            assert!((got - w).abs() < 2e-4, "{key}[{k}] {got} vs {w} (roll {r}, pitch {q}, yaw {y}): {p}");
        }
    }
    // On screen, inside the canvas.
    assert_eq!(p["on_screen"], true, "{p}");
    let (w, h) = (p["canvas"][0].as_f64().unwrap(), p["canvas"][1].as_f64().unwrap());
    let (x, y) = (p["screen"][0].as_f64().unwrap(), p["screen"][1].as_f64().unwrap());
    assert!(w > 300.0 && h > 200.0, "{p}");
    assert!((0.0..=w).contains(&x) && (0.0..=h).contains(&y), "{p}");
    i
}

fn assert_summary_shown(report: &Path, p: &serde_json::Value) {
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("summary.json")).unwrap()).unwrap();
    let mut want = Vec::new();
    summary_leaves("", &s, &mut want);
    let shown: Vec<(String, String)> = p["summary_shown"]
        .as_array()
        .expect("summary_shown")
        .iter()
        .map(|r| (r[0].as_str().unwrap().to_string(), r[1].as_str().unwrap().to_string()))
        .collect();
    assert_eq!(shown, want, "the page's summary.json table");
    assert!(shown.len() > 40, "{}", shown.len());
}

#[test]
fn the_page_shows_the_flight_at_the_asked_time() {
    let Some(bin) = chromium() else { return };
    let d = tmp("looks");
    let report = fly(&d, "4");
    let page = report.join("replay.html");
    let size = std::fs::metadata(&page).unwrap().len();
    assert!(size < 2_000_000, "replay.html is {size} B");
    let (header, rows) = csv_rows(&report);
    for t in ["0", "1.3", "2.5", "3.9999"] {
        let dom = chromium_run(&bin, &d, &file_url(&page, &format!("t={t}")), "--dump-dom");
        let p = probe(&dom);
        assert_no_errors(&p);
        assert_eq!(p["obstacle_meshes"], OBSTACLES, "{p}");
        assert_eq!(p["scene_obstacles"], OBSTACLES, "{p}");
        assert_moving_obstacles_where_the_simulator_has_them(&p);
        assert_eq!(p["n_samples"], rows.len(), "{p}");
        let i = assert_at_row(&p, &header, &rows);
        let asked: f64 = t.parse().unwrap();
        // The sample shown: the row at or before the asked time (every row is displayed here).
        assert!(rows[i][0].parse::<f64>().unwrap() <= asked + 1e-9, "{t}: row {:?}", rows[i]);
        if let Some(next) = rows.get(i + 1) {
            assert!(next[0].parse::<f64>().unwrap() > asked, "{t}: the next row is not later");
        }
        assert_summary_shown(&report, &p);
        assert_lists(&report, &p);
    }
    // Played from 0.5 s (the probe follows every frame): later, and still at its row.
    let p = probe(&chromium_run(&bin, &d, &file_url(&page, "t=0.5&rate=1&play"), "--dump-dom"));
    assert_no_errors(&p);
    let i = assert_at_row(&p, &header, &rows);
    assert!(rows[i][0].parse::<f64>().unwrap() > 0.6, "no playback: {p}");
    // The free-orbit camera sees the vehicle too, and the page draws something.
    let p = probe(&chromium_run(&bin, &d, &file_url(&page, "t=2&cam=orbit"), "--dump-dom"));
    assert_no_errors(&p);
    assert_eq!((p["camera"].as_str(), p["on_screen"].as_bool()), (Some("orbit"), Some(true)), "{p}");
    let shot = d.join("shot.png");
    chromium_run(&bin, &d, &file_url(&page, "t=2.5"), &format!("--screenshot={}", shot.display()));
    let png = std::fs::read(&shot).expect("screenshot written");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 50_000, "screenshot of {} B", png.len());
}

#[test]
fn a_run_that_ended_at_once_and_an_empty_report_give_pages_that_say_so() {
    let Some(bin) = chromium() else { return };
    let d = tmp("empty");
    // One outer step.
    let report = fly(&d, "0.001");
    let (_, rows) = csv_rows(&report);
    assert_eq!(rows.len(), 1);
    let p = probe(&chromium_run(&bin, &d, &file_url(&report.join("replay.html"), "t=5"), "--dump-dom"));
    assert_no_errors(&p);
    assert_eq!((p["sample_index"].as_u64(), p["empty"].as_bool()), (Some(0), Some(false)), "{p}");
    assert_eq!(p["t_shown"], rows[0][0]);
    assert_summary_shown(&report, &p);
    // No samples at all: the library's report of an empty record.
    let scene = parapet_sim::world::scene::Scene::parse(SCENE, "replay_page.rs").unwrap();
    let mut cfg =
        parapet_sim::flight::runner::RunConfig::for_scene(&scene, vec![scene.start, scene.goal]).unwrap();
    cfg.duration = 0.001;
    let run = parapet_sim::fc::control::run(&scene, &cfg, &mut |_| {}).unwrap();
    let dir = d.join("no-samples");
    let rec = parapet_sim::report::RunRecord {
        scene: &scene,
        path: &cfg.path,
        samples: &[],
        summary: &run.summary,
        ranges: &run.ranges,
        range_sensors: &[],
        filter_points: &run.filter_points,
        clock_us: parapet_sim::flight::stack::clock_us,
    };
    parapet_sim::report::write_report(&dir, &rec).unwrap();
    let dom = chromium_run(&bin, &d, &file_url(&dir.join("replay.html"), "probe"), "--dump-dom");
    let p = probe(&dom);
    assert_no_errors(&p);
    assert_eq!(p["empty"], true, "{p}");
    assert_eq!(p["obstacle_meshes"], OBSTACLES, "{p}");
    assert!(dom.contains("This run has no trajectory samples"), "the banner says so");
    // A diverged sample (position NaN, written "NaN" in trajectory.csv) between two good ones:
    // no error, the vehicle hidden at it.
    let mut samples = vec![run.samples[0].clone(); 3];
    for (k, s) in samples.iter_mut().enumerate() {
        s.t += 0.004 * k as f64;
    }
    samples[1].pos.x = f64::NAN;
    samples[1].h_bar = f64::INFINITY;
    let dir = d.join("nan");
    let rec = parapet_sim::report::RunRecord { samples: &samples, ..rec };
    parapet_sim::report::write_report(&dir, &rec).unwrap();
    let p = probe(&chromium_run(&bin, &d, &file_url(&dir.join("replay.html"), "t=0.005"), "--dump-dom"));
    assert_no_errors(&p);
    assert_eq!((p["sample_index"].as_u64(), p["vehicle_visible"].as_bool()), (Some(1), Some(false)), "{p}");
    let (header, rows) = csv_rows(&dir);
    assert_eq!(rows[1][header.iter().position(|h| h == "y").unwrap()], "NaN");
    assert_eq!(p["now"]["x, y, z [m]"], format!("{}, NaN, {}", rows[1][4], rows[1][6]), "{p}");
    assert_eq!(p["now"]["h̄ [m²]"], rows[1][header.iter().position(|h| h == "h_bar").unwrap()], "{p}");
}

/// `name`'s rows of a report CSV (header dropped).
fn csv_of(report: &Path, name: &str) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(report.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    text.lines().skip(1).map(|l| l.split(',').map(String::from).collect()).collect()
}

/// The probe's overlays at its time against the report's files: the filter's points drawn are
/// `filter_points.csv`'s rows of the latest logged step at or before the shown time (every step
/// is in the page of a short flight); each drawn scan is the sensor's scan in `ranges.csv` with
/// as many returns, every `stride`-th drawn, at most one kept-scan period old.
fn assert_overlays(report: &Path, p: &serde_json::Value) -> (usize, usize) {
    let t: f64 = p["t_shown"].as_str().unwrap().parse().unwrap();
    let fp = csv_of(report, "filter_points.csv");
    // The step drawn (a logged step without points has no row): at most one logging period
    // (0.1 s) before the shown time, no row of a later step up to it.
    let step: f64 = p["filter_points_t"].as_str().expect("a logged step").parse().unwrap();
    assert!((0.0..0.1 + 1e-9).contains(&(t - step)), "{step} vs {t}: {p}");
    let later =
        fp.iter().filter(|r| (step + 1e-9..=t + 1e-9).contains(&r[0].parse::<f64>().unwrap())).count();
    assert_eq!(later, 0, "{p}");
    let n_fp = fp.iter().filter(|r| Some(r[0].as_str()) == p["filter_points_t"].as_str()).count();
    assert_eq!(p["filter_points_drawn"].as_u64(), Some(n_fp as u64), "{p}");
    let ranges = csv_of(report, "ranges.csv");
    let stride = p["returns_stride"].as_u64().unwrap() as usize;
    let mut drawn = 0;
    for sc in p["returns_scans"].as_array().unwrap() {
        let (st, sensor) = (sc["t"].as_str().unwrap(), sc["sensor"].as_str().unwrap());
        let hits = ranges.iter().filter(|r| r[0] == st && r[1] == sensor && !r[3].is_empty()).count();
        assert!(
            ranges.iter().any(|r| r[0] == st && r[1] == sensor),
            "no scan {st} of {sensor} in ranges.csv"
        );
        assert_eq!(sc["hits"].as_u64(), Some(hits as u64), "{p}");
        assert_eq!(sc["drawn"].as_u64(), Some(hits.div_ceil(stride) as u64), "{p}");
        let age = t - st.parse::<f64>().unwrap();
        assert!(
            (0.0..=1.0 / parapet_sim::report::replay::MAX_SCANS_PER_S + 0.0041).contains(&age),
            "{age}: {p}"
        );
        drawn += hits.div_ceil(stride);
    }
    assert_eq!(p["returns_drawn"].as_u64(), Some(drawn as u64), "{p}");
    (n_fp, drawn)
}

/// The page's lists against `trajectory.csv`: every guidance-mode change listed at its row's
/// time and name, the first filter intervention at the first `filter_active` row, and the
/// failsafe guidance entered at its row (when the run has one).
fn assert_lists(report: &Path, p: &serde_json::Value) {
    let (header, rows) = csv_rows(report);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let mut want = Vec::new();
    let mut last = "";
    for r in &rows {
        if r[col("mode")] != last {
            last = &r[col("mode")];
            want.push(format!("{} s  guidance {last}", r[0]));
        }
    }
    let shown: Vec<String> = p["modes_shown"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .filter(|v| v.contains("guidance"))
        .collect();
    assert_eq!(shown, want, "{p}");
    if let Some(r) = rows.iter().find(|r| r[col("filter_active")] == "1") {
        let first = p["barriers_shown"][0].as_str().unwrap();
        assert!(first.starts_with(&format!("{} s  – ", r[0])), "{first} vs {}", r[0]);
    }
    let events: Vec<&str> =
        p["events_shown"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    // Every entry into a failsafe's guidance, at its row.
    let failsafe: Vec<&str> =
        parapet_sim::report::replay::FAILSAFE_GUIDANCE.iter().map(|m| m.as_str()).collect();
    let mut last = "";
    let mut entered = 0;
    for r in &rows {
        let m = r[col("mode")].as_str();
        if m != last && failsafe.contains(&m) {
            let e = format!("{} s  guidance entered: {m}", r[0]);
            assert!(events.contains(&e.as_str()), "{e} not in {events:?}");
            entered += 1;
        }
        last = m;
    }
    assert_eq!(events.iter().filter(|e| e.contains("guidance entered")).count(), entered, "{events:?}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("summary.json")).unwrap()).unwrap();
    let end = format!(
        "{} s  end: {} (controller {})",
        rows.last().unwrap()[0],
        s["end_reason"].as_str().unwrap(),
        s["final_controller_state"].as_str().unwrap()
    );
    assert_eq!(events.last().copied(), Some(end.as_str()), "{events:?}");
}

/// `parapet run` of `scenes/pilot/wall.toml` with the pilot script `script` of `scenes/pilot/`
/// and a lidar into `dir/out`; the report directory.
fn fly_pilot_at_the_wall(dir: &Path, script: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/pilot");
    let out = dir.join("out");
    let (scene, script) = (root.join("wall.toml"), root.join(script));
    let args = ["run", "--scene", scene.to_str().unwrap(), "--pilot", script.to_str().unwrap()];
    // A planar lidar flies under the assumption that nothing stands or hangs out of its plane.
    let lidar = ["--perception", "lidar", "--assume", "no-overhangs,no-low-obstacles"];
    let o = parapet(&[&args[..], &lidar, &["--out", out.to_str().unwrap()]].concat());
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// A piloted flight at the wall with a lidar whose RC link is lost at 2 s (`scenes/pilot/`):
/// the page at several times draws the filter's points and the lidar's returns of that time,
/// the failsafe's guidance changes are listed at their `trajectory.csv` times.
#[test]
fn the_page_draws_the_points_and_returns_of_the_time_and_lists_the_failsafe() {
    let Some(bin) = chromium() else { return };
    let d = tmp("overlays");
    let out = fly_pilot_at_the_wall(&d, "rc_loss.pilot.toml");
    let (header, rows) = csv_rows(&out);
    let modes: Vec<&str> =
        rows.iter().map(|r| r[header.iter().position(|h| h == "mode").unwrap()].as_str()).collect();
    assert!(modes.contains(&"Hold") && modes.contains(&"Land"), "the RC-loss failsafe holds, then lands");
    let page = out.join("replay.html");
    let (mut fp_total, mut ret_total) = (0, 0);
    for t in ["1.5", "4.2", "11"] {
        let p = probe(&chromium_run(&bin, &d, &file_url(&page, &format!("t={t}")), "--dump-dom"));
        assert_no_errors(&p);
        assert_at_row(&p, &header, &rows);
        let (a, b) = assert_overlays(&out, &p);
        fp_total += a;
        ret_total += b;
        assert_lists(&out, &p);
    }
    assert!(fp_total > 0 && ret_total > 0, "points {fp_total}, returns {ret_total}");
}

/// The office screenshot's fragment: t = 9.8 s (the filter at the coat stand), free orbit.
const SHOT: &str = "t=9.8&cam=orbit";

/// `docs/figures/replay_office.png`: the default office flight, see [`SHOT`].
#[test]
#[ignore = "writes docs/figures/replay_office.png; run by hand (docs/simulator.md)"]
fn office_screenshot() {
    let Some(bin) = chromium() else { return };
    let d = tmp("office");
    let out = d.join("out");
    let o = parapet(&["run", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let page = out.join("replay.html");
    let p = probe(&chromium_run(&bin, &d, &file_url(&page, SHOT), "--dump-dom"));
    assert_no_errors(&p);
    assert_eq!(p["on_screen"], true, "{p}");
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/figures/replay_office.png");
    chromium_run(&bin, &d, &file_url(&page, SHOT), &format!("--screenshot={}", docs.display()));
    let len = std::fs::metadata(&docs).map(|m| m.len()).unwrap_or(0);
    assert!(len > 50_000, "{} is {len} B", docs.display());
    eprintln!(
        "replay.html {} B, ready after {} ms (probe), screenshot {}",
        std::fs::metadata(&page).unwrap().len(),
        p["ready_ms"],
        docs.display()
    );
}

/// `docs/figures/replay_forest.png`: a generated forest (400 trunks, seed 1) flown at
/// `--speed 5`, follow camera at 9.5 s, the vehicle at more than 3 m/s (checked).
#[test]
#[ignore = "writes docs/figures/replay_forest.png; run by hand (docs/simulator.md)"]
fn forest_screenshot() {
    let Some(bin) = chromium() else { return };
    let d = tmp("forest");
    let scene = d.join("forest.toml");
    let s = scene.to_str().unwrap();
    let o =
        parapet(&["scene", "generate", "--kind", "forest", "--obstacles", "400", "--seed", "1", "--out", s]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let out = d.join("out");
    let o = parapet(&["run", "--scene", s, "--speed", "5", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let page = out.join("replay.html");
    let p = probe(&chromium_run(&bin, &d, &file_url(&page, "t=9.5"), "--dump-dom"));
    assert_no_errors(&p);
    assert_eq!((p["obstacle_meshes"].as_u64(), p["on_screen"].as_bool()), (Some(400), Some(true)), "{p}");
    // At speed: the shown row's speed is at least 3 m/s.
    let (header, rows) = csv_rows(&out);
    let i = assert_at_row(&p, &header, &rows);
    let v = |n: &str| rows[i][header.iter().position(|h| h == n).unwrap()].parse::<f64>().unwrap();
    let speed = (v("vx").powi(2) + v("vy").powi(2) + v("vz").powi(2)).sqrt();
    assert!(speed >= 3.0, "{speed} m/s at the shot");
    eprintln!("forest shot at {} s: {speed:.2} m/s", rows[i][0]);
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/figures/replay_forest.png");
    chromium_run(&bin, &d, &file_url(&page, "t=9.5"), &format!("--screenshot={}", docs.display()));
    let len = std::fs::metadata(&docs).map(|m| m.len()).unwrap_or(0);
    assert!(len > 50_000, "{} is {len} B", docs.display());
    eprintln!("replay.html {} B, screenshot {}", std::fs::metadata(&page).unwrap().len(), docs.display());
}

/// `docs/figures/replay_wall_slide.png`: the piloted wall slide (`scenes/pilot/wall.toml`,
/// `wall_slide.pilot.toml`: full forward and half right stick at the wall) with a lidar, at
/// 6 s in free orbit: the vehicle sliding east along the wall, the filter's points on the wall
/// (cyan) and the lidar's returns (magenta).
#[test]
#[ignore = "writes docs/figures/replay_wall_slide.png; run by hand (docs/simulator.md)"]
fn wall_slide_screenshot() {
    let Some(bin) = chromium() else { return };
    let d = tmp("wall-slide");
    let out = fly_pilot_at_the_wall(&d, "wall_slide.pilot.toml");
    let page = out.join("replay.html");
    let shot = "t=6&cam=orbit";
    let p = probe(&chromium_run(&bin, &d, &file_url(&page, shot), "--dump-dom"));
    assert_no_errors(&p);
    let (header, rows) = csv_rows(&out);
    assert_at_row(&p, &header, &rows);
    let (points, returns) = assert_overlays(&out, &p);
    assert!(points > 0 && returns > 0, "{p}");
    assert_lists(&out, &p);
    // Sliding: the filter acts at the shown time.
    assert_eq!(p["now"]["filter"], "intervened", "{p}");
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/figures/replay_wall_slide.png");
    chromium_run(&bin, &d, &file_url(&page, shot), &format!("--screenshot={}", docs.display()));
    let len = std::fs::metadata(&docs).map(|m| m.len()).unwrap_or(0);
    assert!(len > 50_000, "{} is {len} B", docs.display());
    eprintln!("replay.html {} B, screenshot {}", std::fs::metadata(&page).unwrap().len(), docs.display());
}

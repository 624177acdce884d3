//! `parapet campaign`: the CI-sized campaign (`scenes/campaigns/ci.toml`, 200
//! flights), its outputs, the worst flight's command reproducing it bit for bit,
//! shards merged byte-identical to a single-process run, merges of mixed
//! campaigns refused, and bad options refused with exit code 2.

use std::path::{Path, PathBuf};
use std::process::Command;

#[allow(dead_code)] // only the directory guard is shared here
mod common;

use parapet_sim::campaign::{
    cmd_campaign, cmd_campaign_merge, CampaignArgs, CampaignMergeArgs, IdentityArgs,
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn tmp(name: &str) -> common::TmpDir {
    common::tmp("campaign", name)
}

fn campaign(file: &Path, out: &Path, shard: Option<&str>) {
    campaign_with(file, out, shard, &[]);
}

/// [`campaign`] with `--param` options.
fn campaign_with(file: &Path, out: &Path, shard: Option<&str>, param: &[&str]) {
    let a = CampaignArgs {
        campaign: file.into(),
        out: out.into(),
        jobs: Some(2),
        shard: shard.map(String::from),
        identity: IdentityArgs {
            guidance: None,
            param: param.iter().map(|s| s.to_string()).collect(),
            params_file: None,
        },
    };
    cmd_campaign(a).unwrap_or_else(|e| panic!("{e}"));
}

fn csv_rows(p: &Path) -> Vec<Vec<String>> {
    let mut r = csv::Reader::from_path(p).unwrap();
    r.records().map(|x| x.unwrap().iter().map(String::from).collect()).collect()
}

/// The index of column `name` in `head` (a `campaign.csv` header); panics naming it when absent.
fn column(head: &[String], name: &str) -> usize {
    head.iter().position(|h| h == name).unwrap_or_else(|| panic!("column {name}"))
}

fn csv_head(p: &Path) -> Vec<String> {
    csv::Reader::from_path(p).unwrap().headers().unwrap().iter().map(String::from).collect()
}

/// The campaign's `summary.json` in `out`.
fn summary_json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// Flies a `worst.txt` command's `parapet run` arguments again (from `host-sim/`, as the
/// campaign wrote them); that run's `summary.json`.
fn rerun(args: &[&str]) -> serde_json::Value {
    let st = Command::new(env!("CARGO_BIN_EXE_parapet"))
        .args(args)
        .current_dir(root().join("host-sim"))
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let dir = args[args.iter().position(|a| *a == "--out").unwrap() + 1];
    serde_json::from_str(&std::fs::read_to_string(Path::new(dir).join("summary.json")).unwrap()).unwrap()
}

#[test]
fn ci_campaign_outputs_agree_and_the_worst_flight_reproduces() {
    let out = tmp("ci");
    campaign(&root().join("scenes/campaigns/ci.toml"), &out, None);
    let rows = csv_rows(&out.join("campaign.csv"));
    assert_eq!(rows.len(), 200);
    let head = csv_head(&out.join("campaign.csv"));
    let col = |name: &str| column(&head, name);
    let (collided, reason, clearance) = (col("collided"), col("end_reason"), col("min_clearance_m"));
    for q in ["wind_speed", "mass", "k_f", "motor_tau", "fix_dropout_length", "speed"] {
        col(q);
    }
    let summary = summary_json(&out);
    let n_coll = rows.iter().filter(|r| r[collided] == "true").count() as u64;
    let all = &summary["all"];
    assert_eq!(all["flights"], 200);
    assert_eq!(all["failed"], 0);
    assert_eq!(all["collisions"].as_u64().unwrap(), n_coll);
    let rate = all["collision_rate"].as_f64().unwrap();
    assert!((rate - n_coll as f64 / 200.0).abs() < 1e-12);
    assert!(all["collision_rate_upper_95"].as_f64().unwrap() > rate);
    // Per-scene rows add up; the collisions' places add up.
    let per: u64 =
        summary["per_scene"].as_object().unwrap().values().map(|s| s["flights"].as_u64().unwrap()).sum();
    assert_eq!(per, 200);
    let placed: u64 = summary["collisions_by_obstacle"]
        .as_object()
        .unwrap()
        .values()
        .flat_map(|m| m.as_object().unwrap().values().map(|c| c.as_u64().unwrap()))
        .sum();
    assert_eq!(placed, n_coll);
    let min = rows.iter().map(|r| r[clearance].parse::<f64>().unwrap()).fold(f64::INFINITY, f64::min);
    assert_eq!(all["min_clearance_m"]["p0"].as_f64().unwrap(), min);
    for f in
        ["min_clearance_hist.svg", "outcome_vs_wind_speed.svg", "outcome_vs_mass.svg", "outcome_vs_speed.svg"]
    {
        assert!(out.join(f).is_file(), "{f}");
    }
    assert_worst_reports(&out, &summary, &rows, &head);
    // The worst flight's command flies it again, bit for bit.
    let worst = &summary["worst"][0];
    let flight = worst["flight"].as_u64().unwrap() as usize;
    assert_eq!(worst["min_clearance_m"].as_f64().unwrap(), min);
    let text = std::fs::read_to_string(out.join("worst.txt")).unwrap();
    let cmd = text.lines().find(|l| l.starts_with("parapet run")).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("parapet run")).count(), 10);
    let args: Vec<&str> = cmd.split(' ').skip(1).collect();
    assert!(args.iter().all(|a| !a.starts_with('\'')), "simple words: {cmd}");
    let s = rerun(&args);
    assert_eq!(
        s["min_clearance_m"].as_f64().unwrap().to_bits(),
        rows[flight][clearance].parse::<f64>().unwrap().to_bits()
    );
    assert_eq!(s["end_reason"].as_str().unwrap(), rows[flight][reason]);
    assert_eq!(
        s["tracking_rms_m"].as_f64().unwrap(),
        rows[flight][col("tracking_rms_m")].parse::<f64>().unwrap()
    );
    std::fs::remove_dir_all(&out).ok();
}

/// The first `WORST_REPORTS` worst flights have their full report (flown again after the
/// campaign): its `summary.json` is the flight's campaign row to the bit, its `replay.html` draws
/// that flight (its sample count is the row's outer steps), `worst.txt` and `summary.json` name
/// it; the other worst flights have none.
fn assert_worst_reports(out: &Path, summary: &serde_json::Value, rows: &[Vec<String>], head: &[String]) {
    use parapet_sim::campaign::output::WORST_REPORTS;
    let col = |name: &str| column(head, name);
    let worst = summary["worst"].as_array().unwrap();
    assert_eq!(worst.len(), 10);
    let text = std::fs::read_to_string(out.join("worst.txt")).unwrap();
    for (k, w) in worst.iter().enumerate() {
        let flight = w["flight"].as_u64().unwrap();
        let dir = format!("worst/flight_{flight:06}");
        if k >= WORST_REPORTS {
            assert!(w["report"].is_null(), "{w}");
            assert!(!out.join(&dir).exists(), "{dir}");
            continue;
        }
        assert_eq!(w["report"], dir.as_str(), "{w}");
        assert!(text.contains(&format!("the flight in 3D: {dir}/replay.html")), "{text}");
        let row = &rows[flight as usize];
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(&dir).join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(
            s["min_clearance_m"].as_f64().unwrap().to_bits(),
            row[col("min_clearance_m")].parse::<f64>().unwrap().to_bits(),
            "{dir}"
        );
        assert_eq!(s["end_reason"], row[col("end_reason")].as_str());
        let page = std::fs::read_to_string(out.join(&dir).join("replay.html")).unwrap();
        let steps = row[col("outer_steps")].as_str();
        assert!(page.contains(&format!("\"n_samples\":{steps},")), "{dir}: {steps} samples");
        let csv_rows =
            std::fs::read_to_string(out.join(&dir).join("trajectory.csv")).unwrap().lines().count();
        assert_eq!(csv_rows, steps.parse::<usize>().unwrap() + 1, "{dir}: header and one row per step");
    }
}

/// A small campaign over two scenes (absolute paths), `seed` and `flights` given.
fn small(dir: &Path, name: &str, seed: u64, flights: u64) -> PathBuf {
    let s = root().join("scenes");
    let text = format!(
        "name = \"small\"\nseed = {seed}\nflights = {flights}\n\
         [[scenes]]\nfile = {:?}\nstraight = true\n[[scenes]]\nfile = {:?}\n\
         [draw]\nwind_speed = {{ uniform = [0, 2] }}\nmass = {{ normal = [1.0, 0.1], min = 0.8, max = 1.2 }}\n\
         fix_dropout_rate = 0.5\nfix_dropout_length = 0.2\nturbulence_sigma = 0.3\n",
        s.join("one_sphere.toml").display().to_string(),
        s.join("narrow_passage.toml").display().to_string()
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn shards_merge_byte_identical_and_mixed_campaigns_are_refused() {
    let dir = tmp("shards");
    let c = small(&dir, "small.toml", 7, 9);
    campaign(&c, &dir.join("single"), None);
    for i in 1..=3 {
        campaign(&c, &dir.join(format!("s{i}")), Some(&format!("{i}/3")));
    }
    let shards: Vec<PathBuf> = [3, 1, 2].iter().map(|i| dir.join(format!("s{i}"))).collect();
    let merge = |shards: Vec<PathBuf>, file: &Path| {
        cmd_campaign_merge(CampaignMergeArgs {
            campaign: file.into(),
            out: dir.join("merged"),
            shards,
            identity: IdentityArgs { guidance: None, param: Vec::new(), params_file: None },
        })
    };
    merge(shards.clone(), &c).unwrap_or_else(|e| panic!("{e}"));
    for f in ["campaign.csv", "summary.json"] {
        let (a, b) = (
            std::fs::read(dir.join("single").join(f)).unwrap(),
            std::fs::read(dir.join("merged").join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs");
    }
    // The merge writes the worst flights' reports as a single process does.
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("merged/summary.json")).unwrap()).unwrap();
    let report = s["worst"][0]["report"].as_str().expect("the worst flight's report");
    for d in ["single", "merged"] {
        assert!(dir.join(d).join(report).join("replay.html").is_file(), "{d}/{report}/replay.html");
    }
    assert_eq!(
        csv_rows(&dir.join("s2/campaign.csv")).iter().map(|r| r[0].clone()).collect::<Vec<_>>(),
        ["1", "4", "7"]
    );
    // Another campaign's shard, a shard twice, a shard missing: refused, naming why.
    let other = small(&dir, "other.toml", 8, 9);
    campaign(&other, &dir.join("o2"), Some("2/3"));
    let e = merge(vec![shards[0].clone(), shards[1].clone(), dir.join("o2")], &c).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    assert!(e.to_string().contains("another campaign") && e.to_string().contains("identity"), "{e}");
    let e = merge(vec![shards[0].clone(), shards[1].clone(), shards[1].clone()], &c).unwrap_err().to_string();
    assert!(e.contains("twice"), "{e}");
    let e = merge(vec![shards[0].clone(), shards[1].clone()], &c).unwrap_err().to_string();
    assert!(e.contains("missing") && e.contains("2/3"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_campaign_options_exit_2_naming_the_option() {
    let dir = tmp("bad");
    let c = small(&dir, "small.toml", 1, 2);
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_parapet")).args(args).output().unwrap();
    let cs = c.display().to_string();
    for (args, want) in [
        (vec!["campaign", cs.as_str(), "--shard", "4/3"], "--shard"),
        (vec!["campaign", cs.as_str(), "--jobs", "0"], "--jobs"),
        (vec!["campaign", "no-such-campaign.toml"], "no-such-campaign.toml"),
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The navigation CI campaign (`scenes/campaigns/navigation_ci.toml`): every flight's
/// position source is drawn, recorded in `campaign.csv` and tabled per source in
/// `summary.json` (the rows add up); no collision the filter did not flag beforehand; the
/// worst flight's command (with its `--position-source`) flies it again bit for bit.
#[test]
fn the_navigation_campaign_draws_records_and_tables_the_position_source() {
    let out = tmp("nav");
    campaign(&root().join("scenes/campaigns/navigation_ci.toml"), &out, None);
    let rows = csv_rows(&out.join("campaign.csv"));
    assert_eq!(rows.len(), 24);
    let head = csv_head(&out.join("campaign.csv"));
    let col = |name: &str| column(&head, name);
    let (src, collided, clearance) = (col("position_source"), col("collided"), col("min_clearance_m"));
    let summary = summary_json(&out);
    let per = summary["per_source"].as_object().unwrap();
    for name in ["mocap", "gps", "rtk", "vio"] {
        let n = rows.iter().filter(|r| r[src] == name).count() as u64;
        assert!(n > 0, "{name} flown");
        let k = rows.iter().filter(|r| r[src] == name && r[collided] == "true").count() as u64;
        let r = &per[name];
        assert_eq!((r["flights"].as_u64(), r["collisions"].as_u64()), (Some(n), Some(k)), "{name}: {r}");
        assert!(r["collision_rate_upper_95"].as_f64().unwrap() > 0.0 && r["goal_rate"].is_number());
    }
    assert_eq!(per.len(), 4, "{per:?}");
    // No collision the filter did not flag beforehand, with any source (`vio`'s flight 2,
    // one_sphere, hit the sphere unflagged while the margin took the drift's σ at t instead of
    // its bound over the flight: docs/filter.md § 18).
    for name in ["mocap", "gps", "rtk", "vio"] {
        assert_eq!(per[name]["collisions_unflagged"], 0, "{name}: {}", per[name]);
    }
    // The worst flight's command names its source and flies it again, bit for bit.
    let worst = summary["worst"][0]["flight"].as_u64().unwrap() as usize;
    let text = std::fs::read_to_string(out.join("worst.txt")).unwrap();
    let cmd = text.lines().find(|l| l.starts_with("parapet run")).unwrap();
    let args: Vec<&str> = cmd.split(' ').skip(1).collect();
    let k = args.iter().position(|a| *a == "--position-source").expect("--position-source in the command");
    assert_eq!(args[k + 1], rows[worst][src]);
    let s = rerun(&args);
    assert_eq!(
        s["min_clearance_m"].as_f64().unwrap().to_bits(),
        rows[worst][clearance].parse::<f64>().unwrap().to_bits()
    );
    std::fs::remove_dir_all(&out).ok();
}

/// The speed CI campaign (`scenes/campaigns/speed_ci.toml`, issue 36): each flight's perception
/// is drawn, passed as `--perception`, recorded in `campaign.csv` and tabled per perception in
/// `summary.json`; a drawn sensor set the pre-flight coverage check refuses (the planar lidar:
/// no world assumption given) is not flown and its row names the gap, so the campaign ends
/// with "could not be flown" (exit 4) and keeps the others; no collision the filter did not
/// flag beforehand.
#[test]
fn the_speed_campaign_draws_the_perception_and_refuses_a_set_that_cannot_see_the_sweep() {
    let out = tmp("speed");
    let file = root().join("scenes/campaigns/speed_ci.toml");
    let a = CampaignArgs {
        campaign: file.clone(),
        out: out.to_path_buf(),
        jobs: Some(2),
        shard: None,
        identity: IdentityArgs { guidance: None, param: Vec::new(), params_file: None },
    };
    match cmd_campaign(a) {
        Err(e) => assert!(e.to_string().contains("could not be flown"), "{e}"),
        Ok(()) => panic!("the planar lidar's draws must be refused before flight"),
    }
    let rows = csv_rows(&out.join("campaign.csv"));
    assert_eq!(rows.len(), 20);
    let head = csv_head(&out.join("campaign.csv"));
    let col = |name: &str| column(&head, name);
    let (perc, end, error) = (col("perception"), col("end_reason"), col("error"));
    let c = parapet_sim::campaign::spec::Campaign::load(&file).unwrap();
    for (i, r) in rows.iter().enumerate() {
        let args = c.flight(i as u64).args;
        let k = args.iter().position(|a| a == "--perception").expect("the drawn perception is an option");
        assert_eq!(args[k + 1], r[perc], "flight {i}");
        if r[perc] == "lidar" {
            assert_eq!(r[end], "error", "flight {i}: {r:?}");
            assert!(r[error].contains("refused before flight (coverage)"), "flight {i}: {}", r[error]);
        } else {
            assert_ne!(r[end], "error", "flight {i} flies: {r:?}");
        }
    }
    let summary = summary_json(&out);
    let per = summary["per_perception"].as_object().unwrap();
    for name in ["truth", "lidar", "lidar3d", "camera", "tof"] {
        let n = rows.iter().filter(|r| r[perc] == name).count() as u64;
        assert!(n > 0, "{name} drawn");
        assert_eq!(per[name]["flights"].as_u64(), Some(n), "{name}: {}", per[name]);
        assert_eq!(per[name]["collisions_unflagged"], 0, "{name}: {}", per[name]);
    }
    assert_eq!(per["lidar"]["failed"], per["lidar"]["flights"]);
    std::fs::remove_dir_all(&out).ok();
}

/// `--position-source` of `parapet run`: an unknown name exits 2 naming the option, the value
/// and the allowed names.
#[test]
fn an_unknown_position_source_exits_2_naming_it() {
    let scene = root().join("scenes/one_sphere.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_parapet"))
        .args(["run", "--scene", &scene.display().to_string(), "--straight", "--position-source", "galileo"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    for want in ["--position-source", "galileo", "mocap, gps, rtk, vio"] {
        assert!(err.contains(want), "`{want}` not in {err}");
    }
}

/// `parapet campaign --param` (issue 37): every flight flies the parameter (its `campaign.csv`
/// column is the value the flight's controller flew, read back; a slower trajectory
/// acceleration takes measurably longer to the goal), it wins over the file's `[run]` key,
/// `summary.json` records it, a drawn parameter or a bad one is refused with exit 2, and
/// `campaign-merge` refuses shards flown with other `--param`s, naming the parameter.
#[test]
fn campaign_param_flies_every_flight_and_merges_only_with_the_same_params() {
    let dir = tmp("param");
    let scene = root().join("host-sim/tests/data/scenes/cli_params_open.toml");
    let file = dir.join("p.toml");
    std::fs::write(
        &file,
        format!(
            "name = \"param\"\nseed = 3\nflights = 2\n[run]\nTRJ_ACC = 3.0\n\
             [[scenes]]\nfile = {:?}\nstraight = true\n[draw]\nCBF_ACC_BOUND = {{ uniform = [0.5, 2.0] }}\n",
            scene.display().to_string()
        ),
    )
    .unwrap();
    // Time to the goal and the TRJ_ACC column of each flight.
    let flown = |out: &Path| -> Vec<(f64, String)> {
        let head = csv_head(&out.join("campaign.csv"));
        let (t, acc) = (column(&head, "time_to_goal_s"), column(&head, "TRJ_ACC"));
        csv_rows(&out.join("campaign.csv"))
            .iter()
            .map(|r| (r[t].parse::<f64>().unwrap_or(f64::NAN), r[acc].clone()))
            .collect()
    };
    let (slow, fast) = (dir.join("slow"), dir.join("fast"));
    campaign_with(&file, &slow, None, &["TRJ_ACC=0.1"]);
    campaign_with(&file, &fast, None, &["TRJ_ACC=2"]);
    let (s, f) = (flown(&slow), flown(&fast));
    println!("time to goal: TRJ_ACC=0.1 {s:?}, TRJ_ACC=2 {f:?}");
    for ((ts, accs), (tf, accf)) in s.iter().zip(&f) {
        assert_eq!((accs.as_str(), accf.as_str()), ("0.1", "2"), "the value each flight flew");
        assert!(ts.is_finite() && tf.is_finite(), "both reach the goal: {ts} {tf}");
        assert!(*ts > tf + 2.0, "0.1 m/s² takes longer than 2 m/s²: {ts} vs {tf}");
    }
    assert_eq!(summary_json(&slow)["params_set"]["TRJ_ACC"], 0.1);
    let worst = std::fs::read_to_string(slow.join("worst.txt")).unwrap();
    assert!(worst.contains("--param TRJ_ACC=0.1") && !worst.contains("TRJ_ACC=3"), "{worst}");
    // Shards flown with --param TRJ_ACC=0.1 merge only when given the same.
    for i in 1..=2 {
        campaign_with(&file, &dir.join(format!("s{i}")), Some(&format!("{i}/2")), &["TRJ_ACC=0.1"]);
    }
    let merge = |param: &[&str]| {
        cmd_campaign_merge(CampaignMergeArgs {
            campaign: file.clone(),
            out: dir.join("merged"),
            shards: vec![dir.join("s1"), dir.join("s2")],
            identity: IdentityArgs {
                guidance: None,
                param: param.iter().map(|s| s.to_string()).collect(),
                params_file: None,
            },
        })
    };
    for (param, got, want) in
        [(vec!["TRJ_ACC=2"], "TRJ_ACC=0.1", "TRJ_ACC=2"), (vec![], "TRJ_ACC=0.1", "not set")]
    {
        let e = merge(&param).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let e = e.to_string();
        assert!(e.contains("params.TRJ_ACC") && e.contains(got) && e.contains(want), "{param:?}: {e}");
    }
    merge(&["TRJ_ACC=0.1"]).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        std::fs::read(slow.join("campaign.csv")).unwrap()
            == std::fs::read(dir.join("merged/campaign.csv")).unwrap()
    );
    // Refused before any flight, exit 2, naming the parameter and why.
    let fs = file.display().to_string();
    for (param, want) in [
        ("NO_SUCH=1", "NO_SUCH"),
        ("TRJ_ACC=100", "0.1 ≤ TRJ_ACC ≤ 15"),
        ("CBF_ACC_BOUND=1", "draws this parameter"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_parapet"))
            .args(["campaign", &fs, "--param", param, "--out", dir.join("bad").to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{param}: {err}");
        assert!(err.contains(want) && err.contains("--param"), "{param}: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

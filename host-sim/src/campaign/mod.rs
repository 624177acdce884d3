//! `parapet campaign`: a Monte Carlo campaign of N flights over a list of scenes,
//! each flight's disturbances, vehicle mismatch, faults and controller parameters
//! drawn from the distributions of a campaign file ([`spec`]), on `--jobs`
//! threads, optionally one shard of a job array (`--shard I/N`), with
//! `parapet campaign-merge` joining the shards. See `docs/robustness.md`.
//!
//! Each flight is flown exactly as `parapet run` with the flight's options
//! ([`spec::FlightDraw::args`], through [`crate::cli::run_config_from_args`]) plus
//! its drawn disturbances, so the command printed for a worst flight (`parapet run
//! <options> --disturbances <out>/worst/flight_NNNNNN.toml`) reproduces it bit for bit.
//! Flight i's draws depend only on (campaign seed, i): a shard flies the flights
//! with i mod N = I − 1, and the merged files equal a single-process run's byte for byte.
//! `--guidance`, `--params FILE` and `--param NAME=VALUE` set every flight's options over the
//! file's `[run]` keys ([`spec::Campaign::with_params`]) and enter the campaign's identity:
//! `campaign-merge` takes the same and refuses shards flown with other ones, naming the parameter.
//!
//! Outputs ([`output`]): `campaign.csv`, `summary.json`, `worst.txt` (the commands),
//! `worst/*.toml`, the full `parapet run` report of the [`output::WORST_REPORTS`] worst flights
//! (flown again after the campaign, one at a time: `worst/flight_NNNNNN/`, with `replay.html`), plots (`min_clearance_hist.svg`, `outcome_vs_<quantity>.svg`) and
//! `timing.json` (wall time; the only file that differs between runs). A shard
//! writes its `campaign.csv` and `shard.json` only.
//!
//! Memory: one row per flight (the samples of a flight are dropped when it ends; a worst
//! flight's report is written from a second flight of it, not from kept samples);
//! time: the flights' durations are bounded as `parapet run`'s.
//!
//! May import: `crate::cli` (run options, errors), `crate::fc` (the in-process run), `crate::flight::runner`,
//! `crate::report`, `crate::sim::disturbance`,
//! `crate::input`, rayon, indicatif, clap, serde.

pub mod output;
pub mod spec;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, Context};
use clap::Args;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cli::{run_config_from_args, CliError};
use crate::input::InputError;
use output::{Outcome, Row};
use parapet_core::outer::guidance::MissionGuidance;
use spec::Campaign;

/// Options of `parapet campaign`.
#[derive(Debug, Args)]
pub struct CampaignArgs {
    /// Campaign file (TOML; see docs/robustness.md and scenes/campaigns/).
    pub campaign: PathBuf,
    /// Output directory.
    #[arg(long, default_value = "out/campaign")]
    pub out: PathBuf,
    /// Flights flown in parallel (default: every core; 1 ≤ jobs ≤ 256).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Fly only shard I of N (1 ≤ I ≤ N ≤ 100000): the flights with index mod N = I − 1;
    /// writes campaign.csv and shard.json for `parapet campaign-merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// The options that set the flights' parameters (part of the campaign's identity).
    #[command(flatten)]
    pub identity: IdentityArgs,
}

/// The options of `parapet campaign` that enter the campaign's identity: `campaign-merge`
/// takes the same ones and refuses shards flown with others.
#[derive(Debug, Args)]
pub struct IdentityArgs {
    /// Mission guidance of every flight (MIS_GUIDANCE): trajectory | paper, over the file's
    /// `[run] guidance`; part of the campaign's identity (give it to `campaign-merge` too).
    #[arg(long, value_parser = crate::cli::values::parse_guidance)]
    pub guidance: Option<MissionGuidance>,
    /// Set a parameter by name for every flight (repeatable), as `parapet run --param NAME=VALUE`:
    /// over the file's `[run]` keys, under its `[draw]`s (a drawn parameter is refused); part
    /// of the campaign's identity (give it to `campaign-merge` too).
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub param: Vec<String>,
    /// A QGroundControl `.params` file for every flight, as `parapet run --params` (before
    /// `--param`; over `[run]`, under `[draw]`); part of the campaign's identity.
    #[arg(long = "params", value_name = "FILE")]
    pub params_file: Option<PathBuf>,
}

impl IdentityArgs {
    /// The campaign file with these options applied.
    fn load(&self, file: &Path) -> Result<Campaign, CliError> {
        Ok(Campaign::load(file)?
            .with_params(self.params_file.as_deref(), &self.param)?
            .with_guidance(self.guidance))
    }
}

/// Options of `parapet campaign-merge`.
#[derive(Debug, Args)]
pub struct CampaignMergeArgs {
    /// The campaign file the shards flew.
    #[arg(long)]
    pub campaign: PathBuf,
    /// Output directory of the merged campaign.
    #[arg(long, default_value = "out/campaign")]
    pub out: PathBuf,
    /// The shards' output directories (each with campaign.csv and shard.json).
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// The `--guidance`, `--param` and `--params` the shards flew with (the campaign's identity).
    #[command(flatten)]
    pub identity: IdentityArgs,
}

/// `shard.json`: what a shard flew.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardManifest {
    /// Campaign name.
    pub campaign: String,
    /// Campaign identity (campaign, scene and path files).
    pub identity: String,
    /// Flights of the whole campaign.
    pub flights: u64,
    /// This shard, 1-based.
    pub shard_index: u64,
    /// Number of shards.
    pub shard_count: u64,
    /// Rows in this shard's campaign.csv.
    pub rows: u64,
    /// The parameters set on the command line (`--param`, `--params`): name → value.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub params: std::collections::BTreeMap<String, f64>,
}

fn parse_shard(s: &str) -> Result<(u64, u64), InputError> {
    let err =
        || InputError::option("shard", "not a shard I/N").value(s).allowed("I/N with 1 ≤ I ≤ N ≤ 100000");
    let (i, n) = s.split_once('/').ok_or_else(err)?;
    let (i, n): (u64, u64) = (i.trim().parse().map_err(|_| err())?, n.trim().parse().map_err(|_| err())?);
    if !(1 <= i && i <= n && n <= 100_000) {
        return Err(err());
    }
    Ok((i, n))
}

/// The scene and run configuration of flight `i` of `c`: its `parapet run` options plus its
/// drawn disturbances, the drawn plant checked as `--disturbances` would check it (so the
/// worst-flight command flies too). The error names the scene when it was read.
pub fn flight_config(
    c: &Campaign,
    i: u64,
) -> Result<(crate::world::scene::Scene, crate::flight::runner::RunConfig), (Option<String>, String)> {
    let d = c.flight(i);
    let (scene, mut cfg) = run_config_from_args(&d.args).map_err(|e| (None, e.to_string()))?;
    cfg.disturbances = d.disturbances(&cfg.disturbances, &scene.vehicle);
    if let Some(p) = &cfg.disturbances.plant {
        let checked = p.validate().map_err(|e| (e.field.to_string(), e.reason, String::new()));
        if let Err((field, value, allowed)) =
            checked.and_then(|_| crate::sim::disturbance::check_integrable(p))
        {
            let why = format!("the drawn [plant] field `{field}`: {value} {allowed}");
            return Err((Some(scene.name.clone()), why));
        }
    }
    Ok((scene, cfg))
}

/// Fly the worst flight `i` of `c` again (bit for bit as in the campaign, the command of
/// `worst.txt`) and write its full `parapet run` report — `replay.html` among it — into `dir`.
/// One flight's samples in memory at a time; they are dropped on return.
fn write_worst_report(c: &Campaign, i: u64, dir: &Path) -> Result<(), CliError> {
    let (scene, cfg) = flight_config(c, i)
        .map_err(|(_, e)| CliError::Failed(anyhow!("worst flight {i} cannot be flown again: {e}")))?;
    let out = crate::fc::control::run(&scene, &cfg, &mut |_| {})
        .map_err(|e| CliError::Failed(anyhow!("worst flight {i} flown again: {e:#}")))?;
    for w in crate::cli::report_out::write_run_report(dir, &scene, &cfg, &out, "run")? {
        eprintln!("warning: worst flight {i}: {w}");
    }
    Ok(())
}

/// The `--perception` value of a flight's options (the last given), else `truth`.
fn perception_of(args: &[String]) -> &str {
    args.iter()
        .rposition(|a| a == "--perception")
        .and_then(|k| args.get(k + 1))
        .map_or("truth", |s| s.as_str())
}

/// Fly flight `i` of `c`.
pub fn fly(c: &Campaign, i: u64) -> Row {
    let d = c.flight(i);
    let mut row = Row {
        flight: i,
        scene: c.scenes[d.scene]
            .file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        seed: d.seed,
        position_source: d.position_source.map(|s| s.as_str().to_string()).unwrap_or_default(),
        perception: String::new(),
        values: d.values.values().copied().chain(c.set_columns().iter().map(|n| c.params_set[n])).collect(),
        outcome: Outcome::default(),
    };
    let failed = |mut row: Row, e: String| {
        row.outcome = Outcome { end_reason: "error".into(), error: e, ..Default::default() };
        row
    };
    let (scene, cfg) = match flight_config(c, i) {
        Ok(x) => x,
        Err((scene, e)) => {
            if let Some(name) = scene {
                row.scene = name;
            }
            return failed(row, e);
        }
    };
    row.scene = scene.name.clone();
    row.position_source = cfg.sensors.position_source.as_str().to_string();
    row.perception = perception_of(&d.args).to_string();
    // The set parameters' columns: the values the flight's controller flies, read back.
    if let Ok(cbf) = cfg.cbf_params() {
        let p = crate::flight::runner::controller_params(&scene, &cfg, cbf, cfg.variant);
        for (k, name) in c.set_columns().iter().enumerate() {
            let Some(i) = parapet_core::params::index_of(name) else { continue };
            let v = (parapet_core::params::TABLE[i].get)(&p);
            if let Some(slot) = row.values.get_mut(d.values.len() + k) {
                *slot = format!("{v}").parse().unwrap_or(f64::from(v));
            }
        }
    }
    // The pre-flight coverage check of `parapet run`: a sensor set that cannot see the sweep
    // without an assumption the flight was not given does not fly.
    match crate::flight::runner::coverage_gaps(&scene, &cfg) {
        Err(e) => return failed(row, format!("{e:#}")),
        Ok(gaps) => {
            let refused: Vec<&str> =
                gaps.iter().filter(|g| g.refuses(&cfg.sensors.assume)).map(|g| g.text.as_str()).collect();
            if !refused.is_empty() {
                return failed(row, format!("refused before flight (coverage): {}", refused.join("; ")));
            }
        }
    }
    match crate::fc::control::run(&scene, &cfg, &mut |_| {}) {
        Err(e) => failed(row, format!("{e:#}")),
        Ok(out) => {
            let s = &out.summary;
            let count = |f: &dyn Fn(&crate::report::Sample) -> bool| {
                out.samples.iter().filter(|x| f(x)).count() as u64
            };
            row.outcome = Outcome {
                collided: s.collided,
                collision_with: s.collision_with.clone().unwrap_or_default(),
                reached_goal: s.reached_goal,
                end_reason: s.end_reason.clone(),
                min_clearance_m: s.min_clearance_m,
                min_h_bar: s.min_h_bar,
                tracking_rms_m: s.tracking_rms_m,
                filter_active_steps: count(&|x| x.filter.intervened),
                unavoidable_steps: count(&|x| x.filter.unavoidable),
                infeasible_steps: count(&|x| x.filter.infeasible),
                deadlock_steps: count(&|x| x.safety.deadlock),
                obstacles_dropped_steps: count(&|x| x.safety.obstacles_dropped > 0),
                outer_steps: out.samples.len() as u64,
                sim_time_s: s.sim_time_s,
                time_to_goal_s: s.time_to_goal_s,
                error: String::new(),
            };
            row
        }
    }
}

/// Fly the flights `indices` of `c` on `jobs` threads, with a progress bar on a terminal.
pub fn fly_all(c: &Campaign, indices: &[u64], jobs: usize) -> anyhow::Result<Vec<Row>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .map_err(|e| anyhow!("cannot start the thread pool: {e}"))?;
    let bar = std::io::stderr().is_terminal().then(|| {
        let pb = indicatif::ProgressBar::new(indices.len() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "campaign [{bar:40}] {pos}/{len} flights {elapsed_precise} eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    });
    let rows = pool.install(|| {
        indices
            .par_iter()
            .map(|&i| {
                let r = fly(c, i);
                if let Some(pb) = &bar {
                    pb.inc(1);
                }
                r
            })
            .collect::<Vec<Row>>()
    });
    if let Some(pb) = bar {
        pb.finish_and_clear();
    }
    Ok(rows)
}

fn create_dir(dir: &Path) -> Result<(), CliError> {
    if dir.is_file() {
        return Err(InputError::option("out", "is an existing file, not a directory")
            .value(dir.display())
            .into());
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| CliError::Failed(anyhow!("cannot create {}: {e}", dir.display())))
}

/// Write every output of the full campaign `rows` (sorted by flight) into `out`.
fn finish(c: &Campaign, rows: &[Row], out: &Path) -> Result<output::Summary, CliError> {
    let names = c.columns();
    output::write_csv(&out.join("campaign.csv"), &names, rows)?;
    let args_of = |i: u64| c.flight(i).args;
    let summary = output::summarise(c, rows, &args_of);
    // The worst flights' disturbance files and commands.
    let worst_dir = out.join("worst");
    if worst_dir.exists() {
        std::fs::remove_dir_all(&worst_dir).context("cannot clear worst/")?;
    }
    std::fs::create_dir_all(&worst_dir).context("cannot create worst/")?;
    let mut text = String::from(
        "# The worst flights of the campaign; each command reproduces its flight bit for bit.\n",
    );
    for w in &summary.worst {
        let d = c.flight(w.flight);
        let (scene, cfg) = run_config_from_args(&d.args)?;
        let dist = d.disturbances(&cfg.disturbances, &scene.vehicle);
        let file = out.join(&w.disturbances_file);
        std::fs::write(&file, dist.to_toml()).with_context(|| format!("cannot write {}", file.display()))?;
        let mut cmd: Vec<String> = vec!["parapet".into(), "run".into()];
        cmd.extend(d.args.iter().cloned());
        cmd.extend(["--disturbances".into(), file.display().to_string()]);
        cmd.extend(["--out".into(), out.join(output::worst_report_dir(w.flight)).display().to_string()]);
        let report = match &w.report {
            Some(dir) => {
                write_worst_report(c, w.flight, &out.join(dir))?;
                format!("; its report: {dir}/, the flight in 3D: {dir}/replay.html")
            }
            None => String::new(),
        };
        text += &format!(
            "# flight {} ({}, {}, min clearance {:.4} m{}{report})\n{}\n",
            w.flight,
            w.scene,
            w.end_reason,
            w.min_clearance_m,
            if w.collision_with.is_empty() { String::new() } else { format!(", hit {}", w.collision_with) },
            cmd.iter().map(|s| output::shell_word(s)).collect::<Vec<_>>().join(" ")
        );
    }
    std::fs::write(out.join("worst.txt"), text).context("cannot write worst.txt")?;
    // Written once the worst flights' reports it names are.
    let json = serde_json::to_string_pretty(&summary).map_err(|e| anyhow!("{e}"))? + "\n";
    std::fs::write(out.join("summary.json"), json).context("cannot write summary.json")?;
    for w in output::plots(out, &names, rows) {
        eprintln!("warning: {w}");
    }
    Ok(summary)
}

fn print_summary(s: &output::Summary, out: &Path) {
    let a = &s.all;
    println!(
        "campaign {}: {} flights ({} failed), {} collisions: rate {:.4} (95 % upper bound {:.4}), goal {:.3}, \
         timeout {:.3}, min clearance p0 {:.4} p5 {:.4} p50 {:.4} m",
        s.campaign,
        a.flights,
        a.failed,
        a.collisions,
        a.collision_rate,
        a.collision_rate_upper_95,
        a.goal_rate,
        a.timeout_rate,
        a.min_clearance_m["p0"],
        a.min_clearance_m["p5"],
        a.min_clearance_m["p50"]
    );
    for per in [&s.per_source, &s.per_perception] {
        if per.len() > 1 {
            for (name, r) in per {
                println!(
                    "  {name}: {} flights ({} failed), {} collisions ({} not flagged beforehand), 95 % upper bound \
                     {:.4}, goal {:.3}",
                    r.flights, r.failed, r.collisions, r.collisions_unflagged, r.collision_rate_upper_95, r.goal_rate
                );
            }
        }
    }
    println!("  report: {}", out.display());
}

/// CPU time of this process (user + system, all threads), s, from `/proc/self/stat`
/// (Linux; clock ticks of 1/100 s); `None` elsewhere.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at field 3.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// `parapet campaign`.
pub fn cmd_campaign(a: CampaignArgs) -> Result<(), CliError> {
    let c = a.identity.load(&a.campaign)?;
    let jobs = match a.jobs {
        Some(j) if !(1..=256).contains(&j) => {
            return Err(InputError::option("jobs", "out of range").value(j).allowed("1 ≤ jobs ≤ 256").into())
        }
        Some(j) => j,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let (si, sn) = match &a.shard {
        Some(s) => parse_shard(s)?,
        None => (1, 1),
    };
    // Every flight's options parse before any flies (the first flight of each scene).
    for i in 0..c.scenes.len().min(c.flights as usize) as u64 {
        run_config_from_args(&c.flight(i).args)
            .map_err(|e| CliError::BadInput(format!("{}: scenes[{i}]: {e}", a.campaign.display())))?;
    }
    create_dir(&a.out)?;
    let indices: Vec<u64> = (si - 1..c.flights).step_by(sn as usize).collect();
    let wall = Instant::now();
    let cpu0 = process_cpu_seconds();
    let rows = fly_all(&c, &indices, jobs)?;
    let wall_s = wall.elapsed().as_secs_f64();
    let cpu_s = cpu0.and_then(|c0| Some(process_cpu_seconds()? - c0));
    let sim_s: f64 = rows.iter().map(|r| r.outcome.sim_time_s).sum();
    let timing = serde_json::json!({
        "flights": rows.len(), "jobs": jobs, "wall_time_s": wall_s, "sim_time_s": sim_s, "cpu_time_s": cpu_s,
        "real_time_factor": sim_s / wall_s, "real_time_factor_per_job": sim_s / wall_s / jobs as f64,
        "real_time_factor_per_cpu_second": cpu_s.map(|c| sim_s / c),
    });
    std::fs::write(a.out.join("timing.json"), format!("{timing:#}\n")).context("cannot write timing.json")?;
    let failed = rows.iter().filter(|r| r.outcome.end_reason == "error").count();
    if sn > 1 {
        let names = c.columns();
        output::write_csv(&a.out.join("campaign.csv"), &names, &rows)?;
        let m = ShardManifest {
            campaign: c.name.clone(),
            identity: c.identity.clone(),
            flights: c.flights,
            shard_index: si,
            shard_count: sn,
            rows: rows.len() as u64,
            params: c.params_set.clone(),
        };
        let json = serde_json::to_string_pretty(&m).map_err(|e| anyhow!("{e}"))? + "\n";
        std::fs::write(a.out.join("shard.json"), json).context("cannot write shard.json")?;
        println!(
            "campaign {} shard {si}/{sn}: {} flights in {wall_s:.1} s -> {}",
            c.name,
            rows.len(),
            a.out.display()
        );
    } else {
        let s = finish(&c, &rows, &a.out)?;
        print_summary(&s, &a.out);
    }
    println!(
        "  {} flights, {sim_s:.0} s simulated in {wall_s:.1} s wall on {jobs} jobs: {:.0}x real time ({:.0}x per job{})",
        rows.len(),
        sim_s / wall_s,
        sim_s / wall_s / jobs as f64,
        cpu_s.map(|c| format!(", {:.0}x per CPU second", sim_s / c)).unwrap_or_default()
    );
    if failed > 0 {
        return Err(CliError::SomeFailed(format!(
            "{failed} flights could not be flown (end_reason error in campaign.csv)"
        )));
    }
    Ok(())
}

/// The first parameter (by name) set differently in a shard's `shard` and the merge's `given`:
/// its name, the shard's value and the given one ("not set" where absent).
fn params_difference(
    shard: &std::collections::BTreeMap<String, f64>,
    given: &std::collections::BTreeMap<String, f64>,
) -> Option<(String, String, String)> {
    let text = |m: &std::collections::BTreeMap<String, f64>, n: &str| {
        m.get(n).map_or("not set".to_string(), |x| format!("{n}={x}"))
    };
    shard
        .keys()
        .chain(given.keys())
        .filter(|n| shard.get(*n) != given.get(*n))
        .min()
        .map(|n| (n.clone(), text(shard, n), text(given, n)))
}

/// `parapet campaign-merge`.
pub fn cmd_campaign_merge(a: CampaignMergeArgs) -> Result<(), CliError> {
    let c = a.identity.load(&a.campaign)?;
    let names = c.columns();
    let mut seen: Vec<Option<PathBuf>> = Vec::new();
    let mut rows = Vec::new();
    for dir in &a.shards {
        let mp = dir.join("shard.json");
        let text = crate::input::read_text(&mp)?;
        let m: ShardManifest = serde_json::from_str(&text)
            .map_err(|e| InputError::file(mp.display(), format!("not a shard manifest: {e}")))?;
        let refuse = |field: &str, got: String, want: String| -> CliError {
            InputError::file(mp.display(), "from another campaign: refusing to merge")
                .field(field)
                .value(got)
                .allowed(want)
                .into()
        };
        if let Some((name, got, want)) = params_difference(&m.params, &c.params_set) {
            return Err(InputError::file(
                mp.display(),
                "flown with other --param / --params options: refusing to merge (give campaign-merge \
                 the shards' --param and --params)",
            )
            .field(format!("params.{name}"))
            .value(got)
            .allowed(want)
            .into());
        }
        if m.identity != c.identity {
            return Err(refuse("identity", m.identity, format!("{} ({})", c.identity, a.campaign.display())));
        }
        if m.flights != c.flights {
            return Err(refuse("flights", m.flights.to_string(), c.flights.to_string()));
        }
        if seen.is_empty() {
            seen = vec![None; m.shard_count as usize];
        }
        if m.shard_count as usize != seen.len() || !(1..=m.shard_count).contains(&m.shard_index) {
            return Err(refuse("shard_count", m.shard_count.to_string(), seen.len().to_string()));
        }
        if let Some(other) = &seen[m.shard_index as usize - 1] {
            return Err(InputError::file(mp.display(), "shard given twice")
                .field("shard_index")
                .value(format!("{} (also in {})", m.shard_index, other.display()))
                .into());
        }
        seen[m.shard_index as usize - 1] = Some(dir.clone());
        let shard_rows = output::read_csv(&dir.join("campaign.csv"), &names)
            .map_err(|e| CliError::BadInput(format!("{e:#}")))?;
        let n = m.shard_count;
        if shard_rows.len() as u64 != m.rows
            || shard_rows.iter().any(|r| r.flight % n != m.shard_index - 1 || r.flight >= c.flights)
        {
            return Err(InputError::file(
                dir.join("campaign.csv").display(),
                "rows do not match its shard.json",
            )
            .value(format!("{} rows", shard_rows.len()))
            .into());
        }
        rows.extend(shard_rows);
    }
    if let Some(k) = seen.iter().position(Option::is_none) {
        return Err(InputError::option("shards", "a shard is missing")
            .value(format!("shard {}/{}", k + 1, seen.len()))
            .into());
    }
    rows.sort_by_key(|r| r.flight);
    if rows.len() as u64 != c.flights || rows.iter().enumerate().any(|(k, r)| r.flight != k as u64) {
        return Err(CliError::BadInput(format!(
            "the shards do not hold flights 0..{} exactly once",
            c.flights
        )));
    }
    create_dir(&a.out)?;
    let s = finish(&c, &rows, &a.out)?;
    print_summary(&s, &a.out);
    Ok(())
}

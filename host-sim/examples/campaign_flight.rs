//! One campaign flight flown again with its full `parapet run` report (trajectory.csv,
//! summary.json, replay.html, …): the tool to trace a flight of a sharded campaign, whose
//! shards write only `campaign.csv` (`docs/robustness.md` § At speed). The flight is the
//! campaign's, bit for bit (`campaign::flight_config`, as `worst.txt`'s commands).
//!
//! ```sh
//! cargo run --release -p parapet-sim --example campaign_flight -- CAMPAIGN.toml FLIGHT OUT_DIR [NAME=VALUE …]
//! ```
//! `NAME=VALUE`: the campaign's `--param`s, if it was flown with any.

use anyhow::{anyhow, Context, Result};
use parapet_sim::campaign::flight_config;
use parapet_sim::campaign::spec::Campaign;
use std::path::PathBuf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, flight, out, params @ ..] = args.as_slice() else {
        return Err(anyhow!("usage: campaign_flight CAMPAIGN.toml FLIGHT OUT_DIR [NAME=VALUE …]"));
    };
    let flight: u64 = flight.parse().with_context(|| format!("FLIGHT `{flight}` is not an index"))?;
    let c = Campaign::load(&PathBuf::from(file))
        .map_err(|e| anyhow!("{e}"))?
        .with_params(None, params)
        .map_err(|e| anyhow!("{e}"))?;
    let (scene, cfg) = flight_config(&c, flight).map_err(|(_, e)| anyhow!("flight {flight}: {e}"))?;
    let run = parapet_sim::fc::control::run(&scene, &cfg, &mut |_| {})?;
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).with_context(|| format!("{}", out.display()))?;
    for w in parapet_sim::cli::report_out::write_run_report(&out, &scene, &cfg, &run, "run")
        .map_err(|e| anyhow!("{e}"))?
    {
        eprintln!("warning: {w}");
    }
    let s = &run.summary;
    println!(
        "flight {flight} ({}): collided {} with {:?}, goal {}, end {:?}, min clearance {:.4} m -> {}",
        scene.name,
        s.collided,
        s.collision_with,
        s.reached_goal,
        s.end_reason,
        s.min_clearance_m,
        out.display()
    );
    Ok(())
}

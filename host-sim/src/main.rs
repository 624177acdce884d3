//! The `parapet` binary: the command-line parser and the dispatch to the commands
//! of [`parapet_sim::cli`], [`parapet_sim::sweep`] and [`parapet_sim::campaign`].
//! Only this file sees every command (the library's modules import none above them).

use clap::{Parser, Subcommand};
use parapet_sim::cli::{self, help, CliError};
use parapet_sim::{campaign, sweep};

fn main() {
    std::process::exit(run());
}

/// Parapet: quadrotor flight with a closed-form CBF safety filter — simulator and tools.
#[derive(Debug, Parser)]
#[command(name = "parapet", version, about, long_about = None, after_help = help::top())]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Plan (or load) a path through a scene and fly it in closed loop on the 6-DOF
    /// simulator; write summary.json, trajectory.csv, flight.ulg, plots, replay.html (3D replay
    /// page) and flight.mcap (Foxglove).
    #[command(after_help = help::run(), allow_negative_numbers = true)]
    Run(cli::RunArgs),
    /// Processor-in-the-loop: fly a scene like `run`, with the real firmware binary
    /// (`parapet-firmware-qemu`) in QEMU netduinoplus2 as the flight controller, in lockstep
    /// over MAVLink; same report plus PIL figures (frames, instructions per step, real-time factor).
    #[command(after_help = help::pil(), allow_negative_numbers = true)]
    Pil(cli::PilArgs),
    /// Plan a collision-free path through a scene's static obstacles and write it as JSON.
    #[command(after_help = help::plan(), allow_negative_numbers = true)]
    Plan(cli::PlanArgs),
    /// Drive the plant open loop with rotor speeds from a CSV (t,w1,w2,w3,w4 in rad/s)
    /// and write the states (t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r; NED / FRD).
    #[command(after_help = help::replay(), allow_negative_numbers = true)]
    Replay(cli::ReplayArgs),
    /// Fly a scene over a grid of (μ, δ1[, speed]) × noise seeds in parallel; write sweep.csv
    /// and heatmaps of collision rate, min clearance and tracking RMS (paper Fig. 9).
    #[command(allow_negative_numbers = true)]
    Sweep(sweep::SweepArgs),
    /// Join the sweep.csv files of sharded sweeps (`--shard I/N`) and redraw the heatmaps.
    SweepMerge(sweep::SweepMergeArgs),
    /// Scene tools: `parapet scene generate` writes procedural forest, city, warehouse and
    /// clutter scenes (seeded, with a mission the planner connects).
    Scene(cli::scene::SceneArgs),
    /// Parameter files: `parapet params export FILE` / `import FILE` (QGroundControl `.params`,
    /// tab-separated; the metadata JSON is `cargo xtask params`).
    Params(cli::params::ParamsArgs),
    /// Onboard flight logs over MAVLink: `parapet log list --port P`, `parapet log pull --port P
    /// --out FILE` (ULog; P = udpin:HOST:PORT, udp:HOST:PORT or a serial device).
    #[command(after_help = cli::log::help())]
    Log(cli::log::LogArgs),
    /// Monte Carlo campaign: N flights over scenes with drawn wind, vehicle mismatch, faults
    /// and controller parameters; campaign.csv, summary.json, plots, the worst flights'
    /// commands; `--shard I/N` for job arrays (see docs/robustness.md).
    #[command(after_help = help::campaign())]
    Campaign(campaign::CampaignArgs),
    /// Join the shards of a campaign (`parapet campaign --shard I/N`) into its full outputs.
    #[command(after_help = help::campaign_merge())]
    CampaignMerge(campaign::CampaignMergeArgs),
}

/// Parse the process arguments, run, print errors; returns the exit code.
fn run() -> i32 {
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) | Err(CliError::StdoutClosed) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

fn dispatch(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Run(a) => cli::cmd_run(a),
        Command::Pil(a) => cli::cmd_pil(a),
        Command::Plan(a) => cli::cmd_plan(a),
        Command::Replay(a) => cli::cmd_replay(a),
        Command::Sweep(a) => sweep::cmd_sweep(a),
        Command::SweepMerge(a) => sweep::cmd_sweep_merge(a),
        Command::Scene(a) => cli::output::out(&cli::scene::cmd_scene(a)?),
        Command::Params(a) => cli::output::out(&cli::params::cmd_params(a)?),
        Command::Log(a) => cli::output::out(&cli::log::cmd_log(a)?),
        Command::Campaign(a) => campaign::cmd_campaign(a),
        Command::CampaignMerge(a) => campaign::cmd_campaign_merge(a),
    }
}

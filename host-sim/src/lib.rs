//! parapet-sim: 6-DOF quadrotor simulator, scenes, planner and the `parapet` CLI.
//!
//! * [`plant`]: rigid-body 6-DOF quadrotor (NED/FRD), RK4 at 1 kHz.
//! * [`sensors`]: IMU and position/velocity measurement with noise and latency.
//! * [`scene`]: scene files (TOML, ENU z-up) → NED obstacles, mission, overrides.
//! * [`replay`]: open-loop replay of rotor speeds from a CSV.
//! * [`planner`]: offline RRT-Connect + shortcutting planner (static obstacles, NED).
//! * [`pathfile`]: path files (JSON, ENU z-up) written by `parapet plan`.
//! * [`runner`]: the closed loop plant → sensors → controller, metrics.
//! * [`pil`]: processor-in-the-loop: the QEMU firmware flies the scene over MAVLink lockstep.
//! * [`cli`]: the `parapet` command line (`run`, `plan`, `replay`).
//! * [`report`]: summary.json, trajectory.csv, plots, summary table.
//! * [`input`]: the one error type for bad user input, and the documented limits.
//! * [`output`]: stdout that survives a closed pipe; outputs never replace inputs.
//! * [`help`]: the long help texts (defaults, limits, examples, exit codes).
//! * [`validate`]: up-front checks of a run's settings against the core's limits.
//! * [`preflight`]: pre-flight checks (start, waypoints, path vs scene) before any flight.
//! * [`campaign`]: `parapet campaign`: Monte Carlo campaigns of disturbed flights, shards and merge.
//! * [`disturbance`]: wind (steady, Dryden, gusts), vehicle mismatch, sensor/report/rotor faults.
//! * [`world`]: spatial index of the static obstacles, nearest-obstacle tracker, scene checks, generator.
pub mod campaign;
pub mod cli;
pub mod control;
pub mod disturbance;
pub mod help;
pub mod input;
pub mod output;
pub mod pathfile;
pub mod pil;
pub mod planner;
pub mod plant;
pub mod preflight;
pub mod replay;
pub mod report;
pub mod runner;
pub mod scene;
pub mod sensors;
pub mod sweep;
pub mod validate;
pub mod world;

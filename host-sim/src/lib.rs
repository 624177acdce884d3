//! parapet-sim: 6-DOF quadrotor simulator, scenes, planner and the `parapet` CLI.
//!
//! Folders by concern, listed bottom-up: a module may import only the modules
//! listed before it (the layering is checked by the workspace's
//! `tests/tests/layering.rs`, which fails on an import cycle between any two
//! sibling modules).
//!
//! * [`input`]: the one error type for bad user input, and the documented limits.
//! * [`sim`]: the simulated vehicle and its environment: 6-DOF plant, sensors,
//!   wind / mismatch / faults, open-loop replay.
//! * [`world`]: scene files, obstacle motion, the spatial index and
//!   nearest-obstacle queries, scene checks, the scene generator.
//! * [`perception`]: range sensors in the loop (`--perception`): scans by exact
//!   ray casts, latency, the core's obstacle memory, `ranges.csv`.
//! * [`plan`]: the offline planner (RRT-Connect + shortcutting) and path files.
//! * [`report`]: summary.json, trajectory.csv, plots, flight.ulg, replay.html, flight.mcap
//!   (Foxglove), summary table.
//! * [`flight`]: the closed loop plant → sensors → flight stack, its settings,
//!   metrics, up-front validation and pre-flight checks.
//! * [`fc`]: the flight stacks the loop flies: the in-process `parapet-core`
//!   controller, the processor-in-the-loop firmware in QEMU and its host twin.
//! * [`pilot`]: the simulated pilot and offboard companion (issue 21): script files, RC
//!   frames and setpoints into a flight stack, piloted runs (`--pilot`, `--offboard`).
//! * [`cli`]: the `parapet` command line (`run`, `pil`, `plan`, `replay`,
//!   `scene generate`), help texts, errors and exit codes.
//! * [`sweep`], [`campaign`]: parameter sweeps and Monte Carlo campaigns.
pub mod campaign;
pub mod cli;
pub mod decimal;
pub mod fc;
pub mod flight;
pub mod input;
pub mod perception;
pub mod pilot;
pub mod plan;
pub mod report;
pub mod sim;
pub mod sweep;
pub mod world;

//! parapet-sim: 6-DOF quadrotor simulator, scenes, planner and the `parapet` CLI.

//! The runs of a sweep: [`SweepSetup`], what every run shares (scene, base configuration,
//! pre-flight options, duration rule, the `--grid` parameters), a run's configuration from its
//! grid point (μ, δ1, speed, the `--grid` values: a parameter with a scene key as that
//! `[controller]` key, the others by name), its checks, and flying it into its `sweep.csv` row.
//!
//! May import: `super::{grid, record}`, `crate::{fc, flight, input, world}`.

use std::panic::AssertUnwindSafe;

use super::grid::{self, GridPoint};
use super::record::{self, SweepRecord};
use crate::fc::control::run;
use crate::flight::preflight::PreflightOptions;
use crate::flight::runner::{default_duration, RunConfig};
use crate::flight::validate::Given;
use crate::input::InputError;
use crate::world::scene::Scene;

/// Everything shared by the runs of one sweep.
pub struct SweepSetup {
    /// The scene.
    pub scene: Scene,
    /// Base configuration (path, filter, noise, duration rule); each run sets μ, δ1, speed, seed.
    pub base: RunConfig,
    /// Pre-flight options (path file, `--foreign-path`).
    pub preflight: PreflightOptions,
    /// The scene's `[sim] duration` is set: every run flies the base duration.
    /// Otherwise a run's duration is `runner::default_duration` at its speed, at
    /// most [`SweepSetup::duration_limit`].
    pub scene_duration: bool,
    /// `--duration`, s.
    pub duration_limit: Option<f64>,
    /// What `validate::check_run` is told: the grid's options and `--max-duration`.
    pub given: Given,
    /// The parameters of the `--grid` axes, in their order.
    pub axes: Vec<&'static parapet_core::params::Param>,
}

impl SweepSetup {
    /// The configuration of run `p`, and its scene (the run's speed and `--grid` values set:
    /// a parameter with a scene key as that `[controller]` key, the others by name).
    pub fn config(&self, p: &GridPoint) -> Result<(Scene, RunConfig), InputError> {
        let mut scene = self.scene.clone();
        let mut cfg = self.base.clone();
        let grid_err = |d: &parapet_core::params::Param, x: f64, e: String| {
            InputError::option("grid", e).field(d.name).value(x)
        };
        let mut keyed = false;
        for (d, &x) in self.axes.iter().zip(&p.params) {
            if d.key.is_some() {
                scene.apply_param(d, x).map_err(|e| grid_err(d, x, e))?;
                keyed = true;
            } else {
                cfg.param_overrides.push((d.name, x as f32));
            }
        }
        if keyed {
            // What the scene's [controller] table decides, again (the --grid values set there).
            let fresh = RunConfig::for_scene(&scene, cfg.path.clone())
                .map_err(|e| InputError::option("grid", format!("{e:#}")))?;
            (cfg.params, cfg.accel_bound, cfg.velocity_margin, cfg.memory) =
                (fresh.params, fresh.accel_bound, fresh.velocity_margin, fresh.memory);
        }
        scene.speed = p.speed;
        cfg.params.mu = p.mu;
        cfg.params.delta1 = p.delta1;
        cfg.params.speed = p.speed;
        cfg.seed = p.seed;
        if !self.scene_duration {
            // The rule of `parapet run` at this speed, at most `--duration`.
            let rule = default_duration(&scene, &cfg.path, p.speed);
            cfg.duration = self.duration_limit.unwrap_or(f64::INFINITY).min(rule);
            // A sweep's runs end at their limit (its size check counts that work).
            cfg.default_duration_s = None;
        }
        Ok((scene, cfg))
    }

    /// `validate::check_run`, the parameter set's cross-parameter rules (when set by name) and
    /// `preflight::check` for run `p`; its scene and configuration.
    pub fn check(&self, p: &GridPoint) -> Result<(Scene, RunConfig), InputError> {
        let (scene, cfg) = self.config(p)?;
        crate::flight::validate::check_run(&scene, &cfg, &self.given)?;
        if let (false, Ok(cbf)) = (self.axes.is_empty() && cfg.param_overrides.is_empty(), cfg.cbf_params()) {
            let set = crate::flight::runner::controller_params(&scene, &cfg, cbf, cfg.variant);
            set.validate().map_err(|e| {
                InputError::option(
                    if self.axes.is_empty() { "param" } else { "grid" },
                    "the parameter set is inconsistent",
                )
                .value(e.to_string())
                .allowed("a consistent set (docs/cascade.md, the parameter table's cross-parameter rules)")
            })?;
        }
        crate::flight::preflight::check(&scene, &cfg, &self.preflight)?;
        Ok((scene, cfg))
    }

    /// The `--grid` values run `p`'s controller flies, read back from its parameter set
    /// (`None` entries: the value asked for, when the set cannot be built).
    fn flown_params(&self, p: &GridPoint, flown: Option<(&Scene, &RunConfig)>) -> Vec<f64> {
        let set = flown.and_then(|(scene, cfg)| {
            let cbf = cfg.cbf_params().ok()?;
            Some(crate::flight::runner::controller_params(scene, cfg, cbf, cfg.variant))
        });
        let asked = p.params.iter().map(|&x| grid::as_flown(x as f32));
        match set {
            Some(set) => self.axes.iter().map(|d| grid::as_flown((d.get)(&set))).collect(),
            None => asked.collect(),
        }
    }

    fn failed_row(&self, p: &GridPoint, error: String) -> SweepRecord {
        let filter = if self.base.cbf { self.base.variant.as_str().to_string() } else { "none".into() };
        SweepRecord {
            index: p.index,
            scene: self.scene.name.clone(),
            filter,
            mu: p.mu,
            delta: self.base.params.delta,
            delta1: p.delta1,
            kp: self.base.params.kp,
            kd: self.base.params.kd,
            speed: p.speed,
            seed: p.seed,
            noise: self.base.sensors.noise,
            status: record::Status::Failed,
            collided: None,
            first_collision_time_s: None,
            collision_with: None,
            min_clearance_m: None,
            min_h_bar: None,
            min_filter_h_bar: None,
            reached_goal: None,
            time_to_goal_s: None,
            final_distance_to_goal_m: None,
            reached_path_end: None,
            final_distance_to_path_end_m: None,
            tracking_rms_m: None,
            filter_active_fraction: None,
            end_reason: None,
            sim_time_s: None,
            error: Some(error.replace(['\n', '\r'], " ")),
            params: self.flown_params(p, None),
        }
    }

    /// Fly run `p` and make its row; a pre-flight refusal, a run error or a panic
    /// in the run is a `failed` row carrying the message.
    pub fn fly(&self, p: &GridPoint) -> SweepRecord {
        let (scene, cfg) = match self.check(p) {
            Ok(x) => x,
            Err(err) => return self.failed_row(p, format!("refused before the flight: {err}")),
        };
        let params = self.flown_params(p, Some((&scene, &cfg)));
        let flown = std::panic::catch_unwind(AssertUnwindSafe(|| run(&scene, &cfg, &mut |_| {})));
        let s = match flown {
            Ok(Ok(out)) => out.summary,
            Ok(Err(err)) => return self.failed_row(p, format!("{err:#}")),
            Err(panic) => {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "unknown".into());
                return self.failed_row(p, format!("internal error (panic): {what}"));
            }
        };
        SweepRecord {
            index: p.index,
            scene: s.scene,
            filter: s.filter,
            mu: p.mu,
            delta: s.params.delta,
            delta1: p.delta1,
            kp: s.params.kp,
            kd: s.params.kd,
            speed: p.speed,
            seed: p.seed,
            noise: s.noise,
            status: record::Status::Ok,
            collided: Some(s.collided),
            first_collision_time_s: s.first_collision_time_s,
            collision_with: s.collision_with,
            min_clearance_m: Some(s.min_clearance_m),
            min_h_bar: Some(s.min_h_bar),
            min_filter_h_bar: s.min_filter_h_bar,
            reached_goal: Some(s.reached_goal),
            time_to_goal_s: s.time_to_goal_s,
            final_distance_to_goal_m: Some(s.final_distance_to_goal_m),
            reached_path_end: Some(s.reached_path_end),
            final_distance_to_path_end_m: Some(s.final_distance_to_path_end_m),
            tracking_rms_m: Some(s.tracking_rms_m),
            filter_active_fraction: Some(s.filter_active_fraction),
            end_reason: Some(s.end_reason),
            sim_time_s: Some(s.sim_time_s),
            error: None,
            params,
        }
    }
}

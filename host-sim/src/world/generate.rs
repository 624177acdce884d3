//! `parapet scene generate`: procedural scenes for studies and benchmarks.
//!
//! Four kinds, all seeded (`ChaCha8Rng`; the same parameters and seed give the
//! same file byte for byte), all written as an ordinary scene TOML (ENU, z up,
//! see `scenes/README.md`) that the loader validates like any other:
//!
//! * **forest**: vertical trunks (cylinders from the ground, 8–20 m tall, above
//!   the flight ceiling) placed uniformly (a Poisson forest) at `density`
//!   trunks per m², radius uniform in `[radius_min, radius_max]`; the square
//!   area grows with the count (side `√(n / density)`).
//! * **city**: a grid of blocks (`block` m square) separated by streets of
//!   `street` m; each block holds 2 × 2 buildings (boxes, 6–40 m tall) with
//!   random setbacks.
//! * **warehouse**: rows of racks (boxes 1.2 m deep, 10 m long, above the
//!   ceiling) separated by aisles of `aisle` m, with a cross aisle every 4
//!   racks; about as deep as long.
//! * **clutter**: spheres, boxes and cylinders at random in a volume
//!   (`density` obstacles per m² of floor, 0.3–1.5 m in size).
//!
//! The mission (start and goal at 1.5 m height, `mission_length` m apart along
//! the direction (0.8, 0.6), centred in the scene) is placed where both are at
//! least 1 m clear of every obstacle, and accepted only when the planner finds
//! a path through **every** obstacle, mapped or not (default parameters, the
//! seed of the generator); otherwise another placement is tried (up to
//! [`MISSION_TRIES`]).
//!
//! **Unmapped obstacles** (`unmapped` = a fraction in [0, 1]): that share of the
//! obstacles, `round(fraction × count)` of them, chosen uniformly from a random
//! stream of their own (the seed's ChaCha8 stream 1), is written with
//! `mapped = false`. The obstacles and the mission do not depend on the
//! fraction: the same seed gives the same world at every fraction, only the
//! flags differ, and the world with all obstacles has a path. Coordinates are rounded to the millimetre
//! and duplicates (after rounding) dropped, so the file loads as written;
//! obstacles are written in Morton order of 4 m cells (neighbours, near indices).
//!
//! Owns the generator. May import: `parapet-core` (shapes), [`super::index`],
//! `crate::world::scene`, `crate::input` (errors). The planner's check comes in
//! as a function ([`generate_with`]); `crate::plan::generate` passes the planner.

use std::fmt::Write as _;

use parapet_core::obstacle::Shape;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::index::StaticIndex;
use crate::input::InputError;
use crate::world::scene::{enu_arr_to_ned, to_f32, Scene};

/// Mission placements tried before giving up.
pub const MISSION_TRIES: usize = 20;
/// Largest obstacle count accepted.
pub const MAX_GENERATED_OBSTACLES: usize = 1_000_000;
/// Clearance of the mission start and goal from every obstacle, m.
pub const ENDPOINT_CLEARANCE_M: f64 = 1.0;
/// Height of the mission start and goal above the ground, m.
pub const MISSION_HEIGHT_M: f64 = 1.5;

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// Vertical trunks.
    Forest,
    /// Blocks of buildings and streets.
    City,
    /// Rack rows and aisles.
    Warehouse,
    /// Random spheres, boxes and cylinders.
    Clutter,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Forest => "forest",
            Kind::City => "city",
            Kind::Warehouse => "warehouse",
            Kind::Clutter => "clutter",
        }
    }
}

/// Generator parameters (`parapet scene generate --help` has the same defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct GenParams {
    /// Kind of scene.
    pub kind: Kind,
    /// RNG seed.
    pub seed: u64,
    /// Number of obstacles (before dropping duplicates).
    pub obstacles: usize,
    /// Forest: trunks per m²; clutter: obstacles per m² of floor.
    pub density: f64,
    /// Forest: smallest trunk radius, m.
    pub radius_min: f64,
    /// Forest: largest trunk radius, m.
    pub radius_max: f64,
    /// City: street width, m.
    pub street: f64,
    /// City: block side, m.
    pub block: f64,
    /// Warehouse: aisle width, m.
    pub aisle: f64,
    /// Distance start → goal, m (shortened to fit the scene).
    pub mission_length: f64,
    /// Height of the flight volume (bounds max z), m.
    pub ceiling: f64,
    /// Mission reference speed, m/s.
    pub speed: f64,
    /// Share of the obstacles written with `mapped = false`, in [0, 1].
    pub unmapped: f64,
}

impl Default for GenParams {
    fn default() -> Self {
        GenParams {
            kind: Kind::Forest,
            seed: 0,
            obstacles: 1000,
            density: 0.05,
            radius_min: 0.1,
            radius_max: 0.4,
            street: 8.0,
            block: 20.0,
            aisle: 3.0,
            mission_length: 60.0,
            ceiling: 5.0,
            speed: 0.5,
            unmapped: 0.0,
        }
    }
}

/// One generated obstacle, file frame ENU (m).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Obs {
    Cylinder { base: [f64; 3], radius: f64, height: f64 },
    Box { min: [f64; 3], max: [f64; 3] },
    Sphere { center: [f64; 3], radius: f64 },
}

/// Millimetre rounding (what the file holds).
fn mm(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

impl Obs {
    fn rounded(self) -> Obs {
        let r3 = |a: [f64; 3]| [mm(a[0]), mm(a[1]), mm(a[2])];
        match self {
            Obs::Cylinder { base, radius, height } => {
                Obs::Cylinder { base: r3(base), radius: mm(radius).max(0.001), height: mm(height).max(0.001) }
            }
            Obs::Box { min, max } => {
                let (a, mut b) = (r3(min), r3(max));
                for i in 0..3 {
                    b[i] = b[i].max(a[i] + 0.001);
                }
                Obs::Box { min: a, max: b }
            }
            Obs::Sphere { center, radius } => {
                Obs::Sphere { center: r3(center), radius: mm(radius).max(0.001) }
            }
        }
    }

    /// Lowest x/y corner (ENU, m), for the file order.
    fn corner(&self) -> [f64; 2] {
        match *self {
            Obs::Cylinder { base, .. } => [base[0], base[1]],
            Obs::Box { min, .. } => [min[0], min[1]],
            Obs::Sphere { center, .. } => [center[0], center[1]],
        }
    }

    /// The shape as the scene loader builds it (NED, f32).
    fn shape(&self) -> Shape {
        match *self {
            Obs::Cylinder { base, radius, height } => {
                Shape::cylinder(to_f32(&enu_arr_to_ned(base)), radius as f32, height as f32)
            }
            Obs::Box { min, max } => Shape::aabb(to_f32(&enu_arr_to_ned(min)), to_f32(&enu_arr_to_ned(max))),
            Obs::Sphere { center, radius } => Shape::sphere(to_f32(&enu_arr_to_ned(center)), radius as f32),
        }
    }

    fn write(&self, mapped: bool, out: &mut String) {
        let a = |v: [f64; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
        let _ = match *self {
            Obs::Cylinder { base, radius, height } => {
                write!(
                    out,
                    "{{ kind = \"cylinder\", base = {}, radius = {radius}, height = {height}",
                    a(base)
                )
            }
            Obs::Box { min, max } => write!(out, "{{ kind = \"box\", min = {}, max = {}", a(min), a(max)),
            Obs::Sphere { center, radius } => {
                write!(out, "{{ kind = \"sphere\", center = {}, radius = {radius}", a(center))
            }
        };
        out.push_str(if mapped { " },\n" } else { ", mapped = false },\n" });
    }
}

fn check_params(p: &GenParams) -> Result<(), InputError> {
    let opt = |name: &str, value: f64, ok: bool, allowed: &str| {
        if ok && value.is_finite() {
            Ok(())
        } else {
            Err(InputError::option(name, "out of range").value(value).allowed(allowed))
        }
    };
    if !(1..=MAX_GENERATED_OBSTACLES).contains(&p.obstacles) {
        return Err(InputError::option("obstacles", "out of range")
            .value(p.obstacles)
            .allowed(format!("1 ≤ obstacles ≤ {MAX_GENERATED_OBSTACLES}")));
    }
    opt("density", p.density, p.density > 0.0 && p.density <= 2.0, "0 < density ≤ 2 per m²")?;
    opt("radius-min", p.radius_min, p.radius_min >= 0.01 && p.radius_min <= 5.0, "0.01 ≤ radius-min ≤ 5 m")?;
    opt(
        "radius-max",
        p.radius_max,
        p.radius_max >= p.radius_min && p.radius_max <= 5.0,
        &format!("radius-min ({}) ≤ radius-max ≤ 5 m", p.radius_min),
    )?;
    opt("street", p.street, (2.0..=100.0).contains(&p.street), "2 ≤ street ≤ 100 m")?;
    opt("block", p.block, (4.0..=500.0).contains(&p.block), "4 ≤ block ≤ 500 m")?;
    opt("aisle", p.aisle, (1.0..=50.0).contains(&p.aisle), "1 ≤ aisle ≤ 50 m")?;
    opt(
        "mission-length",
        p.mission_length,
        (1.0..=10_000.0).contains(&p.mission_length),
        "1 ≤ mission-length ≤ 10000 m",
    )?;
    opt("ceiling", p.ceiling, (2.5..=100.0).contains(&p.ceiling), "2.5 ≤ ceiling ≤ 100 m")?;
    opt("speed", p.speed, p.speed > 0.0 && p.speed <= 20.0, "0 < speed ≤ 20 m/s")?;
    opt("unmapped", p.unmapped, (0.0..=1.0).contains(&p.unmapped), "0 ≤ unmapped ≤ 1 (a fraction)")?;
    Ok(())
}

/// Obstacles and the scene's square side (m) for `p`.
fn obstacles(p: &GenParams, rng: &mut ChaCha8Rng) -> (Vec<Obs>, f64) {
    let n = p.obstacles;
    let mut out = Vec::with_capacity(n);
    let side = match p.kind {
        Kind::Forest | Kind::Clutter => {
            let side = (n as f64 / p.density).sqrt().max(10.0);
            for _ in 0..n {
                let (x, y) = (rng.random_range(0.0..side), rng.random_range(0.0..side));
                out.push(if p.kind == Kind::Forest {
                    let radius = if p.radius_max > p.radius_min {
                        rng.random_range(p.radius_min..p.radius_max)
                    } else {
                        p.radius_min
                    };
                    Obs::Cylinder { base: [x, y, 0.0], radius, height: rng.random_range(8.0..20.0) }
                } else {
                    let s = rng.random_range(0.3..1.5);
                    let z = rng.random_range(0.0..p.ceiling);
                    match rng.random_range(0..3) {
                        0 => Obs::Sphere { center: [x, y, z], radius: s / 2.0 },
                        1 => Obs::Box {
                            min: [x, y, z],
                            max: [x + s, y + rng.random_range(0.3..1.5), z + rng.random_range(0.3..1.5)],
                        },
                        _ => Obs::Cylinder {
                            base: [x, y, z],
                            radius: s / 2.0,
                            height: rng.random_range(0.3..3.0),
                        },
                    }
                });
            }
            side
        }
        Kind::City => {
            let blocks = n.div_ceil(4);
            let g = (blocks as f64).sqrt().ceil() as usize;
            let pitch = p.block + p.street;
            let half = p.block / 2.0;
            'grid: for bi in 0..g {
                for bj in 0..g {
                    let (x0, y0) = (p.street + bi as f64 * pitch, p.street + bj as f64 * pitch);
                    for (li, lj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        if out.len() == n {
                            break 'grid;
                        }
                        let (lx, ly) = (x0 + li as f64 * half, y0 + lj as f64 * half);
                        let set = |rng: &mut ChaCha8Rng| rng.random_range(0.0..0.15 * half);
                        let min = [lx + set(rng), ly + set(rng), 0.0];
                        let max = [lx + half - set(rng), ly + half - set(rng), rng.random_range(6.0..40.0)];
                        out.push(Obs::Box { min, max });
                    }
                }
            }
            p.street + g as f64 * pitch
        }
        Kind::Warehouse => {
            // Rows along x: racks 10 m long, a cross aisle every 4 racks.
            let (len, depth, cross) = (10.0, 1.2, p.aisle.max(3.0));
            // About as deep (rows × row pitch) as long (racks × rack pitch).
            let rack_pitch = len + cross / 4.0;
            let rows = ((n as f64 * rack_pitch / (depth + p.aisle)).sqrt().ceil() as usize).clamp(1, n);
            let per_row = n.div_ceil(rows);
            let (x_start, y_start) = (p.aisle, p.aisle);
            let mut x_end: f64 = 0.0;
            for r in 0..rows {
                let y = y_start + r as f64 * (depth + p.aisle);
                for k in 0..per_row {
                    if out.len() == n {
                        break;
                    }
                    let x = x_start + k as f64 * len + (k / 4) as f64 * cross;
                    let gap = rng.random_range(0.0..0.2);
                    out.push(Obs::Box {
                        min: [x + gap, y, 0.0],
                        max: [x + len - gap, y + depth, p.ceiling + 1.0],
                    });
                    x_end = x_end.max(x + len);
                }
            }
            let y_end = y_start + rows as f64 * (depth + p.aisle);
            (x_end + p.aisle).max(y_end)
        }
    };
    (out, side)
}

/// Morton code of the 4 m cell of an x/y point (m, ≥ 0 in generated scenes).
fn morton(p: [f64; 2]) -> u64 {
    let spread = |v: f64| {
        let mut x = (v / 4.0).clamp(0.0, u32::MAX as f64) as u64;
        x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
        x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
        x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        x = (x | (x << 2)) & 0x3333_3333_3333_3333;
        (x | (x << 1)) & 0x5555_5555_5555_5555
    };
    spread(p[0]) | (spread(p[1]) << 1)
}

/// A generated scene: the TOML text and what it holds.
#[derive(Clone, Debug)]
pub struct Generated {
    /// The scene file's text.
    pub toml: String,
    /// The scene as loaded from that text.
    pub scene: Scene,
    /// Planner iterations of the check that a path exists.
    pub plan_iterations: u32,
    /// Length of the planner's path, m.
    pub plan_length_m: f32,
}

/// What the check that a path exists found: planner iterations and path length, m;
/// or why there is none.
pub type PathCheck = Result<(u32, f32), String>;

/// Generate a scene (see the module docs) with `path_exists` as the check that a
/// mission placement is connected (the planner's: `crate::plan::generate::generate`).
/// Errors: parameters out of range (named option, value, allowed range), or no
/// mission placement with a path.
pub fn generate_with(
    p: &GenParams,
    path_exists: &mut dyn FnMut(&Scene, u64) -> PathCheck,
) -> Result<Generated, InputError> {
    check_params(p)?;
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let (raw, side) = obstacles(p, &mut rng);
    // Rounded as written; duplicates after rounding dropped (the loader refuses them).
    let mut seen = std::collections::HashSet::with_capacity(raw.len());
    let mut obs: Vec<Obs> =
        raw.into_iter().map(Obs::rounded).filter(|o| seen.insert(format!("{o:?}"))).collect();
    // Written in Morton (Z) order of 4 m cells: obstacles near each other get
    // near indices, so the simulator's per-obstacle data of a neighbourhood
    // shares cache lines (a 10^5-trunk forest flew 1.6x slower in random order).
    obs.sort_by_key(|o| morton(o.corner()));
    let mapped = mapped_flags(obs.len(), p.unmapped, p.seed);
    let shapes: Vec<Shape> = obs.iter().map(Obs::shape).collect();
    let index = StaticIndex::from_shapes(&shapes);
    let (lo, hi) = ([0.0, 0.0, 0.0], [side, side, p.ceiling]);
    let length = p.mission_length.min(0.8 * side);
    let clear = |e: [f64; 3]| index.nearest(&enu_arr_to_ned(e), None).0 >= ENDPOINT_CLEARANCE_M;
    let mut last_err = String::new();
    for attempt in 0..MISSION_TRIES {
        // Centred, then shifted sideways and along by up to a tenth of the side.
        let j = if attempt == 0 { 0.0 } else { 0.1 * side };
        let (cx, cy) = (side / 2.0 + rng.random_range(-j..=j), side / 2.0 + rng.random_range(-j..=j));
        // Along (0.8, 0.6): never along a city street or a warehouse aisle.
        let (dx, dy) = (0.4 * length, 0.3 * length);
        let mut start = [mm(cx - dx), mm(cy - dy), MISSION_HEIGHT_M];
        let mut goal = [mm(cx + dx), mm(cy + dy), MISSION_HEIGHT_M];
        // Nudge each endpoint to a clear spot nearby.
        for e in [&mut start, &mut goal] {
            let base = *e;
            for k in 0..200 {
                if clear(*e) {
                    break;
                }
                let r = 0.5 + k as f64 * 0.05;
                e[0] = mm((base[0] + rng.random_range(-r..=r)).clamp(0.5, side - 0.5));
                e[1] = mm((base[1] + rng.random_range(-r..=r)).clamp(0.5, side - 0.5));
            }
        }
        if !(clear(start) && clear(goal)) {
            last_err = "no clear spot for the start or the goal".into();
            continue;
        }
        let toml = write_toml(p, &obs, &mapped, lo, hi, start, goal);
        let scene = Scene::parse(&toml, "generated scene").map_err(InputError::from)?;
        match path_exists(&scene, p.seed) {
            Ok((plan_iterations, plan_length_m)) => {
                return Ok(Generated { toml, scene, plan_iterations, plan_length_m })
            }
            Err(e) => last_err = e,
        }
    }
    Err(InputError::option("seed", format!(
        "no mission with a planned path in {MISSION_TRIES} placements (last: {last_err}); try another seed or a lower density"
    ))
    .value(p.seed))
}

/// Per obstacle: `true` when mapped. `round(fraction × n)` obstacles are unmapped,
/// chosen uniformly by stream 1 of the seed's ChaCha8 (the obstacles and the
/// mission draw from stream 0, so they do not depend on the fraction).
fn mapped_flags(n: usize, fraction: f64, seed: u64) -> Vec<bool> {
    let mut flags = vec![true; n];
    let k = ((fraction * n as f64).round() as usize).min(n);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(1);
    for i in rand::seq::index::sample(&mut rng, n, k) {
        flags[i] = false;
    }
    flags
}

fn write_toml(
    p: &GenParams,
    obs: &[Obs],
    mapped: &[bool],
    lo: [f64; 3],
    hi: [f64; 3],
    start: [f64; 3],
    goal: [f64; 3],
) -> String {
    let mut s = String::with_capacity(90 * obs.len() + 1024);
    let k = p.kind.name();
    let _ = writeln!(
        s,
        "# Generated by `parapet scene generate --kind {k} --seed {} --obstacles {}{}`.",
        p.seed,
        p.obstacles,
        if p.unmapped > 0.0 { format!(" --unmapped {}", p.unmapped) } else { String::new() }
    );
    let _ = writeln!(s, "name = \"{k}-{}-{}\"", obs.len(), p.seed);
    let _ = writeln!(
        s,
        "description = \"{} obstacles ({k}), seed {}, density {} /m², radius {}..{} m, street {} m, block {} m, aisle {} m\"",
        obs.len(),
        p.seed,
        p.density,
        p.radius_min,
        p.radius_max,
        p.street,
        p.block,
        p.aisle
    );
    // `obstacles` is a top-level key: before the first table.
    s.push_str("obstacles = [\n");
    for (o, &m) in obs.iter().zip(mapped) {
        o.write(m, &mut s);
    }
    s.push_str("]\n");
    let a = |v: [f64; 3]| format!("[{}, {}, {}]", mm(v[0]), mm(v[1]), mm(v[2]));
    let _ = writeln!(s, "[bounds]\nmin = {}\nmax = {}", a(lo), a(hi));
    let _ = writeln!(s, "[mission]\nstart = {}\ngoal = {}\nspeed = {}", a(start), a(goal), p.speed);
    s
}

//! Cost of the flight-control cascade of `parapet_core::controller::FlightController`
//! on the host: `cargo bench -p parapet-tests --bench cascade`.
//!
//! The controller (default parameters: paper office, multi-relative filter) is
//! armed and flying a long straight mission at 0.25 m/s. Benchmarks:
//! * `outer_16_obstacles` — one outer step as the 250 Hz loop runs it: a fresh
//!   position fix and a 16-point obstacle update (`update_position`,
//!   `update_obstacles`), then `step_outer` (waypoint sample + PD tracking + CBF
//!   filter over the 16 points + thrust/attitude mapping). Positions, velocities
//!   and obstacle layouts cycle through 256 seeded problems of the `cbf_filter`
//!   benchmark (K = 16), placed around the mission reference, so the filter
//!   intervenes in a good share of the steps (printed).
//! * `inner` — one inner step (`step_inner`: estimator + failsafe tilt check +
//!   attitude P + rate PID + mixer), with a fresh fix every 4th step.
//! * `period_4ms` — one 4 ms control period: 4 inner steps + 1 outer step as above.
//!
//! After each benchmark the controller must still be armed and flying the
//! mission (else the benchmark measured a failsafe path and stops with an error).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use parapet_core::cbf::FilterVariant;
use parapet_core::controller::{ControllerParams, FlightController, GuidanceMode, PositionFix};
use parapet_core::estimator::ImuSample;
use parapet_core::failsafe::FailsafeState;
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;
use parapet_tests::bench_states::{problems, SplitMix64, FORWARD_HALF_ANGLE_DEG};

const START: Vec3 = Vec3::new(0.0, 0.0, -1.5);
const SPEED: f32 = 0.25;
const N: usize = 256;

/// Fix, obstacle set and IMU sample of one benchmark step.
struct Step {
    offset: Vec3,
    velocity: Vec3,
    obstacles: Vec<ObstaclePoint>,
    imu: ImuSample,
}

fn steps() -> Vec<Step> {
    let mut rng = SplitMix64::new(7);
    problems(16, N, 2024, FORWARD_HALF_ANGLE_DEG)
        .into_iter()
        .map(|pr| {
            // Vehicle 0–0.2 m off the reference, obstacles placed relative to it as in the problem.
            let offset = rng.direction() * rng.uniform(0.0, 0.2);
            let obstacles = pr
                .obstacles
                .iter()
                .map(|o| ObstaclePoint { point: o.point - pr.p, velocity: Some(Vec3::zeros()), ..*o })
                .collect();
            let imu = ImuSample {
                gyro: rng.direction() * rng.uniform(0.0, 0.3),
                accel: Vec3::new(0.0, 0.0, -9.81) + rng.direction() * rng.uniform(0.0, 0.5),
            };
            Step { offset, velocity: pr.v, obstacles, imu }
        })
        .collect()
}

/// Mission reference position `t_us` after the mission start (straight line north from START).
fn reference(t_us: u64) -> Vec3 {
    START + Vec3::new(SPEED * t_us as f32 * 1e-6, 0.0, 0.0)
}

/// Obstacle points given relative to the vehicle, moved to `p`, in a fixed array
/// (no allocation in the timed loop); returns the array and the count.
fn shifted(rel: &[ObstaclePoint], p: Vec3) -> ([ObstaclePoint; 32], usize) {
    let mut out = [ObstaclePoint::fixed(Vec3::zeros(), 0); 32];
    for (o, r) in out.iter_mut().zip(rel) {
        *o = ObstaclePoint { point: r.point + p, ..*r };
    }
    (out, rel.len().min(32))
}

struct Bench {
    fc: FlightController,
    now: u64,
    t_mission: u64,
    steps: Vec<Step>,
    i: usize,
    outer: u64,
    intervened: u64,
}

impl Bench {
    fn new() -> Bench {
        let params = ControllerParams::default();
        assert_eq!(params.filter_variant, FilterVariant::MultiRelative);
        let mut fc = FlightController::new(params).expect("default parameters");
        // A path far longer than any benchmark flies (0.25 m/s · hours of simulated time).
        fc.set_path(&[START, START + Vec3::new(20_000.0, 0.0, 0.0)]).expect("path");
        let level = ImuSample { gyro: Vec3::zeros(), accel: Vec3::new(0.0, 0.0, -9.81) };
        let mut now = 0;
        // Let the estimator initialise at rest, with fixes and an empty obstacle set.
        for k in 0..500u64 {
            now = k * 1000;
            if k % 4 == 0 {
                fc.update_position(PositionFix {
                    t_us: now,
                    position: START,
                    velocity: Vec3::zeros(),
                    yaw: Some(0.0),
                });
                fc.update_obstacles(now, &[]);
                fc.step_outer(now);
            }
            fc.step_inner(now, &level);
        }
        fc.arm(now).expect("arm");
        fc.hold_position(now, START).expect("hold");
        fc.step_outer(now);
        fc.start_mission(now).expect("mission");
        Bench { fc, now, t_mission: now, steps: steps(), i: 0, outer: 0, intervened: 0 }
    }

    fn outer(&mut self) {
        let s = &self.steps[self.i % N];
        self.i += 1;
        self.now += 4000;
        let p = reference(self.now - self.t_mission) + s.offset;
        let (obs, n) = shifted(&s.obstacles, p);
        self.fc.update_position(PositionFix {
            t_us: self.now,
            position: p,
            velocity: s.velocity,
            yaw: Some(0.0),
        });
        self.fc.update_obstacles(self.now, black_box(&obs[..n]));
        self.fc.step_outer(black_box(self.now));
    }

    fn inner(&mut self, with_fix: bool) -> [f32; 4] {
        let s = &self.steps[self.i % N];
        self.i += 1;
        self.now += 1000;
        if with_fix && self.now.is_multiple_of(4000) {
            let p = reference(self.now - self.t_mission) + s.offset;
            self.fc.update_position(PositionFix {
                t_us: self.now,
                position: p,
                velocity: s.velocity,
                yaw: Some(0.0),
            });
        }
        self.fc.step_inner(black_box(self.now), black_box(&s.imu)).throttle
    }

    fn count(&mut self) {
        self.outer += 1;
        self.intervened += self.fc.telemetry().filter.intervened as u64;
    }

    /// One more outer step (the telemetry's mode is set there), then: still armed and
    /// flying the mission.
    fn check(&mut self, what: &str) {
        self.outer();
        let tel = self.fc.telemetry();
        assert_eq!(self.fc.state(), FailsafeState::Armed, "{what}: left Armed ({:?})", tel.last_transition);
        assert_eq!(tel.mode, GuidanceMode::Mission, "{what}: not flying the mission");
    }
}

fn bench_cascade(c: &mut Criterion) {
    // Share of outer steps in which the filter intervened, on one pass over the problems.
    let mut b = Bench::new();
    for _ in 0..N {
        b.outer();
        b.count();
    }
    b.check("warm-up");
    println!(
        "\ncascade: filter intervened in {:.0} % of {} outer steps (16 obstacles each)",
        100.0 * b.intervened as f64 / b.outer as f64,
        b.outer
    );

    let mut group = c.benchmark_group("cascade");
    let mut b = Bench::new();
    group.bench_function("outer_16_obstacles", |bn| bn.iter(|| b.outer()));
    b.check("outer");
    let mut b = Bench::new();
    group.bench_function("inner", |bn| bn.iter(|| b.inner(true)));
    b.check("inner");
    let mut b = Bench::new();
    group.bench_function("period_4ms", |bn| {
        bn.iter(|| {
            // The runner's order: outer at the start of the period, then 4 inner steps.
            b.outer();
            let t0 = b.now;
            b.now -= 1000; // the first inner step shares the outer step's time
            for _ in 0..4 {
                black_box(b.inner(false));
            }
            b.now = t0;
        })
    });
    b.check("period");
    group.finish();
}

criterion_group!(benches, bench_cascade);
criterion_main!(benches);

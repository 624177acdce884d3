//! Bidirectional RRT-Connect (Kuffner & LaValle 2000) on the vehicle's bounding sphere: two
//! trees grown from start and goal with a kd-tree ([`kiddo`]) for the nearest node, each
//! extension checked with the same segment test as the rest of the planner
//! ([`super::space::Space`]). Small problems sample the whole bounds; indexed ones a region
//! around start and goal that grows while no path is found (module docs of [`super`]).
//!
//! May import: [`super`] (problem, parameters, errors, constants), `parapet-core` (`Vec3`).

use std::time::Instant;

use kiddo::{KdTree, SquaredEuclidean};
use parapet_core::Vec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::space::Space;
use super::*;

/// One RRT tree: node positions, parent indices and a k-d tree over them.
struct Tree {
    nodes: Vec<Vec3>,
    parent: Vec<u32>,
    kd: KdTree<f32, 3>,
}

impl Tree {
    fn new(root: Vec3) -> Self {
        let mut t =
            Tree { nodes: Vec::with_capacity(256), parent: Vec::with_capacity(256), kd: KdTree::new() };
        t.add(root, u32::MAX);
        t
    }

    fn add(&mut self, p: Vec3, parent: u32) -> u32 {
        let idx = self.nodes.len() as u32;
        self.kd.add(&[p.x, p.y, p.z], idx as u64);
        self.nodes.push(p);
        self.parent.push(parent);
        idx
    }

    fn nearest(&self, p: &Vec3) -> u32 {
        self.kd.nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z]).item as u32
    }

    /// Positions from node `i` back to the root (root last).
    fn branch(&self, mut i: u32) -> Vec<Vec3> {
        let mut out = Vec::new();
        while i != u32::MAX {
            out.push(self.nodes[i as usize]);
            i = self.parent[i as usize];
        }
        out
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Extend {
    /// Blocked; nothing added.
    Trapped,
    /// A full step was added, target not reached.
    Advanced(u32),
    /// The target itself was added (or already was a node).
    Reached(u32),
}

/// Extend `tree` by at most `range` towards `target` from node `near_i`.
/// The step is added only if the whole segment is valid (no partial steps:
/// a node left against an obstacle attracts many samples it cannot serve).
fn extend_from(space: &mut Space, tree: &mut Tree, near_i: u32, target: &Vec3, range: f32) -> Extend {
    let near = tree.nodes[near_i as usize];
    let delta = target - near;
    let dist = delta.norm();
    if dist.is_nan() || dist <= 0.0 {
        // The target is already a node of this tree.
        return Extend::Reached(near_i);
    }
    let (q, full) = if dist <= range { (*target, true) } else { (near + delta * (range / dist), false) };
    if !space.segment_valid(&near, &q) {
        return Extend::Trapped;
    }
    let i = tree.add(q, near_i);
    if full {
        Extend::Reached(i)
    } else {
        Extend::Advanced(i)
    }
}

/// Extend `tree` towards `target` from the nearest of its nodes; if that
/// step is blocked, from the next nearest, up to `k` nodes.
fn extend(space: &mut Space, tree: &mut Tree, target: &Vec3, range: f32, k: usize) -> Extend {
    if k <= 1 {
        let near_i = tree.nearest(target);
        return extend_from(space, tree, near_i, target, range);
    }
    let near = tree.kd.nearest_n::<SquaredEuclidean>(&[target.x, target.y, target.z], k);
    for n in near {
        let r = extend_from(space, tree, n.item as u32, target, range);
        if r != Extend::Trapped {
            return r;
        }
    }
    Extend::Trapped
}

/// RRT-Connect search until `budget_ms` after `t0`; returns the raw path
/// (start first) and the iterations used.
pub(super) fn search(
    space: &mut Space,
    problem: &PlanProblem,
    params: &PlannerParams,
    rng: &mut ChaCha8Rng,
    t0: &Instant,
    budget_ms: f64,
) -> Result<(Vec<Vec3>, u32), PlanError> {
    let (lo_b, hi_b) = (problem.bounds_min, problem.bounds_max);
    // Small problems sample the whole bounds; indexed ones a region around
    // start and goal that grows while no path is found.
    let mut margin = REGION_MIN_MARGIN_M.max(0.5 * (problem.goal - problem.start).norm());
    let indexed = space.index.is_some();
    let region = |margin: f32| {
        if !indexed {
            return (lo_b, hi_b - lo_b);
        }
        let m = Vec3::repeat(margin);
        let lo = (problem.start.inf(&problem.goal) - m).sup(&lo_b);
        let hi = (problem.start.sup(&problem.goal) + m).inf(&hi_b);
        (lo, hi - lo)
    };
    let (mut lo, mut extent) = region(margin);
    let range_of = |extent: &Vec3| params.range_m.unwrap_or_else(|| (0.2 * extent.max()).max(0.1));
    let mut range = range_of(&extent);
    let mut trees = [Tree::new(problem.start), Tree::new(problem.goal)];
    // trees[a] grows towards the sample this iteration; trees[1 - a] connects.
    let mut a = 0usize;
    for it in 1..=params.max_iterations {
        if it % 16 == 0 && t0.elapsed().as_secs_f64() * 1e3 > budget_ms {
            return Err(PlanError::NoPathFound {
                iterations: it - 1,
                elapsed_ms: t0.elapsed().as_secs_f64() * 1e3,
            });
        }
        if it % REGION_GROW_ITERATIONS == 0 && indexed {
            margin *= 2.0;
            (lo, extent) = region(margin);
            range = range_of(&extent);
        }
        let b = 1 - a;
        let u = rng.random::<f32>();
        let sample =
            if u < params.goal_bias { trees[b].nodes[0] } else { free_sample(space, rng, &lo, &extent) };
        let (ta, tb) = if a == 0 {
            let (x, y) = trees.split_at_mut(1);
            (&mut x[0], &mut y[0])
        } else {
            let (x, y) = trees.split_at_mut(1);
            (&mut y[0], &mut x[0])
        };
        let new_a = match extend(space, ta, &sample, range, params.neighbours) {
            Extend::Trapped => {
                a = b;
                continue;
            }
            Extend::Advanced(i) | Extend::Reached(i) => i,
        };
        let target = ta.nodes[new_a as usize];
        // Connect: grow tb towards the new node until reached or blocked.
        loop {
            match extend(space, tb, &target, range, 1) {
                Extend::Advanced(_) => continue,
                Extend::Trapped => break,
                Extend::Reached(new_b) => {
                    let mut from_a = ta.branch(new_a);
                    let mut from_b = tb.branch(new_b);
                    // Both branches end at their roots and start at the same point.
                    from_b.remove(0);
                    let path = if a == 0 {
                        from_a.reverse();
                        from_a.extend(from_b);
                        from_a
                    } else {
                        from_b.reverse();
                        from_b.extend(from_a);
                        from_b
                    };
                    return Ok((path, it));
                }
            }
        }
        a = b;
    }
    Err(PlanError::NoPathFound {
        iterations: params.max_iterations,
        elapsed_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// Uniform sample in the bounds box.
fn uniform(rng: &mut ChaCha8Rng, lo: &Vec3, extent: &Vec3) -> Vec3 {
    Vec3::new(
        lo.x + extent.x * rng.random::<f32>(),
        lo.y + extent.y * rng.random::<f32>(),
        lo.z + extent.z * rng.random::<f32>(),
    )
}

/// Uniform sample in the bounds, redrawn up to [`FREE_SAMPLE_TRIES`] times
/// until it is clear of obstacles (a sample inside an obstacle mostly yields
/// blocked extensions).
fn free_sample(space: &mut Space, rng: &mut ChaCha8Rng, lo: &Vec3, extent: &Vec3) -> Vec3 {
    let mut q = uniform(rng, lo, extent);
    for _ in 1..FREE_SAMPLE_TRIES {
        if space.clear_of_obstacles(&q) {
            break;
        }
        q = uniform(rng, lo, extent);
    }
    q
}

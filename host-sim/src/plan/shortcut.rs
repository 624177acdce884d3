//! Path shortcutting of the planner (`simplify`): random shortcuts and corner
//! cutting, every replacement segment checked through `Space`. May import:
//! the planner's parent items and `space`.

use super::space::Space;
use super::*;

/// Point at arc length `t` on the polyline, with the index of its segment.
pub(super) fn point_at(path: &[Vec3], cum: &[f32], t: f32) -> (usize, Vec3) {
    let seg = match cum.binary_search_by(|c| c.total_cmp(&t)) {
        Ok(i) => i.min(path.len() - 2),
        Err(i) => i.saturating_sub(1).min(path.len() - 2),
    };
    let l = cum[seg + 1] - cum[seg];
    let u = if l > 0.0 { ((t - cum[seg]) / l).clamp(0.0, 1.0) } else { 0.0 };
    (seg, path[seg] + (path[seg + 1] - path[seg]) * u)
}

pub(super) fn cumulative(path: &[Vec3]) -> Vec<f32> {
    let mut cum = Vec::with_capacity(path.len());
    let mut acc = 0.0;
    cum.push(0.0);
    for w in path.windows(2) {
        acc += (w[1] - w[0]).norm();
        cum.push(acc);
    }
    cum
}

/// Shortcut a valid path (start first, goal last) into a shorter valid path
/// with few waypoints. Every replacement segment is checked, so validity is
/// preserved.
pub(super) fn simplify(
    space: &mut Space,
    mut path: Vec<Vec3>,
    attempts: u32,
    corner_passes: u32,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec3> {
    // 1. Random vertex-to-vertex shortcuts until a run of failures.
    let mut failures = 0;
    while path.len() > 2 && failures < 2 * path.len() {
        let n = path.len();
        let i = rng.random_range(0..n);
        let j = rng.random_range(0..n);
        let (i, j) = (i.min(j), i.max(j));
        if j < i + 2 {
            failures += 1;
            continue;
        }
        if space.segment_valid(&path[i], &path[j]) {
            path.drain(i + 1..j);
            failures = 0;
        } else {
            failures += 1;
        }
    }
    // 2. Random shortcuts between points anywhere on the path.
    let mut cum = cumulative(&path);
    for _ in 0..attempts {
        if path.len() < 3 {
            break;
        }
        let total = cum[cum.len() - 1];
        if total.is_nan() || total <= 0.0 {
            break;
        }
        let t1 = rng.random::<f32>() * total;
        let t2 = rng.random::<f32>() * total;
        let (t1, t2) = (t1.min(t2), t1.max(t2));
        let (s1, p1) = point_at(&path, &cum, t1);
        let (s2, p2) = point_at(&path, &cum, t2);
        if s1 == s2 {
            continue;
        }
        // Only worth it if it removes length: the polyline p1 → … → p2 is
        // longer than the chord whenever a vertex lies strictly between.
        if (t2 - t1) - (p2 - p1).norm() < 1e-4 {
            continue;
        }
        // The pieces kept from the cut segments are checked too (not only
        // assumed valid as parts of valid segments): every segment of the
        // returned path has passed `segment_valid` itself.
        if space.segment_valid(&p1, &p2)
            && space.segment_valid(&path[s1], &p1)
            && space.segment_valid(&p2, &path[s2 + 1])
        {
            let mut next = Vec::with_capacity(path.len());
            next.extend_from_slice(&path[..=s1]);
            if (p1 - path[s1]).norm() > 1e-6 {
                next.push(p1);
            }
            if (p2 - path[s2 + 1]).norm() > 1e-6 {
                next.push(p2);
            }
            next.extend_from_slice(&path[s2 + 1..]);
            path = next;
            cum = cumulative(&path);
        }
    }
    // 3. Corner cutting: replace each interior waypoint `v` (neighbours `a`,
    // `b`) by `v + t(a − v)`, `v + t(b − v)` with the largest `t` found by
    // bisection for which the cut is valid.
    for _ in 0..corner_passes {
        let mut k = 1;
        while k + 1 < path.len() {
            let (a, v, b) = (path[k - 1], path[k], path[k + 1]);
            let (mut lo, mut hi) = (0.0f32, 1.0f32);
            if space.segment_valid(&a, &b) {
                lo = 1.0;
            } else {
                for _ in 0..CORNER_BISECTIONS {
                    let t = 0.5 * (lo + hi);
                    if space.segment_valid(&(v + (a - v) * t), &(v + (b - v) * t)) {
                        lo = t;
                    } else {
                        hi = t;
                    }
                }
                if lo > 0.0
                    && !(space.segment_valid(&a, &(v + (a - v) * lo))
                        && space.segment_valid(&(v + (b - v) * lo), &b))
                {
                    lo = 0.0;
                }
            }
            if lo >= 1.0 {
                path.remove(k);
            } else if lo > 0.0 {
                path[k] = v + (a - v) * lo;
                path.insert(k + 1, v + (b - v) * lo);
                k += 2;
            } else {
                k += 1;
            }
        }
    }
    // 4. Greedy pass: from each kept waypoint, jump to the farthest reachable one.
    let mut out = vec![path[0]];
    let mut i = 0;
    while i + 1 < path.len() {
        let mut j = path.len() - 1;
        while j > i + 1 && !space.segment_valid(&path[i], &path[j]) {
            j -= 1;
        }
        out.push(path[j]);
        i = j;
    }
    // 5. Drop waypoints that lie (nearly) on the segment between their
    // neighbours, if that segment passes the check.
    let mut k = 1;
    while k + 1 < out.len() {
        let (a, b, c) = (out[k - 1], out[k], out[k + 1]);
        let ab = (b - a).norm();
        let bc = (c - b).norm();
        let nearly_straight = ab + bc - (c - a).norm() < 1e-6 * (ab + bc).max(1.0) || ab < 1e-6 || bc < 1e-6;
        if nearly_straight && space.segment_valid(&a, &c) {
            out.remove(k);
        } else {
            k += 1;
        }
    }
    out
}

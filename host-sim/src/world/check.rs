//! Scene-loader checks that need the whole obstacle list: duplicated and
//! degenerate obstacles. Called by [`crate::world::scene::Scene::parse`] after each
//! obstacle has been converted (and its own fields checked).
//!
//! * **Degenerate:** a radius, height or box side below [`MIN_OBSTACLE_SIZE_M`]
//!   (1 mm), or below what `f32` resolves at the obstacle's coordinates
//!   (64 ulps): the controller's geometry is `f32`, and such a shape is a
//!   typo or a unit error rather than an obstacle.
//! * **Duplicated:** two obstacles with the same kind, the same geometry (as
//!   the simulator stores it, `f32`) and the same motion; one of them is
//!   redundant and every query would count it twice.
//!
//! Owns the checks. May import: `parapet-core` (shapes), [`super::obstacle`].

use std::collections::HashMap;

use parapet_core::obstacle::Shape;

use super::obstacle::SceneObstacle;

/// Smallest radius, height or box side accepted, m.
pub const MIN_OBSTACLE_SIZE_M: f64 = 1e-3;

/// The bit pattern of a shape's numbers (kind first), for exact duplicate detection.
fn shape_key(shape: &Shape) -> [u32; 7] {
    let b = |x: f32| x.to_bits();
    match *shape {
        Shape::Point { center } => [0, b(center[0]), b(center[1]), b(center[2]), 0, 0, 0],
        Shape::Sphere { center, radius } => [1, b(center[0]), b(center[1]), b(center[2]), b(radius), 0, 0],
        Shape::Box { min, max } => [2, b(min[0]), b(min[1]), b(min[2]), b(max[0]), b(max[1]), b(max[2])],
        Shape::Cylinder { base, radius, height } => {
            [3, b(base[0]), b(base[1]), b(base[2]), b(radius), b(height), 0]
        }
    }
}

/// `(field, size)` pairs of a shape and the largest coordinate magnitude, m.
fn sizes(shape: &Shape) -> (Vec<(&'static str, f64)>, f64) {
    let m = |a: &[f32; 3]| a.iter().fold(0f64, |m, x| m.max((*x as f64).abs()));
    match *shape {
        Shape::Point { center } => (vec![], m(&center)),
        Shape::Sphere { center, radius } => (vec![("radius", radius as f64)], m(&center)),
        Shape::Box { min, max } => {
            // File order is ENU (x east, y north, z up); NED stores (north, east, down).
            let side = |i: usize| (max[i] - min[i]) as f64;
            (vec![("max", side(0).min(side(1)).min(side(2)))], m(&min).max(m(&max)))
        }
        Shape::Cylinder { base, radius, height } => {
            (vec![("radius", radius as f64), ("height", height as f64)], m(&base))
        }
    }
}

/// Check a scene's converted obstacles. The error is
/// `"obstacles[i]: field `f`: …"` for a degenerate obstacle and
/// `"obstacles[j]: duplicate of obstacles[i] …"` for a duplicate.
pub fn obstacles(obstacles: &[SceneObstacle]) -> Result<(), String> {
    for (i, o) in obstacles.iter().enumerate() {
        let (sizes, coord) = sizes(&o.shape);
        let min = MIN_OBSTACLE_SIZE_M.max(64.0 * f32::EPSILON as f64 * coord);
        for (field, size) in sizes {
            let ok = size >= min;
            if !ok {
                let what = if field == "max" { "smallest box side" } else { field };
                let size = size as f32;
                return Err(format!(
                    "obstacles[{i}]: field `{field}`: degenerate obstacle, {what} {size:e} m \
                     (got {size:e}; allowed ≥ {min:e} m at coordinates up to {coord} m)"
                ));
            }
        }
    }
    let mut seen: HashMap<[u32; 7], usize> = HashMap::with_capacity(obstacles.len());
    for (j, o) in obstacles.iter().enumerate() {
        match seen.entry(shape_key(&o.shape)) {
            std::collections::hash_map::Entry::Occupied(e) => {
                let i = *e.get();
                if obstacles[i].motion == o.motion {
                    return Err(format!(
                        "obstacles[{j}]: duplicate of obstacles[{i}] (same kind, geometry and motion); remove one"
                    ));
                }
            }
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(j);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::world::scene::Scene;

    const HEAD: &str = "name = \"t\"\n[bounds]\nmin = [-10, -10, 0]\nmax = [10, 10, 5]\n\
                        [mission]\nstart = [0, 0, 1]\ngoal = [5, 0, 1]\nspeed = 0.3\n";

    fn parse(obstacles: &str) -> Result<Scene, String> {
        Scene::parse(&format!("{HEAD}{obstacles}"), "t.toml").map_err(|e| e.to_string())
    }

    #[test]
    fn duplicates_are_named_with_both_indices() {
        let o = "[[obstacles]]\nkind = \"sphere\"\ncenter = [3, 0, 1]\nradius = 0.3\n";
        let other = "[[obstacles]]\nkind = \"box\"\nmin = [1, 1, 0]\nmax = [2, 2, 2]\n";
        let e = parse(&format!("{o}{other}{o}")).unwrap_err();
        assert!(e.starts_with("t.toml:") && e.contains("obstacles[2]: duplicate of obstacles[0]"), "{e}");
        // Same shape, different motion: not a duplicate.
        let moving = format!("{o}velocity = [0, 1, 0]\n");
        assert!(parse(&format!("{o}{other}{moving}")).is_ok());
        // Nearly the same (another f32): not a duplicate either.
        assert!(parse(&format!("{o}{}", o.replace("0.3", "0.31"))).is_ok());
    }

    #[test]
    fn degenerate_obstacles_name_field_value_and_range() {
        let e = parse("[[obstacles]]\nkind = \"sphere\"\ncenter = [3, 0, 1]\nradius = 1e-5\n").unwrap_err();
        assert!(e.contains("obstacles[0]") && e.contains("`radius`") && e.contains("1e-5"), "{e}");
        assert!(e.contains("allowed ≥ 1e-3"), "{e}");
        let e = parse("[[obstacles]]\nkind = \"box\"\nmin = [1, 1, 0]\nmax = [2, 1.0001, 2]\n").unwrap_err();
        assert!(e.contains("`max`") && e.contains("smallest box side"), "{e}");
        let e =
            parse("[[obstacles]]\nkind = \"cylinder\"\nbase = [9, 9, 0]\nradius = 0.2\nheight = 0.0002\n")
                .unwrap_err();
        assert!(e.contains("`height`"), "{e}");
        // At large coordinates the f32 resolution sets the floor.
        let far = "[[obstacles]]\nkind = \"sphere\"\ncenter = [9, 9, 1]\nradius = 0.002\n";
        assert!(parse(far).is_ok());
    }
}

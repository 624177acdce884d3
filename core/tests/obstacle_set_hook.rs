//! The controller's obstacle update applies the obstacle-set policy of
//! `parapet_core::obstacle_set` (issue 17): the multi variants keep the most critical
//! points, the closest-obstacle variants the nearest, and the telemetry reports drops.

use parapet_core::cbf::FilterVariant;
use parapet_core::controller::{ControllerParams, FlightController, PositionFix, OBSTACLE_CAPACITY};
use parapet_core::obstacle::ObstaclePoint;
use parapet_core::Vec3;

/// 40 points on a ring 0.35 m around the vehicle's x axis (ids 100..), then one wall point
/// 0.5 m ahead (id 1), for a vehicle at the origin flying +x at 0.3 m/s.
fn offered() -> Vec<ObstaclePoint> {
    let mut pts: Vec<ObstaclePoint> = (0..40u16)
        .map(|i| {
            let a = f32::from(i) * 0.157;
            let x = 0.02 * f32::from(i % 5);
            ObstaclePoint::fixed(Vec3::new(x, 0.35 * a.cos(), 0.35 * a.sin()), 100 + i)
        })
        .collect();
    pts.push(ObstaclePoint::fixed(Vec3::new(0.5, 0.0, 0.0), 1));
    pts
}

fn controller(variant: FilterVariant) -> FlightController {
    let params = ControllerParams { filter_variant: variant, ..ControllerParams::default() };
    let mut fc = FlightController::new(params).unwrap_or_else(|e| panic!("{e:?}"));
    fc.update_position(PositionFix {
        t_us: 1_000_000,
        position: Vec3::zeros(),
        velocity: Vec3::new(0.3, 0.0, 0.0),
        yaw: Some(0.0),
    });
    fc
}

#[test]
fn multi_variants_keep_the_closing_wall_and_report_the_drops() {
    for variant in [FilterVariant::MultiRelative, FilterVariant::Multi] {
        let mut fc = controller(variant);
        fc.update_obstacles(1_000_000, &offered());
        assert!(fc.obstacles().iter().any(|o| o.id == 1), "{variant:?}: the wall was dropped");
        let t = fc.telemetry();
        assert_eq!(usize::from(t.obstacle_count), OBSTACLE_CAPACITY);
        assert_eq!((t.obstacle_set.offered, t.obstacle_set.kept, t.obstacle_set.dropped), (41, 32, 9));
        assert_eq!(t.obstacles_dropped, 9);
        // Every dropped ring point has h > δ1 = 0.1: none of the dropped is near.
        assert_eq!(t.obstacle_set.dropped_near, 0);
        assert!(t.obstacle_set.min_dropped_key > 0.1, "{:?}", t.obstacle_set);
    }
}

#[test]
fn closest_obstacle_variants_keep_the_published_nearest_policy() {
    for variant in [FilterVariant::Paper, FilterVariant::Relative] {
        let mut fc = controller(variant);
        fc.update_obstacles(1_000_000, &offered());
        assert!(!fc.obstacles().iter().any(|o| o.id == 1), "{variant:?}: nearest-first keeps the ring");
        assert_eq!(fc.telemetry().obstacle_set.dropped, 9);
    }
}

#[test]
fn implausible_points_are_bad_input_and_the_rest_is_kept() {
    let mut fc = controller(FilterVariant::MultiRelative);
    let pts = [
        ObstaclePoint::fixed(Vec3::new(f32::NAN, 0.0, 0.0), 1),
        ObstaclePoint::fixed(Vec3::new(2.0e5, 0.0, 0.0), 2),
        ObstaclePoint::fixed(Vec3::new(1.0, 0.0, 0.0), 3),
    ];
    let before = fc.telemetry().non_finite_inputs;
    fc.update_obstacles(1_000_000, &pts);
    let t = fc.telemetry();
    assert_eq!(fc.obstacles().iter().map(|o| o.id).collect::<Vec<_>>(), vec![3]);
    assert_eq!((t.obstacle_set.rejected, t.obstacles_dropped), (2, 2));
    assert!(t.non_finite_inputs > before);
}

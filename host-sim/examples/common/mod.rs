//! What the navigation examples (`nav_errors`, `nav_trace`) share: the `FlightStack` methods
//! their recorders forward unchanged to the in-process controller in their field `c`.

/// Inside `impl FlightStack for R` where `R.c` is a `parapet_sim::fc::control::Controller`:
/// `height_fix`, `navigation`, `inner` and `state_name` forwarded to it.
macro_rules! forward_to_controller {
    () => {
        fn height_fix(&mut self, t: f64, down: f64) {
            self.c.height_fix(t, down);
        }
        fn navigation(
            &self,
            t: f64,
        ) -> Option<(nalgebra::Vector3<f64>, parapet_sim::flight::sensing::ErrorBound)> {
            self.c.navigation(t)
        }
        fn inner(&mut self, t: f64, imu: &parapet_sim::sim::sensors::ImuReading) -> [f32; 4] {
            self.c.inner(t, imu)
        }
        fn state_name(&self) -> String {
            self.c.state_name()
        }
    };
}

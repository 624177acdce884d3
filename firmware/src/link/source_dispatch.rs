//! The dispatcher's side of the external position sources (GPS_INPUT, VISION_POSITION_ESTIMATE,
//! a VIO's ODOMETRY):
//! `impl Router` methods that check a source's fix, hand it to the autopilot, count refusals
//! and announce source changes and losses (STATUSTEXT). The sources themselves (conversion,
//! checks, the monitor) are [`crate::link::position_sources`]; this file is apart from it so
//! that `router` may import `position_sources` without a cycle. May import: the router, the
//! position sources, the link's outbound/telemetry helpers, [`crate::app`].

use crate::app::autopilot::{Autopilot, FixKind, PositionFix, SourceNoise};
use crate::link::inputs::FixClock;
use crate::link::outbound::Outbound;
use crate::link::position_sources::{
    check_fix, FixRefusal, Source, POSITION_LOST_TEXT, POSITION_SOURCE_TEXT,
};
use crate::link::router::Router;

/// The dispatcher's side of the sources (its state: `Router::vision`, `Router::sources`).
impl Router {
    /// A GPS_INPUT / VISION_POSITION_ESTIMATE / VIO ODOMETRY fix: checked, then to the
    /// autopilot's navigation filter with σ `noise` (GPS absolute, vision and VIO relative);
    /// refusals counted
    /// ([`crate::link::position_sources`]).
    pub(crate) fn external_fix<A: Autopilot>(
        &mut self,
        fix: Result<Option<PositionFix>, FixRefusal>,
        source: Source,
        noise: SourceNoise,
        now_us: u64,
        ap: &mut A,
    ) {
        let lockstep = self.fix_clock == FixClock::Message;
        let checked = fix.and_then(|f| match f {
            Some(f) => check_fix(&f, lockstep.then(|| now_us.saturating_sub(f.t_us))).map(|()| Some(f)),
            None => Ok(None),
        });
        match checked {
            Ok(Some(f)) => {
                // Vision and a VIO's ODOMETRY are relative (their frame may jump); GPS absolute.
                let kind = if source == Source::Gps { FixKind::Absolute } else { FixKind::Relative };
                ap.navigation_fix(&f, kind, noise);
                self.source_accepted(source, now_us);
            }
            Ok(None) => {}
            Err(_) => self.stats.position_rejected = self.stats.position_rejected.saturating_add(1),
        }
    }

    /// A fix of `source` went to the autopilot: STATUSTEXT INFO when the source changed.
    pub(crate) fn source_accepted(&mut self, source: Source, now_us: u64) {
        if let Some(name) = self.sources.accepted(source, now_us) {
            let t = crate::link::telemetry::status_text(
                crate::link::dialect::MavSeverity::MAV_SEVERITY_INFO,
                POSITION_SOURCE_TEXT,
                name,
            );
            self.reply(Outbound::StatusText(t));
        }
    }

    /// At firmware time `now_us`: STATUSTEXT WARNING [`POSITION_LOST_TEXT`] once when the
    /// source has fed no fix for [`crate::link::position_sources::SOURCE_LOSS_US`].
    pub(crate) fn poll_sources(&mut self, now_us: u64) {
        if self.sources.poll(now_us) {
            let t = crate::link::telemetry::status_text(
                crate::link::dialect::MavSeverity::MAV_SEVERITY_WARNING,
                POSITION_LOST_TEXT,
                "",
            );
            self.reply(Outbound::StatusText(t));
        }
    }
}

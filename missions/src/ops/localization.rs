//! The localizer (1520): corrects the cart's drifting odometry by matching sonar segments
//! against the a-priori map's walls, and stores the correction in the world DM.

use super::records::{LocationRecord, LOCATION, MAP, SONAR};
use super::{cart, cart_err, correction, dm_err, newest};
use crate::algo::localize::{
    localize, recent_travel, swept_segments, Fix, LocalizeParams, Reframe, SensedPoint,
};
use crate::algo::segments::SegmentParams;
use crate::geom::Segment;
use crate::hardware::CartClient;
use marie_actors::declare::DeclaredParams;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::{Query, FEATURE, WORLD};
use marie_vocabulary::property::{ParamSchema, Value};
use std::collections::BTreeMap;
use std::time::Duration;

marie_actors::params! {
    /// The localizer's parameters.
    pub struct LocalizerParams {
        /// how far back in time echoes are fitted at most
        pub window: f64 = 20.0, range(0.5, 120.0), unit("s");
        /// how far back along each sensor's path echoes are fitted (short: the odometry
        /// drifts per metre)
        pub travel: f64 = 2.0, range(0.3, 20.0), unit("m");
        /// echoes from before the sensor turned by more than this are not fitted (wheels
        /// slip in turns)
        pub turn: f64 = 10.0, range(1.0, 180.0), unit("deg");
        /// fraction of the measured error corrected per step
        pub gain: f64 = 0.5, range(0.0, 1.0);
        /// largest angle between a segment and its map wall
        pub max_angle: f64 = LocalizeParams::default().max_angle.to_degrees(),
            range(0.5, 45.0), unit("deg");
        /// largest distance between a segment and its map wall
        pub max_offset: f64 = LocalizeParams::default().max_offset, range(0.01, 2.0), unit("m");
        /// shortest segment matched
        pub min_length: f64 = LocalizeParams::default().min_length, range(0.1, 10.0), unit("m");
    }
}

/// Keeps the cart's pose in the map frame while it runs (until suspended), as the thesis'
/// cart had to: its wheels drift by about 1 % of the distance and half a degree of heading
/// per metre. Every step it fits segments to the narrow-beam echoes each sensor heard over the
/// last metres it travelled (`travel`, since it last turned by `turn`, at most `window`
/// seconds back: short in distance, so
/// the odometry's own drift within it is negligible, yet as long when the cart crawls along a
/// wall as when it drives, so the segments are long enough to give the heading), brought into the frame of
/// the newest correction, matches them to the map's walls (world DM, class `map`), and
/// stores the corrected correction ([`LocationRecord`]) with part (`gain`) of the measured
/// error taken out. A direction no matched wall constrains keeps the odometry's estimate.
#[derive(Debug, Default)]
pub struct Localizer {
    cart: Option<CartClient>,
    map: Option<Vec<Segment>>,
    fixes: u64,
}

impl Operation for Localizer {
    fn identity(&self) -> Identity {
        Identity::new(
            "localizer",
            1520,
            "1.0.0",
            "corrects the odometry by matching sonar segments to the map",
        )
    }

    fn parameters(&self) -> ParamSchema {
        LocalizerParams::schema()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(250)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.map = Some(
            newest(ctx, WORLD, MAP)
                .await?
                .ok_or_else(|| OpError::failed("no map in the world DM to localize on"))?,
        );
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: LocalizerParams = ctx.params().read()?;
        let window = Duration::from_secs_f64(p.window);
        let travel = p.travel;
        let turn = p.turn.to_radians();
        let gain = p.gain;
        let params = LocalizeParams {
            max_angle: p.max_angle.to_radians(),
            max_offset: p.max_offset,
            min_length: p.min_length,
            ..LocalizeParams::default()
        };
        let Some(map) = self.map.clone() else {
            return Err(OpError::failed("activated without a map"));
        };
        let now = correction(ctx).await?;
        let since = ctx.now().saturating_sub(window);
        // shared with the scans' other readers: decoded once, not copied
        let scans = ctx
            .dm(FEATURE)?
            .select_kind_shared(SONAR, Query::all().time_from(since))
            .await
            .map_err(dm_err(FEATURE))?;
        let mut by_sensor: BTreeMap<usize, Vec<SensedPoint>> = BTreeMap::new();
        for (_, scan) in &scans {
            let frame = Reframe::new(&scan.correction, &now);
            for e in scan.echoes.iter().filter(|e| e.narrow) {
                let origin =
                    e.point - crate::geom::Pose::new(0.0, 0.0, e.bearing).heading() * e.range;
                by_sensor.entry(e.sensor).or_default().push(SensedPoint {
                    origin: frame.apply(origin),
                    point: frame.apply(e.point),
                });
            }
        }
        let segments: Vec<Segment> = by_sensor
            .values()
            .flat_map(|track| {
                swept_segments(
                    recent_travel(track, travel, turn),
                    &SegmentParams::default(),
                )
            })
            .collect();
        let odometry = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?
            .odometry;
        let pose = now.compose(odometry);
        let Some(fix) = localize(&segments, &map, pose.point(), &params) else {
            return Ok(Step::Continue);
        };
        let step = Fix {
            rotation: fix.rotation * gain,
            shift: fix.shift * gain,
            ..fix
        }
        .limited(params.max_turn, params.max_shift);
        let corrected = step.apply(&now, pose.point(), 1.0);
        let record = LocationRecord {
            correction: corrected,
            odometry,
            pose: corrected.compose(odometry),
            matched: fix.matched,
        };
        ctx.dm(WORLD)?
            .store_kind(LOCATION, &record)
            .await
            .map_err(dm_err(WORLD))?;
        self.fixes += 1;
        tracing::debug!(
            rotation = step.rotation,
            dx = step.shift.x,
            dy = step.shift.y,
            matched = fix.matched,
            "odometry corrected"
        );
        Ok(Step::Continue)
    }

    fn property(&self, name: &str) -> Option<Value> {
        (name == "fixes").then_some(Value::Int(self.fixes as i64))
    }
}

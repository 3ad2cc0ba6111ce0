//! Perception: the segment extractor (1517), the wall sensor (1512) and the docking-spot
//! detector (1518). They read the feature DM and write the feature and world DMs.

use super::records::{
    DockRecord, Echo, EchoScan, SearchRecord, SegmentSet, WallRecord, DOCK, SEARCH, SEGMENTS,
    SONAR, WALL,
};
use super::{cart, cart_err, correction, dm_err, newest};
use crate::algo::dock::{detect_dock, DockParams};
use crate::algo::localize::{reframe, Reframe};
use crate::algo::segments::{extract_segments, SegmentParams};
use crate::algo::track::{track_wall, TrackParams};
use crate::algo::wall::{sense_wall, Side, WallEstimate, WallParams};
use crate::geom::{Point, Pose, Segment};
use crate::hardware::CartClient;
use marie_actors::declare::{DeclaredFlags, DeclaredParams};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_dm::{Query, FEATURE, WORLD};
use marie_vocabulary::property::{ParamSchema, Value};
use marie_vocabulary::status::FlagDecl;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

marie_actors::choice! {
    /// Which sonar beams an operation uses.
    pub enum Beams {
        /// Only narrow beams, whose echoes lie where the wall is.
        Narrow = "narrow",
        /// Every beam; a wide beam's echo is placed on its axis, nearer than its wall.
        All = "all",
    }
}

impl Beams {
    /// Whether an echo of a narrow (`true`) or wide beam is used.
    fn admits(self, narrow: bool) -> bool {
        narrow || self == Beams::All
    }
}

/// Echo scans stored since `since` (clock time) with a seq of at least `from_seq`, oldest
/// first, with the seq that follows the last one returned. Shared with the other readers of
/// the scans (decoded once, never copied).
async fn scans_since(
    ctx: &mut OpContext,
    since: Duration,
    from_seq: u64,
) -> Result<(Vec<Arc<EchoScan>>, u64), OpError> {
    let records = ctx
        .dm(FEATURE)?
        .select_kind_shared(SONAR, Query::all().time_from(since).seq_from(from_seq))
        .await
        .map_err(dm_err(FEATURE))?;
    let next = records
        .last()
        .map_or(from_seq, |(header, _)| header.seq + 1);
    let scans = records.into_iter().map(|(_, scan)| scan).collect();
    Ok((scans, next))
}

/// The wall estimate of the wall segment `wall` as seen from `pose` (the wall is static, the
/// cart is not).
pub(crate) fn wall_from(wall: &Segment, pose: &Pose) -> Option<WallEstimate> {
    sense_wall(
        &[*wall],
        pose,
        &WallParams {
            max_distance: f64::MAX,
            min_length: 0.0,
            max_angle: std::f64::consts::PI,
            ..WallParams::default()
        },
    )
}

marie_actors::params! {
    /// The segment extractor's parameters.
    pub struct SegmentExtractorParams {
        /// how far back echoes are used
        pub window: f64 = 8.0, range(0.5, 120.0), unit("s");
        /// largest distance of an echo from its segment
        pub distance_threshold: f64 = SegmentParams::default().distance_threshold,
            range(0.005, 1.0), unit("m");
        /// fewest echoes a segment needs
        pub min_points: i64 = SegmentParams::default().min_points as i64, range(2, 1000);
        /// larger jumps between consecutive echoes end a segment
        pub max_gap: f64 = SegmentParams::default().max_gap, range(0.01, 5.0), unit("m");
        /// shortest segment reported
        pub min_length: f64 = SegmentParams::default().min_length, range(0.0, 50.0), unit("m");
        /// which sonar beams to fit: a wide beam's echo is placed on its axis, so its
        /// points sit nearer than the wall they came from
        pub beams: Beams = Beams::Narrow;
        /// only echoes heard since this activation (not an earlier stage's, which the
        /// sonar may have heard for the localizer while the cart turned)
        pub fresh: bool = false;
    }
}

/// Fits line segments to the sonar echoes of a recent time window, sensor by sensor (each
/// sensor's echoes are ordered along the cart's path), and stores the set in the feature DM.
/// Runs until suspended.
#[derive(Debug, Default)]
pub struct SegmentExtractor {
    sets: u64,
    /// Clock time of the activation (for `fresh`).
    activated: Duration,
}

impl Operation for SegmentExtractor {
    fn identity(&self) -> Identity {
        Identity::new(
            "segment-extractor",
            1517,
            "1.0.0",
            "fits line segments to sonar echoes",
        )
    }

    fn parameters(&self) -> ParamSchema {
        SegmentExtractorParams::schema()
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.activated = ctx.now();
        Ok(Step::Continue)
    }

    fn period(&self) -> Duration {
        Duration::from_millis(250)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: SegmentExtractorParams = ctx.params().read()?;
        let window = Duration::from_secs_f64(p.window);
        let params = SegmentParams {
            distance_threshold: p.distance_threshold,
            min_points: p.min_points as usize,
            max_gap: p.max_gap,
            min_length: p.min_length,
            ..SegmentParams::default()
        };
        let mut since = ctx.now().saturating_sub(window);
        if p.fresh {
            since = since.max(self.activated);
        }
        let (scans, _) = scans_since(ctx, since, 0).await?;
        // every echo in the frame of the newest correction, whatever it was placed with
        let now = correction(ctx).await?;
        let mut by_sensor: BTreeMap<usize, Vec<Point>> = BTreeMap::new();
        for scan in &scans {
            let frame = Reframe::new(&scan.correction, &now);
            for e in scan.echoes.iter().filter(|e| p.beams.admits(e.narrow)) {
                by_sensor
                    .entry(e.sensor)
                    .or_default()
                    .push(frame.apply(e.point));
            }
        }
        let points = by_sensor.values().map(Vec::len).sum();
        let segments = by_sensor
            .values()
            .flat_map(|pts| extract_segments(pts, &params))
            .map(|f| f.segment)
            .collect();
        ctx.dm(FEATURE)?
            .put_kind(SEGMENTS, &SegmentSet { segments, points })
            .map_err(dm_err(FEATURE))?;
        self.sets += 1;
        Ok(Step::Continue)
    }

    fn property(&self, name: &str) -> Option<Value> {
        (name == "sets").then_some(Value::Int(self.sets as i64))
    }
}

marie_actors::choice! {
    /// Which side of the cart a sensed wall must be on.
    pub enum WallSide {
        /// Either side.
        Any = "any",
        /// The cart's left.
        Left = "left",
        /// The cart's right.
        Right = "right",
    }
}

marie_actors::params! {
    /// The wall sensor's parameters.
    pub struct WallSensorParams {
        /// farthest a wall may be
        pub max_distance: f64 = WallParams::default().max_distance, range(0.1, 20.0), unit("m");
        /// shortest wall accepted
        pub min_length: f64 = WallParams::default().min_length, range(0.0, 50.0), unit("m");
        /// which side of the cart the wall must be on
        pub side: WallSide = WallSide::Any;
        /// largest angle between the wall and the cart's heading
        pub max_angle: f64 = WallParams::default().max_angle.to_degrees(),
            range(0.0, 90.0), unit("deg");
        /// keep updating the wall instead of finishing when found
        pub continuous: bool = false;
    }
}

marie_actors::flags! {
    /// What the wall sensor reports.
    pub enum WallSensorFlag {
        /// a wall was found and stored in the world DM
        Found = "wall-found",
    }
}

/// Finds the wall among the newest segments and stores it in the world DM. Finishes with
/// `wall-found`, or with `continuous` keeps updating the wall (raising `wall-found`) until
/// suspended.
///
/// In continuous mode the sensor *tracks* the wall it has (the newest wall record when it is
/// activated): it only accepts segments on that wall's line, refits the line to them (so a
/// direction from an early glimpse or an uncorrected pose does not stay) and extends the
/// wall's known extent with them ([`track_wall`]). Without tracking, a recess in the wall — the docking spot — would, once
/// the cart is alongside it, offer its back wall as "the" wall and lead the follower into it.
#[derive(Debug, Default)]
pub struct WallSensor {
    cart: Option<CartClient>,
    /// The tracked wall and the correction it is placed with.
    tracked: Option<(Segment, Pose)>,
}

impl Operation for WallSensor {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-sensor",
            1512,
            "1.0.0",
            "finds a wall among the extracted segments",
        )
    }

    fn parameters(&self) -> ParamSchema {
        WallSensorParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        WallSensorFlag::decls()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(250)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.tracked = newest(ctx, WORLD, WALL)
            .await?
            .map(|w| (w.segment, w.correction));
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: WallSensorParams = ctx.params().read()?;
        let params = WallParams {
            max_distance: p.max_distance,
            min_length: p.min_length,
            side: match p.side {
                WallSide::Any => None,
                WallSide::Left => Some(Side::Left),
                WallSide::Right => Some(Side::Right),
            },
            max_angle: p.max_angle.to_radians(),
            ..WallParams::default()
        };
        let continuous = p.continuous;
        let Some(set) = newest(ctx, FEATURE, SEGMENTS).await? else {
            return Ok(Step::Continue);
        };
        let odometry = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?
            .odometry;
        let now = correction(ctx).await?;
        let pose = now.compose(odometry);
        let tracked = self.tracked.map(|(wall, then)| {
            Segment::new(reframe(wall.a, &then, &now), reframe(wall.b, &then, &now))
        });
        let found = match (continuous, tracked) {
            (true, Some(wall)) => track_wall(&wall, &set.segments, &TrackParams::default())
                .and_then(|segment| wall_from(&segment, &pose)),
            _ => sense_wall(&set.segments, &pose, &params),
        };
        let Some(w) = found else {
            if continuous && self.tracked.is_some() {
                ctx.raise(WallSensorFlag::Found); // still the same wall, nothing new seen
            }
            return Ok(Step::Continue);
        };
        let record = WallRecord {
            segment: w.line,
            distance: w.distance,
            relative_angle: w.angle,
            side: w.side.sign(),
            pose,
            correction: now,
            #[cfg(feature = "next-protocol")]
            seen_among: u32::try_from(set.segments.len()).ok(),
        };
        self.tracked = Some((w.line, now));
        tracing::debug!(
            a = ?(w.line.a.x, w.line.a.y),
            b = ?(w.line.b.x, w.line.b.y),
            distance = w.distance,
            x = pose.x,
            y = pose.y,
            "wall sensed"
        );
        ctx.dm(WORLD)?
            .store_kind(WALL, &record)
            .await
            .map_err(dm_err(WORLD))?;
        if continuous {
            ctx.raise(WallSensorFlag::Found);
            Ok(Step::Continue)
        } else {
            Ok(Step::finish(WallSensorFlag::Found))
        }
    }
}

marie_actors::params! {
    /// The docking detector's parameters.
    pub struct DockingDetectorParams {
        /// width of the spot's opening along the wall
        pub breadth: f64 = DockParams::default().breadth, range(0.3, 20.0), unit("m");
        /// depth of the spot behind the wall line
        pub depth: f64 = DockParams::default().depth, range(0.1, 10.0), unit("m");
        /// accepted breadth error
        pub breadth_tolerance: f64 = DockParams::default().breadth_tolerance,
            range(0.0, 5.0), unit("m");
        /// accepted depth error
        pub depth_tolerance: f64 = DockParams::default().depth_tolerance,
            range(0.0, 5.0), unit("m");
        /// which sonar beams to use: wide beams blur the spot's edges
        pub beams: Beams = Beams::Narrow;
        /// also use echoes from this long before the activation (0: only since)
        pub history: f64 = 0.0, range(0.0, 3600.0), unit("s");
    }
}

marie_actors::flags! {
    /// What the docking detector reports.
    pub enum DockingDetectorFlag {
        /// a docking spot was found and stored in the world DM
        Found = "dock-found",
    }
}

/// Looks for a docking spot of the given breadth (along the wall) and depth (into it) in the
/// followed wall, among the echoes gathered since it was activated. Finishes with `dock-found`
/// after storing the dock in the world DM; very sensitive to its parameters (thesis 9.3.2).
#[derive(Debug, Default)]
pub struct DockingDetector {
    cart: Option<CartClient>,
    since: Duration,
    /// Seq of the first sonar record not yet read.
    next_seq: u64,
    /// Every echo gathered in this activation.
    echoes: Vec<Echo>,
}

impl Operation for DockingDetector {
    fn identity(&self) -> Identity {
        Identity::new(
            "docking-detector",
            1518,
            "1.0.0",
            "finds a docking spot along the followed wall",
        )
    }

    fn parameters(&self) -> ParamSchema {
        DockingDetectorParams::schema()
    }

    fn flags(&self) -> Vec<FlagDecl> {
        DockingDetectorFlag::decls()
    }

    fn period(&self) -> Duration {
        Duration::from_millis(500)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: DockingDetectorParams = ctx.params().read()?;
        let history = Duration::from_secs_f64(p.history);
        let resumed = match ctx.resumed() {
            true => newest(ctx, WORLD, SEARCH).await?,
            false => None,
        };
        self.since = match resumed {
            Some(search) => search.since,
            None => {
                let since = ctx.now().saturating_sub(history);
                ctx.dm(WORLD)?
                    .store_kind(SEARCH, &SearchRecord { since })
                    .await
                    .map_err(dm_err(WORLD))?;
                since
            }
        };
        self.next_seq = 0;
        self.echoes.clear();
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: DockingDetectorParams = ctx.params().read()?;
        let params = DockParams {
            breadth: p.breadth,
            depth: p.depth,
            breadth_tolerance: p.breadth_tolerance,
            depth_tolerance: p.depth_tolerance,
            ..DockParams::default()
        };
        let Some(wall) = newest(ctx, WORLD, WALL).await? else {
            return Ok(Step::Continue);
        };
        let status = cart(&mut self.cart, ctx)?
            .status()
            .await
            .map_err(cart_err)?;
        let now = correction(ctx).await?;
        let pose = now.compose(status.odometry);
        let Some(estimate) = wall_from(&wall.segment_under(&now), &pose) else {
            return Ok(Step::Continue);
        };
        // only the scans stored since the last step are fetched and decoded
        let (scans, next) = scans_since(ctx, self.since, self.next_seq).await?;
        self.next_seq = next;
        // each echo stays where it was placed: with the correction of its time, which was
        // right then (moving old echoes with a newer correction bends the spot out of shape
        // by the odometry's drift since)
        self.echoes
            .extend(scans.iter().flat_map(|s| s.echoes.iter().copied()));
        let points: Vec<Point> = self
            .echoes
            .iter()
            .filter(|e| p.beams.admits(e.narrow))
            .map(|e| e.point)
            .collect();
        let Some(dock) = detect_dock(&estimate, &points, &params) else {
            return Ok(Step::Continue);
        };
        let park = dock.reference_pose(status.axle_to_centre);
        let o = dock.opening;
        // the centre lies half the depth behind the opening's midpoint
        let into = (dock.pose.point() - o.midpoint()) * 2.0;
        let corners = [o.a, o.b, o.b + into, o.a + into];
        let record = DockRecord {
            park,
            corners,
            breadth: dock.breadth,
            depth: dock.depth,
        };
        ctx.dm(WORLD)?
            .store_kind(DOCK, &record)
            .await
            .map_err(dm_err(WORLD))?;
        tracing::info!(
            breadth = dock.breadth,
            depth = dock.depth,
            x = park.x,
            y = park.y,
            "dock found"
        );
        Ok(Step::finish(DockingDetectorFlag::Found))
    }
}

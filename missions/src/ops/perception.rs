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
use marie_actors::dm::Query;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_actors::flags::{FlagDecl, StatusFlags};
use marie_actors::property::{ParamDecl, ParamSchema, Value};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

/// Echo scans stored since `since` (clock time) with a seq of at least `from_seq`, oldest
/// first, with the seq that follows the last one returned. Shared with the other readers of
/// the scans (decoded once, never copied).
async fn scans_since(
    ctx: &mut OpContext,
    since: Duration,
    from_seq: u64,
) -> Result<(Vec<Arc<EchoScan>>, u64), OpError> {
    let records = ctx
        .dm("feature")?
        .select(Query::class(SONAR).time_from(since).seq_from(from_seq))
        .await
        .map_err(dm_err("feature"))?;
    let next = records.last().map_or(from_seq, |r| r.seq + 1);
    let scans = records
        .iter()
        .map(|r| r.decode_shared().map_err(dm_err("feature")))
        .collect::<Result<_, _>>()?;
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

/// Fits line segments to the sonar echoes of a recent time window, sensor by sensor (each
/// sensor's echoes are ordered along the cart's path), and stores the set in the feature DM.
/// Runs until suspended.
#[derive(Default)]
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
        let d = SegmentParams::default();
        ParamSchema::new(vec![
            ParamDecl::float("window", 8.0)
                .range(0.5, 120.0)
                .unit("s")
                .describe("how far back echoes are used"),
            ParamDecl::float("distance_threshold", d.distance_threshold)
                .range(0.005, 1.0)
                .unit("m")
                .describe("largest distance of an echo from its segment"),
            ParamDecl::int("min_points", d.min_points as i64)
                .range(2.0, 1000.0)
                .describe("fewest echoes a segment needs"),
            ParamDecl::float("max_gap", d.max_gap)
                .range(0.01, 5.0)
                .unit("m")
                .describe("larger jumps between consecutive echoes end a segment"),
            ParamDecl::float("min_length", d.min_length)
                .range(0.0, 50.0)
                .unit("m")
                .describe("shortest segment reported"),
            ParamDecl::choice("beams", &["narrow", "all"], "narrow").describe(
                "which sonar beams to fit: a wide beam's echo is placed on its axis, so its \
                 points sit nearer than the wall they came from",
            ),
            ParamDecl::bool("fresh", false).describe(
                "only echoes heard since this activation (not an earlier stage's, which the \
                 sonar may have heard for the localizer while the cart turned)",
            ),
        ])
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.activated = ctx.now();
        Ok(Step::Continue)
    }

    fn period(&self) -> Duration {
        Duration::from_millis(250)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let window = Duration::from_secs_f64(p.f64("window")?);
        let params = SegmentParams {
            distance_threshold: p.f64("distance_threshold")?,
            min_points: p.i64("min_points")? as usize,
            max_gap: p.f64("max_gap")?,
            min_length: p.f64("min_length")?,
            ..SegmentParams::default()
        };
        let narrow_only = p.text("beams")? == "narrow";
        let mut since = ctx.now().saturating_sub(window);
        if p.bool("fresh")? {
            since = since.max(self.activated);
        }
        let (scans, _) = scans_since(ctx, since, 0).await?;
        // every echo in the frame of the newest correction, whatever it was placed with
        let now = correction(ctx).await?;
        let mut by_sensor: BTreeMap<usize, Vec<Point>> = BTreeMap::new();
        for scan in &scans {
            let frame = Reframe::new(&scan.correction, &now);
            for e in scan.echoes.iter().filter(|e| e.narrow || !narrow_only) {
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
        ctx.dm("feature")?
            .put(
                SEGMENTS,
                Some("current"),
                None,
                &SegmentSet { segments, points },
            )
            .map_err(dm_err("feature"))?;
        self.sets += 1;
        Ok(Step::Continue)
    }

    fn property(&self, name: &str) -> Option<Value> {
        (name == "sets").then_some(Value::Int(self.sets as i64))
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
#[derive(Default)]
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
        let d = WallParams::default();
        ParamSchema::new(vec![
            ParamDecl::float("max_distance", d.max_distance)
                .range(0.1, 20.0)
                .unit("m")
                .describe("farthest a wall may be"),
            ParamDecl::float("min_length", d.min_length)
                .range(0.0, 50.0)
                .unit("m")
                .describe("shortest wall accepted"),
            ParamDecl::choice("side", &["any", "left", "right"], "any")
                .describe("which side of the cart the wall must be on"),
            ParamDecl::float("max_angle", d.max_angle.to_degrees())
                .range(0.0, 90.0)
                .unit("deg")
                .describe("largest angle between the wall and the cart's heading"),
            ParamDecl::bool("continuous", false)
                .describe("keep updating the wall instead of finishing when found"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "wall-found",
            "a wall was found and stored in the world DM",
        )]
    }

    fn period(&self) -> Duration {
        Duration::from_millis(250)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.tracked = newest::<WallRecord>(ctx, "world", WALL)
            .await?
            .map(|w| (w.segment, w.correction));
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let params = WallParams {
            max_distance: p.f64("max_distance")?,
            min_length: p.f64("min_length")?,
            side: match p.text("side")? {
                "left" => Some(Side::Left),
                "right" => Some(Side::Right),
                _ => None,
            },
            max_angle: p.f64("max_angle")?.to_radians(),
            ..WallParams::default()
        };
        let continuous = p.bool("continuous")?;
        let Some(set) = newest::<SegmentSet>(ctx, "feature", SEGMENTS).await? else {
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
                ctx.raise(StatusFlags(1)); // still the same wall, nothing new seen
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
        ctx.dm("world")?
            .store(WALL, Some("followed"), None, &record)
            .await
            .map_err(dm_err("world"))?;
        if continuous {
            ctx.raise(StatusFlags(1));
            Ok(Step::Continue)
        } else {
            Ok(Step::Finish(StatusFlags(1)))
        }
    }
}

/// Looks for a docking spot of the given breadth (along the wall) and depth (into it) in the
/// followed wall, among the echoes gathered since it was activated. Finishes with `dock-found`
/// after storing the dock in the world DM; very sensitive to its parameters (thesis 9.3.2).
#[derive(Default)]
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
        let d = DockParams::default();
        ParamSchema::new(vec![
            ParamDecl::float("breadth", d.breadth)
                .range(0.3, 20.0)
                .unit("m")
                .describe("width of the spot's opening along the wall"),
            ParamDecl::float("depth", d.depth)
                .range(0.1, 10.0)
                .unit("m")
                .describe("depth of the spot behind the wall line"),
            ParamDecl::float("breadth_tolerance", d.breadth_tolerance)
                .range(0.0, 5.0)
                .unit("m")
                .describe("accepted breadth error"),
            ParamDecl::float("depth_tolerance", d.depth_tolerance)
                .range(0.0, 5.0)
                .unit("m")
                .describe("accepted depth error"),
            ParamDecl::choice("beams", &["narrow", "all"], "narrow")
                .describe("which sonar beams to use: wide beams blur the spot's edges"),
            ParamDecl::float("history", 0.0)
                .range(0.0, 3600.0)
                .unit("s")
                .describe("also use echoes from this long before the activation (0: only since)"),
        ])
    }

    fn flags(&self) -> Vec<FlagDecl> {
        vec![FlagDecl::new(
            "dock-found",
            "a docking spot was found and stored in the world DM",
        )]
    }

    fn period(&self) -> Duration {
        Duration::from_millis(500)
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let history = Duration::from_secs_f64(ctx.params().f64("history")?);
        let resumed = match ctx.resumed() {
            true => newest::<SearchRecord>(ctx, "world", SEARCH).await?,
            false => None,
        };
        self.since = match resumed {
            Some(search) => search.since,
            None => {
                let since = ctx.now().saturating_sub(history);
                ctx.dm("world")?
                    .store(SEARCH, Some("since"), None, &SearchRecord { since })
                    .await
                    .map_err(dm_err("world"))?;
                since
            }
        };
        self.next_seq = 0;
        self.echoes.clear();
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p = ctx.params();
        let params = DockParams {
            breadth: p.f64("breadth")?,
            depth: p.f64("depth")?,
            breadth_tolerance: p.f64("breadth_tolerance")?,
            depth_tolerance: p.f64("depth_tolerance")?,
            ..DockParams::default()
        };
        let narrow_only = p.text("beams")? == "narrow";
        let Some(wall) = newest::<WallRecord>(ctx, "world", WALL).await? else {
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
            .filter(|e| e.narrow || !narrow_only)
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
        ctx.dm("world")?
            .store(DOCK, Some("found"), None, &record)
            .await
            .map_err(dm_err("world"))?;
        tracing::info!(
            breadth = dock.breadth,
            depth = dock.depth,
            x = park.x,
            y = park.y,
            "dock found"
        );
        Ok(Step::Finish(StatusFlags(1)))
    }
}

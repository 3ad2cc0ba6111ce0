//! The records the robot's operations exchange through the datamanagers: one [`RecordKind`]
//! per kind of record — its class, sub-class and payload type — in one place, so producer and
//! consumer agree (a misspelt kind does not compile, a payload of another type does not
//! either).
//!
//! | DM | kind | class | sub1 | payload | producer → consumers |
//! |---|---|---|---|---|---|
//! | feature | [`SONAR`] | `sonar` | `scan` | [`EchoScan`] | ultrasonic → segment extractor, docking detector, localizer, picture |
//! | feature | [`SEGMENTS`] | `segments` | `current` | [`SegmentSet`] | segment extractor → wall sensor, wall followers, picture |
//! | world | [`MAP`] | `map` | `walls` | `Vec<Segment>` | node start-up (the a-priori map) → path planner, localizer |
//! | world | [`WALL`] | `wall` | `followed` | [`WallRecord`] | wall sensor → wall follower, controllers, docking detector |
//! | world | [`DOCK`] | `dock` | `found` | [`DockRecord`] | docking detector → path planner |
//! | parameter | [`PATH`] | `path` | `planned` | [`PathRecord`] | path planner → trajectory controller |
//! | parameter | [`PROGRESS`] | `path-progress` | `driven` | [`ProgressRecord`] | trajectory controller → itself, after a restart |
//! | world | [`SEARCH`] | `dock-search` | `since` | [`SearchRecord`] | docking detector → itself, after a restart |
//! | world | [`LOCATION`] | `pose` | `correction` | [`LocationRecord`] | localizer → every operation that places or drives the cart in the map frame |
//!
//! Readers select by the whole kind, class and sub-class: every record of a class here has
//! the one sub-class its kind names.

use crate::geom::{Point, Pose, Segment};
use marie_dm::RecordKind;
use serde::{Deserialize, Serialize};

/// Sonar scans, in the feature DM.
pub const SONAR: RecordKind<EchoScan> = RecordKind::new("sonar").with_sub1("scan");
/// Segments extracted from recent echoes, in the feature DM.
pub const SEGMENTS: RecordKind<SegmentSet> = RecordKind::new("segments").with_sub1("current");
/// The a-priori map (the world's walls), in the world DM.
pub const MAP: RecordKind<Vec<Segment>> = RecordKind::new("map").with_sub1("walls");
/// The followed wall, in the world DM.
pub const WALL: RecordKind<WallRecord> = RecordKind::new("wall").with_sub1("followed");
/// The detected dock, in the world DM.
pub const DOCK: RecordKind<DockRecord> = RecordKind::new("dock").with_sub1("found");
/// Planned paths, in the parameter DM.
pub const PATH: RecordKind<PathRecord> = RecordKind::new("path").with_sub1("planned");
/// The trajectory controller's progress along a path, in the parameter DM.
pub const PROGRESS: RecordKind<ProgressRecord> =
    RecordKind::new("path-progress").with_sub1("driven");
/// The localizer's odometry correction, in the world DM.
pub const LOCATION: RecordKind<LocationRecord> = RecordKind::new("pose").with_sub1("correction");
/// Since when the docking detector gathers echoes, in the world DM.
pub const SEARCH: RecordKind<SearchRecord> = RecordKind::new("dock-search").with_sub1("since");

/// The localizer's correction of the cart's drifting odometry: the cart's pose in the map
/// frame is `correction.compose(odometry)`. Kept in the world DM (the pose is the world's
/// business), so every operation places echoes and drives in one frame — the map's —, and a
/// restarted localizer resumes from the last correction. No record: the identity (the
/// odometry starts at the world's start pose).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LocationRecord {
    /// Odometry frame → map frame.
    pub correction: Pose,
    /// The odometry when the correction was made.
    pub odometry: Pose,
    /// The corrected pose then.
    pub pose: Pose,
    /// Segments matched to map walls for this correction.
    pub matched: usize,
}

/// Since when the docking detector gathers echoes for its search. Kept in the world DM so a
/// detector resuming a lost instance's search (`OpContext::resumed`) still sees the echoes of
/// the spot's near edge, gathered before the crash.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchRecord {
    /// Clock time from which echoes count.
    pub since: std::time::Duration,
}

/// How far the trajectory controller got along a planned path. Kept in the parameter DM, not
/// in the controller, so that a controller restarted after a crash resumes where the crashed
/// one was instead of driving the path again from its start (state that must survive a crash
/// lives outside the actor).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProgressRecord {
    /// Sequence number of the path record in the parameter DM.
    pub path_seq: u64,
    /// Index of the leg being driven.
    pub leg: usize,
    /// Distance driven along that leg, m.
    pub along: f64,
}

/// One sonar echo, placed in the world with the cart's corrected odometry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Echo {
    /// Sensor index.
    pub sensor: usize,
    /// A narrow beam (a precise bearing); wide beams smear edges over their cone.
    pub narrow: bool,
    /// Beam axis angle in the world, rad.
    pub bearing: f64,
    /// Measured range, m.
    pub range: f64,
    /// The echo point (sensor position + range along the axis).
    pub point: Point,
}

/// One scan of all sensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EchoScan {
    /// Simulated time of the scan, s.
    pub time: f64,
    /// The cart's pose when it scanned: its odometry under `correction` (the frame the
    /// echoes are placed in).
    pub pose: Pose,
    /// Echoes (lost readings are left out).
    pub echoes: Vec<Echo>,
    /// The localizer's correction the echoes were placed with (see [`LocationRecord`]), so
    /// the localizer can bring them into its newer frame; identity when absent.
    #[serde(default)]
    pub correction: Pose,
}

impl EchoScan {
    /// Where its echoes were placed, those with a finite position: what the picture and the
    /// live stream draw.
    pub fn points(&self) -> impl Iterator<Item = Point> + '_ {
        self.echoes
            .iter()
            .map(|e| e.point)
            .filter(|p| p.x.is_finite() && p.y.is_finite())
    }
}

/// The segments extracted from recent echoes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSet {
    /// The segments.
    pub segments: Vec<Segment>,
    /// Echo points they were fitted to.
    pub points: usize,
}

/// The followed wall as seen from the cart.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WallRecord {
    /// The wall segment (world frame).
    pub segment: Segment,
    /// Perpendicular distance from the cart to the wall's line, m.
    pub distance: f64,
    /// Angle of the wall relative to the cart's heading, rad.
    pub relative_angle: f64,
    /// +1 when the wall is on the cart's left, -1 on its right.
    pub side: f64,
    /// Cart pose it was measured from.
    pub pose: Pose,
    /// The localizer's correction the wall is placed with (see [`LocationRecord`]): a reader
    /// under a newer correction moves it into its own frame first.
    #[serde(default)]
    pub correction: Pose,
    /// How many segments the wall sensor saw when it picked this wall (the next build's,
    /// feature `next-protocol`: a field added with its default, which the build before
    /// ignores in the records it reads, and which reads as absent in the records that build
    /// stored — `docs/compatibility.md`).
    #[cfg(feature = "next-protocol")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seen_among: Option<u32>,
}

impl WallRecord {
    /// The wall segment in the frame of correction `now`.
    pub fn segment_under(&self, now: &Pose) -> Segment {
        let f = |p| crate::algo::localize::reframe(p, &self.correction, now);
        Segment::new(f(self.segment.a), f(self.segment.b))
    }
}

/// A detected dock.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DockRecord {
    /// The pose a parked cart should have (rear-axle reference).
    pub park: Pose,
    /// The dock's corners (opening first), for pictures.
    pub corners: [Point; 4],
    /// Measured breadth, m.
    pub breadth: f64,
    /// Measured depth, m.
    pub depth: f64,
}

/// One leg of a planned path, driven in one direction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LegRecord {
    /// Waypoints from the leg's start to its end.
    pub waypoints: Vec<Point>,
    /// Heading required at the leg's end, rad.
    pub goal_heading: Option<f64>,
    /// Driven backwards.
    pub reverse: bool,
}

/// A planned path: one or more legs (a manoeuvre changes direction between legs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathRecord {
    /// The legs, in driving order.
    pub legs: Vec<LegRecord>,
}

impl PathRecord {
    /// Every waypoint of every leg, in order (for pictures).
    pub fn waypoints(&self) -> Vec<Point> {
        self.legs
            .iter()
            .flat_map(|l| l.waypoints.iter().copied())
            .collect()
    }
}

/// The next build's field of the followed wall's record, read both ways: what each build
/// does with the other's records in one datamanager.
#[cfg(all(test, feature = "next-protocol"))]
mod next_build {
    use super::*;

    /// The record as the build before the next one has it.
    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct WallRecordBefore {
        segment: Segment,
        distance: f64,
        relative_angle: f64,
        side: f64,
        pose: Pose,
        #[serde(default)]
        correction: Pose,
    }

    fn before() -> WallRecordBefore {
        WallRecordBefore {
            segment: Segment::new(Point::new(0.0, 1.0), Point::new(4.0, 1.0)),
            distance: 1.0,
            relative_angle: 0.1,
            side: 1.0,
            pose: Pose::new(1.0, 0.0, 0.0),
            correction: Pose::default(),
        }
    }

    #[test]
    fn each_build_reads_the_others_wall_records() {
        // the build before's record, read by the next: the field absent
        let old = marie_dm::Payload::encode(&before()).unwrap();
        let read: WallRecord = old.decode().unwrap();
        assert_eq!(read.seen_among, None);
        assert_eq!(read.distance, 1.0);
        // the next build's, read by the build before: the field ignored
        let new = WallRecord {
            seen_among: Some(4),
            ..read
        };
        let bytes = marie_dm::Payload::encode(&new).unwrap();
        assert_eq!(bytes.decode::<WallRecordBefore>().unwrap(), before());
        assert_eq!(bytes.decode::<WallRecord>().unwrap().seen_among, Some(4));
    }
}

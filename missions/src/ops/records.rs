//! The records the robot's operations exchange through the datamanagers: classes and payload
//! types, in one place so producer and consumer agree.
//!
//! | DM | class | sub1 | payload | producer → consumers |
//! |---|---|---|---|---|
//! | feature | `sonar` | `scan` | [`EchoScan`] | ultrasonic → segment extractor, docking detector, picture |
//! | feature | `segments` | `current` | [`SegmentSet`] | segment extractor → wall sensor, docking detector |
//! | world | `map` | `walls` | `Vec<Segment>` | node start-up (the a-priori map) → path planner |
//! | world | `wall` | `followed` | [`WallRecord`] | wall sensor → wall follower, controllers, docking detector |
//! | world | `dock` | `found` | [`DockRecord`] | docking detector → path planner |
//! | parameter | `path` | `planned` | [`PathRecord`] | path planner → trajectory controller |
//! | parameter | `path-progress` | `driven` | [`ProgressRecord`] | trajectory controller → itself, after a restart |
//! | world | `dock-search` | `since` | [`SearchRecord`] | docking detector → itself, after a restart |
//! | world | `pose` | `correction` | [`LocationRecord`] | localizer → every operation that places or drives the cart in the map frame |

use crate::geom::{Point, Pose, Segment};
use serde::{Deserialize, Serialize};

/// Feature DM class of sonar scans.
pub const SONAR: &str = "sonar";
/// Feature DM class of extracted segments.
pub const SEGMENTS: &str = "segments";
/// World DM class of the a-priori map.
pub const MAP: &str = "map";
/// World DM class of the followed wall.
pub const WALL: &str = "wall";
/// World DM class of the detected dock.
pub const DOCK: &str = "dock";
/// Parameter DM class of planned paths.
pub const PATH: &str = "path";
/// Parameter DM class of the trajectory controller's progress along a path.
pub const PROGRESS: &str = "path-progress";

/// World DM class of the localizer's odometry correction.
pub const LOCATION: &str = "pose";

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

/// World DM class of the docking detector's search.
pub const SEARCH: &str = "dock-search";

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

//! The robot in its world: walls, dock, goal, the cart's size, the driven path, the latest
//! sonar echoes, the followed wall, the planned path and the dock found — what the page's
//! robot panel draws, reduced from the robot's [`EventKind::Robot`] events.
//!
//! The contract with the robot (`what` and its `data`) is `marie_telemetry`'s; a
//! cluster's cart node tells its `world` again every few seconds: it replaces the world
//! drawn and leaves the driven path alone. Anything off the contract is ignored here (it
//! may still reach the timeline); data that does not fit it leaves the state as it was.
//!
//! Bounded: the path keeps the latest [`PATH_LIMIT`] poses (halving its resolution rather
//! than dropping its start), and is serialized thinned to at most [`DRAW_LIMIT`] points:
//! the page draws no more, and serializing thins it without copying the state first.
//!
//! [`EventKind::Robot`]: marie_vocabulary::events::EventKind::Robot

use marie_telemetry::{CartPose, Point, Telemetry, WorldData};
use serde::Serialize;
use serde_json::Value;

/// The path keeps at most this many poses.
pub const PATH_LIMIT: usize = 5000;
/// The page is sent at most this many path points.
pub const DRAW_LIMIT: usize = 1000;

/// The robot's part of the state.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RobotView {
    /// The world, once announced.
    pub world: Option<WorldData>,
    /// The latest pose.
    pub pose: Option<CartPose>,
    /// The driven path (bounded, see the module docs); serialized thinned to at most
    /// [`DRAW_LIMIT`] points.
    #[serde(serialize_with = "serialize_thinned")]
    pub path: Vec<Point>,
    /// Poses received in all.
    pub poses: u64,
    /// The latest sonar echoes (world frame).
    pub echoes: Vec<Point>,
    /// The wall being followed.
    pub followed_wall: Option<[Point; 2]>,
    /// The planned path.
    pub planned_path: Vec<Point>,
    /// The dock the detector found.
    pub dock_found: Option<Vec<Point>>,
    /// Collisions reported.
    pub collisions: u64,
}

impl RobotView {
    /// Apply one robot event (`what`, `data`); false when it was not one of the contract's
    /// (or its data did not fit).
    pub fn apply(&mut self, what: &str, data: &Value) -> bool {
        let Some(told) = Telemetry::read(what, data) else {
            return false;
        };
        match told {
            Telemetry::World(w) => self.world = Some(w),
            Telemetry::Pose(p) => self.pose_at(p),
            Telemetry::Echoes(p) => self.echoes = p.points,
            Telemetry::PlannedPath(p) => self.planned_path = p.points,
            Telemetry::FollowedWall(w) => self.followed_wall = Some([w.from, w.to]),
            Telemetry::DockFound(c) => self.dock_found = Some(c.corners),
            Telemetry::Collision(_) => self.collisions += 1,
        }
        true
    }

    fn pose_at(&mut self, pose: CartPose) {
        self.pose = Some(pose);
        self.poses += 1;
        if self.path.len() >= PATH_LIMIT {
            // halve the resolution of what was driven: the whole path stays drawn
            self.path = thin(&self.path, PATH_LIMIT / 2);
        }
        self.path.push([pose.x, pose.y]);
    }
}

/// The path as the page gets it: at most [`DRAW_LIMIT`] points.
#[allow(clippy::ptr_arg)] // serde's `serialize_with` passes the field as it is declared
fn serialize_thinned<S: serde::Serializer>(path: &Vec<Point>, s: S) -> Result<S::Ok, S::Error> {
    if path.len() <= DRAW_LIMIT {
        path.serialize(s)
    } else {
        thin(path, DRAW_LIMIT).serialize(s)
    }
}

/// At most `limit` points of `points`, evenly spaced, the first and the last kept.
pub fn thin(points: &[Point], limit: usize) -> Vec<Point> {
    let n = points.len();
    if n <= limit {
        return points.to_vec();
    }
    if limit < 2 {
        return points.last().copied().into_iter().collect();
    }
    let step = (n - 1) as f64 / (limit - 1) as f64;
    (0..limit)
        .map(|i| points[((i as f64 * step).round() as usize).min(n - 1)])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_contract_events_fill_the_view() {
        let mut r = RobotView::default();
        assert!(r.apply(
            "world",
            &json!({"walls": [[[0.0, 0.0], [5.0, 0.0]]], "dock": [[1.0, 1.0], [2.0, 1.0]],
                    "goal": null, "cart": {"length": 0.6, "width": 0.4}})
        ));
        assert!(r.apply("pose", &json!({"x": 1.0, "y": 2.0, "heading": 0.5})));
        assert!(r.apply("echoes", &json!({"points": [[1.0, 1.0], [2.0, 2.0]]})));
        assert!(r.apply("planned-path", &json!({"points": [[0.0, 0.0], [3.0, 1.0]]})));
        assert!(r.apply(
            "followed-wall",
            &json!({"from": [0.0, 0.0], "to": [5.0, 0.0]})
        ));
        assert!(r.apply("dock-found", &json!({"corners": [[1.0, 1.0], [2.0, 1.0]]})));
        let world = r.world.as_ref().unwrap();
        assert_eq!(world.walls, vec![[[0.0, 0.0], [5.0, 0.0]]]);
        assert_eq!(world.goal, None);
        assert_eq!(world.cart.unwrap().width, 0.4);
        assert_eq!(r.pose.unwrap().heading, 0.5);
        assert_eq!(r.path, vec![[1.0, 2.0]]);
        assert_eq!(r.echoes.len(), 2);
        assert_eq!(r.planned_path[1], [3.0, 1.0]);
        assert_eq!(r.followed_wall, Some([[0.0, 0.0], [5.0, 0.0]]));
        assert_eq!(r.dock_found.as_ref().unwrap().len(), 2);
    }

    #[test]
    fn data_off_the_contract_changes_nothing() {
        let mut r = RobotView::default();
        assert!(!r.apply("pose", &json!({"x": "one"})));
        assert!(!r.apply("echoes", &json!([1, 2])));
        assert!(!r.apply("something-else", &json!({})));
        assert_eq!(r, RobotView::default());
    }

    #[test]
    fn the_path_stays_bounded_and_is_thinned_for_drawing() {
        let mut r = RobotView::default();
        for i in 0..20_000 {
            r.apply("pose", &json!({"x": i as f64, "y": 0.0, "heading": 0.0}));
        }
        assert_eq!(r.poses, 20_000);
        assert!(r.path.len() <= PATH_LIMIT);
        assert_eq!(r.path[0], [0.0, 0.0]);
        assert_eq!(*r.path.last().unwrap(), [19_999.0, 0.0]);
        // what the page gets
        let drawn = serde_json::to_value(&r).unwrap();
        let drawn = drawn["path"].as_array().unwrap();
        assert!(drawn.len() <= DRAW_LIMIT);
        assert_eq!(drawn[0], json!([0.0, 0.0]));
        assert_eq!(*drawn.last().unwrap(), json!([19_999.0, 0.0]));
    }

    #[test]
    fn a_repeated_world_replaces_the_world_and_keeps_what_was_driven() {
        // a cluster's cart node tells its world again every few seconds, mid-run
        let mut r = RobotView::default();
        let world = json!({"walls": [[[0.0, 0.0], [5.0, 0.0]]]});
        // poses may come first to a monitor that joined late
        assert!(r.apply("pose", &json!({"x": 1.0, "y": 1.0, "heading": 0.0})));
        assert!(r.apply("world", &world));
        assert!(r.apply("pose", &json!({"x": 2.0, "y": 1.0, "heading": 0.0})));
        assert!(r.apply("planned-path", &json!({"points": [[2.0, 1.0], [4.0, 1.0]]})));
        let before = r.clone();
        assert!(r.apply("world", &world));
        assert_eq!(r, before);
        assert_eq!(r.path, vec![[1.0, 1.0], [2.0, 1.0]]);
    }

    #[test]
    fn thinning_keeps_short_paths_whole() {
        let pts: Vec<Point> = (0..10).map(|i| [i as f64, 0.0]).collect();
        assert_eq!(thin(&pts, 1000), pts);
        assert_eq!(
            thin(&pts, 4),
            vec![[0.0, 0.0], [3.0, 0.0], [6.0, 0.0], [9.0, 0.0]]
        );
    }
}

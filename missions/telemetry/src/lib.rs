//! # marie-telemetry
//!
//! The contract of the simulated robot's live events: each [`EventKind::Robot`] it
//! publishes has a `what` naming it and its `data` as JSON, and this crate types them once —
//! for the robot that tells them (`marie-missions`' telemetry) and for the viewers that draw
//! them (the monitor's page, the MCAP writer's 3D scene) and word them (a [`Teller`] given
//! [`words`]). Points are `[x, y]` in metres, world frame; angles in radians,
//! counter-clockwise from +x.
//!
//! | `what` | `data` |
//! |---|---|
//! | `world` | [`WorldData`]: `{"walls": [[[x1,y1],[x2,y2]], ...], "dock": [[x,y],...] \| null, "goal": [[x,y],...] \| null, "cart": {"length", "width", "axle_to_centre"}}` |
//! | `pose` | [`CartPose`]: `{"x", "y", "heading"}` — the rear axle |
//! | `echoes` | [`Points`]: `{"points": [[x,y], ...]}` |
//! | `planned-path` | [`Points`] |
//! | `followed-wall` | [`FromTo`]: `{"from": [x,y], "to": [x,y]}` |
//! | `dock-found` | [`Corners`]: `{"corners": [[x,y], ...]}`, the opening first |
//! | `collision` | [`At`]: `{"x", "y"}` — for a robot that tells its collisions as they happen |
//!
//! Why a crate of its own: a viewer needs the contract and nothing of the simulation
//! (no geometry library, no world model), and the monitor depends on the vocabulary and
//! this alone.
//!
//! ```
//! use marie_telemetry::{CartPose, Telemetry};
//! let told = Telemetry::Pose(CartPose { x: 1.0, y: 2.0, heading: 0.0 });
//! let (what, data) = (told.what(), told.data());
//! assert_eq!(what, "pose");
//! assert_eq!(Telemetry::read(what, &data), Some(told.clone()));
//! assert_eq!(told.words(), "pose (1.00, 2.00) heading 0.0°");
//! ```
//!
//! [`EventKind::Robot`]: marie_vocabulary::events::EventKind::Robot
//! [`Teller`]: marie_vocabulary::events::Teller

use marie_vocabulary::events::{EventKind, Gravity};
use serde::{Deserialize, Serialize};
use serde_json::Value;

/// `what` of the world the run drives in.
pub const WORLD: &str = "world";
/// `what` of the cart's sampled pose.
pub const POSE: &str = "pose";
/// `what` of sonar echo points.
pub const ECHOES: &str = "echoes";
/// `what` of a planned path.
pub const PLANNED_PATH: &str = "planned-path";
/// `what` of the followed wall.
pub const FOLLOWED_WALL: &str = "followed-wall";
/// `what` of a detected docking spot.
pub const DOCK_FOUND: &str = "dock-found";
/// `what` of a collision told as it happens.
pub const COLLISION: &str = "collision";

/// A point of the plane, metres, world frame.
pub type Point = [f64; 2];

/// The world: its walls, the dock's recess and the goal area as their corners, the cart's
/// size.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorldData {
    /// Wall segments.
    #[serde(default)]
    pub walls: Vec<[Point; 2]>,
    /// The docking spot's outline.
    #[serde(default)]
    pub dock: Option<Vec<Point>>,
    /// The goal area's outline.
    #[serde(default)]
    pub goal: Option<Vec<Point>>,
    /// The cart's size.
    #[serde(default)]
    pub cart: Option<CartSize>,
}

/// The cart's footprint: the pose is its rear axle, the footprint's centre
/// `axle_to_centre` ahead of it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartSize {
    /// Length, m.
    pub length: f64,
    /// Width, m.
    pub width: f64,
    /// From the rear axle to the footprint's centre, m (0 in older streams).
    #[serde(default)]
    pub axle_to_centre: f64,
}

/// The cart's pose: its rear axle and heading.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartPose {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// Heading, rad.
    pub heading: f64,
}

/// Points: echoes, a path's waypoints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Points {
    /// The points.
    pub points: Vec<Point>,
}

/// A segment: the followed wall.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FromTo {
    /// One end.
    pub from: Point,
    /// The other.
    pub to: Point,
}

/// An outline: the dock found, the opening first.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Corners {
    /// Its corners.
    pub corners: Vec<Point>,
}

/// Where something happened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct At {
    /// x, m.
    #[serde(default)]
    pub x: f64,
    /// y, m.
    #[serde(default)]
    pub y: f64,
}

/// One of the robot's live events, typed.
#[derive(Clone, Debug, PartialEq)]
pub enum Telemetry {
    /// `world`.
    World(WorldData),
    /// `pose`.
    Pose(CartPose),
    /// `echoes`.
    Echoes(Points),
    /// `planned-path`.
    PlannedPath(Points),
    /// `followed-wall`.
    FollowedWall(FromTo),
    /// `dock-found`.
    DockFound(Corners),
    /// `collision`.
    Collision(At),
}

impl Telemetry {
    /// The event `what` names with `data`; `None` for a `what` off the contract or data that
    /// does not fit it.
    pub fn read(what: &str, data: &Value) -> Option<Telemetry> {
        fn parse<T: for<'de> Deserialize<'de>>(data: &Value) -> Option<T> {
            T::deserialize(data).ok()
        }
        Some(match what {
            WORLD => Telemetry::World(parse(data)?),
            POSE => Telemetry::Pose(parse(data)?),
            ECHOES => Telemetry::Echoes(parse(data)?),
            PLANNED_PATH => Telemetry::PlannedPath(parse(data)?),
            FOLLOWED_WALL => Telemetry::FollowedWall(parse(data)?),
            DOCK_FOUND => Telemetry::DockFound(parse(data)?),
            COLLISION => Telemetry::Collision(parse(data)?),
            _ => return None,
        })
    }

    /// Its `what`.
    pub fn what(&self) -> &'static str {
        match self {
            Telemetry::World(_) => WORLD,
            Telemetry::Pose(_) => POSE,
            Telemetry::Echoes(_) => ECHOES,
            Telemetry::PlannedPath(_) => PLANNED_PATH,
            Telemetry::FollowedWall(_) => FOLLOWED_WALL,
            Telemetry::DockFound(_) => DOCK_FOUND,
            Telemetry::Collision(_) => COLLISION,
        }
    }

    /// Its `data`.
    pub fn data(&self) -> Value {
        let data = match self {
            Telemetry::World(w) => serde_json::to_value(w),
            Telemetry::Pose(p) => serde_json::to_value(p),
            Telemetry::Echoes(p) | Telemetry::PlannedPath(p) => serde_json::to_value(p),
            Telemetry::FollowedWall(w) => serde_json::to_value(w),
            Telemetry::DockFound(c) => serde_json::to_value(c),
            Telemetry::Collision(a) => serde_json::to_value(a),
        };
        // plain structs of numbers: always JSON (a NaN is written as null)
        data.unwrap_or(Value::Null)
    }

    /// The [`EventKind::Robot`] that tells it.
    pub fn event(&self) -> EventKind {
        EventKind::Robot {
            what: self.what().to_string(),
            data: self.data(),
        }
    }

    /// It in words, on one line.
    pub fn words(&self) -> String {
        let point = |p: &Point| format!("({:.2}, {:.2})", p[0], p[1]);
        match self {
            Telemetry::World(w) => format!(
                "world: {} walls{}{}",
                w.walls.len(),
                if w.dock.is_some() { ", a dock" } else { "" },
                if w.goal.is_some() { ", a goal" } else { "" },
            ),
            Telemetry::Pose(p) => format!(
                "pose ({:.2}, {:.2}) heading {:.1}°",
                p.x,
                p.y,
                p.heading.to_degrees()
            ),
            Telemetry::Echoes(p) => format!("{} sonar echoes", p.points.len()),
            Telemetry::FollowedWall(w) => format!(
                "following the wall from {} to {}",
                point(&w.from),
                point(&w.to)
            ),
            Telemetry::DockFound(c) => {
                let corners: Vec<String> = c.corners.iter().map(point).collect();
                format!("dock found: {}", corners.join(" "))
            }
            Telemetry::PlannedPath(p) => {
                let end = p
                    .points
                    .last()
                    .map(|p| format!(" to {}", point(p)))
                    .unwrap_or_default();
                format!("planned a path of {} points{end}", p.points.len())
            }
            Telemetry::Collision(a) => format!("collision at {}", point(&[a.x, a.y])),
        }
    }

    /// How grave it is: what the robot tells often is a detail, a collision a warning.
    pub fn gravity(&self) -> Gravity {
        match self {
            Telemetry::Pose(_) | Telemetry::Echoes(_) => Gravity::Detail,
            Telemetry::Collision(_) => Gravity::Warning,
            _ => Gravity::Info,
        }
    }
}

/// The robot's words for a [`Teller`](marie_vocabulary::events::Teller): the contract's
/// events in words and at their gravity, `None` for anything else.
pub fn words(what: &str, data: &Value) -> Option<(String, Gravity)> {
    Telemetry::read(what, data).map(|t| (t.words(), t.gravity()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn every_event_of_the_contract_reads_back_what_it_writes() {
        let all = [
            Telemetry::World(WorldData {
                walls: vec![[[0.0, 0.0], [4.0, 0.0]]],
                dock: Some(vec![[1.0, 1.0], [2.0, 1.0]]),
                goal: None,
                cart: Some(CartSize {
                    length: 1.0,
                    width: 0.6,
                    axle_to_centre: 0.3,
                }),
            }),
            Telemetry::Pose(CartPose {
                x: 1.0,
                y: 2.0,
                heading: 0.5,
            }),
            Telemetry::Echoes(Points {
                points: vec![[1.0, 1.0]],
            }),
            Telemetry::PlannedPath(Points {
                points: vec![[0.0, 0.0], [3.0, 1.0]],
            }),
            Telemetry::FollowedWall(FromTo {
                from: [0.0, 0.0],
                to: [5.0, 0.0],
            }),
            Telemetry::DockFound(Corners {
                corners: vec![[1.0, 1.0]],
            }),
            Telemetry::Collision(At { x: 1.0, y: 2.0 }),
        ];
        for t in all {
            assert_eq!(Telemetry::read(t.what(), &t.data()), Some(t.clone()));
        }
    }

    #[test]
    fn data_off_the_contract_is_not_read() {
        assert_eq!(Telemetry::read(POSE, &json!({"x": "one"})), None);
        assert_eq!(Telemetry::read(ECHOES, &json!([1, 2])), None);
        assert_eq!(Telemetry::read("something-else", &json!({})), None);
        // an older stream's cart has no axle_to_centre
        let world = json!({"walls": [], "cart": {"length": 0.6, "width": 0.4}});
        let Some(Telemetry::World(w)) = Telemetry::read(WORLD, &world) else {
            panic!("a world")
        };
        assert_eq!(w.cart.unwrap().axle_to_centre, 0.0);
    }

    #[test]
    fn the_events_read_as_words_at_their_gravity() {
        let pose = json!({"heading": 3.1, "x": 12.5, "y": 1.5});
        assert_eq!(
            words(POSE, &pose),
            Some(("pose (12.50, 1.50) heading 177.6°".into(), Gravity::Detail))
        );
        assert_eq!(
            words(COLLISION, &json!({"x": 1.0, "y": 2.0})),
            Some(("collision at (1.00, 2.00)".into(), Gravity::Warning))
        );
        assert_eq!(words("weather", &json!({})), None);
    }
}

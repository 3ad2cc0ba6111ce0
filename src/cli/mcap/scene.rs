//! The robot's live events (`robot` events: `world`, `pose`, `echoes`, `planned-path`,
//! `followed-wall`, `dock-found`; `marie_missions::telemetry` has their contract) as
//! Foxglove's 3D scene: lines, boxes, a point cloud and a transform.
//!
//! One topic per thing drawn, each message complete on its own: when Foxglove seeks, its
//! 3D panel takes the latest message of each topic before the new time, so the world
//! (told once, at the start) stays drawn while the cart moves on, and a message that
//! drew only what changed would leave the rest out.
//!
//! Streaming: the scene keeps what its messages need and no more — the cart's size, the
//! latest detections and the driven path, at most [`PATH_LIMIT`] points to the millimetre
//! (halving its resolution when full, as the monitor's path does, so its start stays
//! drawn). Each driven-path message is the whole path (a seek shows it whole), so it goes
//! out at a bounded rate: at most every [`PATH_PERIOD_MS`] of mission time, and no more
//! often than every [`PATH_MS_PER_POINT`] per point it holds — a short path twice a second,
//! a full one every few seconds: about 16 kB of path a second of mission time at most,
//! however long the run — and once more at the end, so the last one holds the last pose.
//! Data off the contract draws nothing (its log line still tells it).

use super::schemas::{
    Color, CubePrimitive, FrameTransform, KeyValue, LinePrimitive, Message, PackedElementField,
    PointCloud, Pose, Quaternion, SceneEntity, SceneUpdate, Time, Topic, Vector3, CART_FRAME,
    WORLD_FRAME,
};
use marie::events::{Event, EventKind};
use marie_monitor::state::robot::thin;
use marie_telemetry::{CartPose, CartSize, Point, Telemetry, WorldData};

/// The driven path keeps at most this many points.
pub(crate) const PATH_LIMIT: usize = 2000;
/// The driven path is published at most this often, ms of mission time.
pub(crate) const PATH_PERIOD_MS: u64 = 500;
/// ... and no more often than this many ms of mission time per point it holds.
pub(crate) const PATH_MS_PER_POINT: u64 = 2;
/// The cart's box is this tall, m (the world is flat: a height to see it by).
const CART_HEIGHT: f64 = 0.3;

const WALL: Color = rgba(0.75, 0.75, 0.75, 1.0);
const DOCK: Color = rgba(0.25, 0.55, 1.0, 1.0);
const GOAL: Color = rgba(0.3, 0.85, 0.35, 1.0);
const CART: Color = rgba(1.0, 0.6, 0.1, 0.75);
const PLANNED: Color = rgba(0.85, 0.35, 0.95, 1.0);
const DRIVEN: Color = rgba(0.1, 0.85, 0.9, 1.0);
const FOLLOWED: Color = rgba(1.0, 0.3, 0.2, 1.0);
const FOUND: Color = rgba(1.0, 0.9, 0.2, 1.0);

const fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

/// What the scene's messages need of the run so far.
#[derive(Debug, Default)]
pub(crate) struct Scene {
    /// The cart's size, once the world told it.
    cart: Option<CartSize>,
    /// The driven path (bounded, see the module docs).
    path: Vec<Point>,
    /// When the driven path was last published.
    path_sent_ms: Option<u64>,
    /// The time of the latest pose not yet in a published path.
    path_pending_ms: Option<u64>,
    /// The wall being followed.
    followed: Option<[Point; 2]>,
    /// The dock the detector found.
    dock_found: Option<Vec<Point>>,
    /// Poses that came before the world told the cart's size, drawn once it does (at
    /// most [`UNDRAWN`]): a cluster's events reach the file as they arrive, and the cart
    /// node's first pose may come before another node's world.
    undrawn: Vec<(CartPose, u64)>,
}

/// Poses kept for drawing until the cart's size is known.
const UNDRAWN: usize = 256;

impl Scene {
    /// The messages `event` makes (none but for the robot's live events).
    pub(crate) fn apply(
        &mut self,
        event: &Event,
        out: &mut Vec<Message>,
    ) -> Result<(), serde_json::Error> {
        let EventKind::Robot { what, data } = &event.kind else {
            return Ok(());
        };
        let at = event.at_ms;
        // data off the contract draws nothing (its log line still tells it)
        match Telemetry::read(what, data) {
            Some(Telemetry::World(world)) => {
                self.cart = world.cart.or(self.cart);
                out.push(Message::new(Topic::World, at, &world_update(&world, at))?);
                if let Some(cart) = self.cart {
                    for (pose, at) in std::mem::take(&mut self.undrawn) {
                        out.push(cart_box(cart, pose, at)?);
                    }
                }
            }
            Some(Telemetry::Pose(pose)) => self.pose(pose, at, out)?,
            Some(Telemetry::Echoes(echoes)) => {
                out.push(Message::new(Topic::Echoes, at, &cloud(&echoes.points, at))?);
            }
            Some(Telemetry::PlannedPath(path)) => {
                let line = strip("planned-path", at, &path.points, PLANNED, 2.0);
                out.push(Message::new(
                    Topic::PlannedPath,
                    at,
                    &SceneUpdate::of(vec![line]),
                )?);
            }
            Some(Telemetry::FollowedWall(wall)) => {
                self.followed = Some([wall.from, wall.to]);
                out.push(self.detections(at)?);
            }
            Some(Telemetry::DockFound(dock)) => {
                self.dock_found = Some(dock.corners);
                out.push(self.detections(at)?);
            }
            Some(Telemetry::Collision(_)) | None => {}
        }
        Ok(())
    }

    /// The messages due at the end: the driven path, if poses came since it was last sent.
    pub(crate) fn finish(&mut self, out: &mut Vec<Message>) -> Result<(), serde_json::Error> {
        if let Some(at) = self.path_pending_ms.take() {
            out.push(self.driven(at)?);
        }
        Ok(())
    }

    fn pose(
        &mut self,
        pose: CartPose,
        at: u64,
        out: &mut Vec<Message>,
    ) -> Result<(), serde_json::Error> {
        let axle = Vector3::at([pose.x, pose.y], 0.0);
        let heading = Quaternion::yaw(pose.heading);
        out.push(Message::new(
            Topic::Transforms,
            at,
            &FrameTransform {
                timestamp: Time::from_ms(at),
                parent_frame_id: WORLD_FRAME,
                child_frame_id: CART_FRAME,
                translation: axle,
                rotation: heading,
            },
        )?);
        match self.cart {
            Some(cart) => out.push(cart_box(cart, pose, at)?),
            None if self.undrawn.len() < UNDRAWN => self.undrawn.push((pose, at)),
            None => {}
        }
        if self.path.len() >= PATH_LIMIT {
            self.path = thin(&self.path, PATH_LIMIT / 2);
        }
        self.path.push([to_mm(pose.x), to_mm(pose.y)]);
        let every = PATH_PERIOD_MS.max(self.path.len() as u64 * PATH_MS_PER_POINT);
        match self.path_sent_ms {
            Some(sent) if at < sent.saturating_add(every) => {
                self.path_pending_ms = Some(at);
            }
            _ => {
                self.path_sent_ms = Some(at);
                self.path_pending_ms = None;
                out.push(self.driven(at)?);
            }
        }
        Ok(())
    }

    fn driven(&self, at: u64) -> Result<Message, serde_json::Error> {
        let line = strip("driven-path", at, &self.path, DRIVEN, 2.0);
        Message::new(Topic::DrivenPath, at, &SceneUpdate::of(vec![line]))
    }

    /// Every detection so far, in one message (see the module docs).
    fn detections(&self, at: u64) -> Result<Message, serde_json::Error> {
        let mut entities = Vec::new();
        if let Some([from, to]) = self.followed {
            entities.push(strip("followed-wall", at, &[from, to], FOLLOWED, 4.0));
        }
        if let Some(corners) = &self.dock_found {
            let mut e = SceneEntity::new("dock-found", at);
            e.lines.push(LinePrimitive::new(
                LinePrimitive::LOOP,
                on_floor(corners),
                3.0,
                FOUND,
            ));
            entities.push(e);
        }
        Message::new(Topic::Detections, at, &SceneUpdate::of(entities))
    }
}

/// `m` metres to the millimetre: what a drawn path needs, in fewer digits of JSON.
fn to_mm(m: f64) -> f64 {
    (m * 1000.0).round() / 1000.0
}

fn on_floor(points: &[Point]) -> Vec<Vector3> {
    points.iter().map(|p| Vector3::at(*p, 0.0)).collect()
}

fn meta(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value,
    }
}

/// Entity `id`: a line strip through `points`.
fn strip(id: &'static str, at: u64, points: &[Point], color: Color, px: f64) -> SceneEntity {
    let mut e = SceneEntity::new(id, at);
    e.lines.push(LinePrimitive::new(
        LinePrimitive::STRIP,
        on_floor(points),
        px,
        color,
    ));
    e
}

/// The world: its walls (one line list: each wall a segment), its dock and goal outlines.
fn world_update(world: &WorldData, at: u64) -> SceneUpdate {
    let mut walls = SceneEntity::new("walls", at);
    let ends: Vec<Point> = world.walls.iter().flatten().copied().collect();
    walls.lines.push(LinePrimitive::new(
        LinePrimitive::LIST,
        on_floor(&ends),
        2.0,
        WALL,
    ));
    walls.metadata = vec![meta("walls", world.walls.len().to_string())];
    let mut entities = vec![walls];
    for (id, outline, color) in [("dock", &world.dock, DOCK), ("goal", &world.goal, GOAL)] {
        if let Some(outline) = outline {
            let mut e = SceneEntity::new(id, at);
            e.lines.push(LinePrimitive::new(
                LinePrimitive::LOOP,
                on_floor(outline),
                2.0,
                color,
            ));
            entities.push(e);
        }
    }
    SceneUpdate::of(entities)
}

/// The echoes as a point cloud: x, y, z as little-endian float32, 12 bytes a point.
fn cloud(points: &[Point], at: u64) -> PointCloud {
    let mut bytes = Vec::with_capacity(points.len() * 12);
    for p in points {
        for v in [p[0] as f32, p[1] as f32, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name, offset| PackedElementField {
        name,
        offset,
        kind: FLOAT32,
    };
    PointCloud {
        timestamp: Time::from_ms(at),
        frame_id: WORLD_FRAME,
        pose: Pose::ORIGIN,
        point_stride: 12,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        data: base64(&bytes),
    }
}

/// Foxglove's `NumericType` FLOAT32.
const FLOAT32: u8 = 7;

/// Standard base64 with padding: what a JSON message carries of Foxglove's `bytes`.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> shift) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The cart's box at `pose`, at `at`: its footprint's centre `axle_to_centre` ahead of the
/// rear axle the pose gives.
fn cart_box(cart: CartSize, pose: CartPose, at: u64) -> Result<Message, serde_json::Error> {
    let heading = Quaternion::yaw(pose.heading);
    let (sin, cos) = pose.heading.sin_cos();
    let centre = [
        pose.x + cart.axle_to_centre * cos,
        pose.y + cart.axle_to_centre * sin,
    ];
    let mut entity = SceneEntity::new("cart", at);
    entity.cubes.push(CubePrimitive {
        pose: Pose {
            position: Vector3::at(centre, CART_HEIGHT / 2.0),
            orientation: heading,
        },
        size: Vector3 {
            x: cart.length,
            y: cart.width,
            z: CART_HEIGHT,
        },
        color: CART,
    });
    entity.metadata = vec![
        meta("x", format!("{:.3}", pose.x)),
        meta("y", format!("{:.3}", pose.y)),
        meta("heading", format!("{:.1}°", pose.heading.to_degrees())),
    ];
    Message::new(Topic::Cart, at, &SceneUpdate::of(vec![entity]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::mcap::schemas::tests::fits;
    use serde_json::{json, Value};

    fn robot(at_ms: u64, what: &str, data: Value) -> Event {
        Event {
            at_ms,
            node: "embedded".into(),
            kind: EventKind::Robot {
                what: what.into(),
                data,
            },
        }
    }

    fn run(events: &[Event]) -> Vec<Message> {
        let mut scene = Scene::default();
        let mut out = Vec::new();
        for e in events {
            scene.apply(e, &mut out).unwrap();
        }
        scene.finish(&mut out).unwrap();
        out
    }

    fn json_of(m: &Message) -> Value {
        serde_json::from_slice(&m.data).unwrap()
    }

    #[test]
    fn base64_is_the_standard_one() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
        assert_eq!(base64(&[0xff, 0xfe, 0x00, 0x01]), "//4AAQ==");
    }

    #[test]
    fn a_pose_that_came_before_the_world_is_drawn_once_the_cart_size_is_known() {
        // a cluster's relay: the cart node's first pose before another node's world
        let world = json!({"cart":{"axle_to_centre":0.35,"length":1.0,"width":0.6},
            "dock":[], "goal":[], "walls":[]});
        let out = run(&[
            robot(10, "pose", json!({"heading":0.0,"x":1.0,"y":0.0})),
            robot(15, "world", world),
            robot(20, "pose", json!({"heading":0.0,"x":1.1,"y":0.0})),
        ]);
        let carts: Vec<u64> = out
            .iter()
            .filter(|m| m.topic == Topic::Cart)
            .map(|m| m.at_ms)
            .collect();
        assert_eq!(carts, [10, 20], "every pose drawn, each at its own time");
        let first = json_of(out.iter().find(|m| m.topic == Topic::Cart).unwrap());
        assert_eq!(first["entities"][0]["metadata"][0]["value"], "1.000");
    }

    #[test]
    fn the_documented_robot_events_draw_the_scene_and_fit_their_schemas() {
        let world = json!({"cart":{"axle_to_centre":0.35,"length":1.0,"width":0.6},
            "dock":[[4.0,-0.8],[6.8,-0.8],[6.8,0.0],[4.0,0.0]],
            "goal":[[6.8,0.0],[4.0,0.0],[4.0,-0.8],[6.8,-0.8]],
            "walls":[[[0.0,0.0],[4.0,0.0]],[[4.0,0.0],[4.0,-0.8]]]});
        let out = run(&[
            robot(0, "world", world),
            robot(20, "pose", json!({"heading":0.0,"x":12.5,"y":1.5})),
            robot(2000, "echoes", json!({"points":[[12.1,0.02],[11.9,-0.01]]})),
            robot(
                2250,
                "followed-wall",
                json!({"from":[12.5,0.0],"to":[11.52,0.0]}),
            ),
            robot(
                38750,
                "dock-found",
                json!({"corners":[[6.75,0.0],[4.09,0.02],[4.08,-0.8],[6.75,-0.82]]}),
            ),
            robot(
                38750,
                "planned-path",
                json!({"points":[[4.66,0.82],[4.61,0.82],[5.4,-0.4]]}),
            ),
            robot(4000, "collision", json!({"x":1.0,"y":2.0})),
        ]);
        let topics: Vec<&str> = out.iter().map(|m| m.topic.name()).collect();
        assert_eq!(
            topics,
            [
                "/world",
                "/tf",
                "/cart",
                "/path/driven",
                "/echoes",
                "/detections",
                "/detections",
                "/path/planned"
            ]
        );
        for m in &out {
            let schema: Value = serde_json::from_str(&m.topic.schema()).unwrap();
            fits(&json_of(m), &schema, m.topic.name());
        }
        let world = json_of(&out[0]);
        assert_eq!(world["entities"][0]["lines"][0]["type"], 2);
        assert_eq!(world["entities"][0]["lines"][0]["points"][3]["y"], -0.8);
        assert_eq!(world["entities"][1]["id"], "dock");
        // the footprint's centre is ahead of the rear axle
        let cart = json_of(&out[2]);
        let cube = &cart["entities"][0]["cubes"][0];
        assert_eq!(cube["pose"]["position"]["x"], 12.85);
        assert_eq!(cube["size"]["x"], 1.0);
        assert_eq!(cube["size"]["y"], 0.6);
        let cloud = json_of(&out[4]);
        assert_eq!(cloud["data"].as_str().unwrap().len(), 2 * 12 / 3 * 4);
        // a later detection keeps the earlier one drawn
        let found = json_of(&out[6]);
        assert_eq!(found["entities"][0]["id"], "followed-wall");
        assert_eq!(found["entities"][1]["id"], "dock-found");
    }

    #[test]
    fn the_driven_path_goes_out_at_a_bounded_rate_bounded_in_size_and_whole_at_the_end() {
        let poses: Vec<Event> = (0..4500u64)
            .map(|i| {
                let x = i as f64 + 0.123_456;
                robot(i * 100, "pose", json!({"x": x, "y": 0.0, "heading": 0.0}))
            })
            .collect();
        let out = run(&poses);
        let driven: Vec<&Message> = out
            .iter()
            .filter(|m| m.topic == Topic::DrivenPath)
            .collect();
        // the first pose's; then every 0.5 s up to 250 points, 2 ms a point after (a path
        // of 2000 points every 4 s): far fewer than one every 0.5 s of the 450 s
        assert!(driven.len() > 100 && driven.len() < 450, "{}", driven.len());
        let bytes: usize = driven.iter().map(|m| m.data.len()).sum();
        assert!(bytes < 450 * 16_000, "{bytes} bytes of path");
        for pair in driven.windows(2) {
            assert!(pair[1].at_ms >= pair[0].at_ms + PATH_PERIOD_MS);
        }
        // the last one: at the last pose, the whole path, bounded
        let last = driven[driven.len() - 1];
        assert_eq!(last.at_ms, 449_900);
        let last = json_of(last);
        let points = last["entities"][0]["lines"][0]["points"]
            .as_array()
            .unwrap();
        assert!(points.len() <= PATH_LIMIT);
        assert_eq!(points[0]["x"], 0.123);
        assert_eq!(points[points.len() - 1]["x"], 4499.123);
        // no world: no cart size, so no box — the transform still goes out
        assert_eq!(out.iter().filter(|m| m.topic == Topic::Cart).count(), 0);
        assert_eq!(
            out.iter().filter(|m| m.topic == Topic::Transforms).count(),
            4500
        );
    }

    #[test]
    fn data_off_the_contract_draws_nothing() {
        let out = run(&[
            robot(0, "pose", json!({"x": "one"})),
            robot(0, "echoes", json!([1, 2])),
            robot(0, "world", json!("flat")),
        ]);
        assert!(out.is_empty());
    }
}

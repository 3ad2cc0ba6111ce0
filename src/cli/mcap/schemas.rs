//! The shapes of what an MCAP file of a run holds: its topics, the JSON Schema each
//! topic's channel names, and the Rust types whose JSON is a message of that schema — side
//! by side, so that a field added to a type is added to its schema in the same place.
//!
//! The topics' schemas are Foxglove's well-known ones (`foxglove.SceneUpdate`,
//! `foxglove.FrameTransform`, `foxglove.PointCloud`, `foxglove.Log`: Foxglove draws a
//! channel by its schema's name) plus `marie.ControlState` for the task tree. The schema
//! texts are our own compact JSON Schemas of the fields we write, not Foxglove's files
//! (<https://github.com/foxglove/foxglove-sdk>, `schemas/jsonschema`): Foxglove reads a
//! `jsonschema` channel's schema only to learn the fields' types — for the message-path
//! editor and to turn a `contentEncoding: base64` string back into bytes — so every
//! object in them has `type` and `properties`, every property a `type` (Foxglove's parser
//! refuses a property without one, a `null` type and arrays of arrays), and nothing
//! refers elsewhere (no `$ref`). A test below holds every message to its schema.

use serde::Serialize;
use serde_json::{json, Value};

/// A topic of the file: one channel each, registered on first use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Topic {
    /// Every event, as a log line.
    Events,
    /// The task tree and its state.
    Control,
    /// The world: walls, dock, goal.
    World,
    /// The cart's footprint at each pose.
    Cart,
    /// `world` → `cart` at each pose.
    Transforms,
    /// The sonar echoes.
    Echoes,
    /// The planned path.
    PlannedPath,
    /// The driven path.
    DrivenPath,
    /// What the operations found: the followed wall, the dock.
    Detections,
}

impl Topic {
    /// Every topic, in the order a summary lists them.
    pub(crate) const ALL: [Topic; 9] = [
        Topic::Events,
        Topic::Control,
        Topic::World,
        Topic::Cart,
        Topic::Transforms,
        Topic::Echoes,
        Topic::PlannedPath,
        Topic::DrivenPath,
        Topic::Detections,
    ];

    /// Its place in [`Topic::ALL`] (declared in that order).
    pub(crate) fn index(self) -> usize {
        self as usize
    }

    /// The topic's name.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Topic::World => "/world",
            Topic::Cart => "/cart",
            Topic::Transforms => "/tf",
            Topic::Echoes => "/echoes",
            Topic::PlannedPath => "/path/planned",
            Topic::DrivenPath => "/path/driven",
            Topic::Detections => "/detections",
            Topic::Events => "/events",
            Topic::Control => "/control",
        }
    }

    /// The name of its schema: how Foxglove knows what to draw.
    pub(crate) fn schema_name(self) -> &'static str {
        match self {
            Topic::World | Topic::Cart | Topic::PlannedPath | Topic::DrivenPath => SCENE_UPDATE,
            Topic::Detections => SCENE_UPDATE,
            Topic::Transforms => "foxglove.FrameTransform",
            Topic::Echoes => "foxglove.PointCloud",
            Topic::Events => "foxglove.Log",
            Topic::Control => "marie.ControlState",
        }
    }

    /// Its schema, a JSON Schema text.
    pub(crate) fn schema(self) -> String {
        let schema = match self {
            Topic::World | Topic::Cart | Topic::PlannedPath | Topic::DrivenPath => scene_update(),
            Topic::Detections => scene_update(),
            Topic::Transforms => frame_transform(),
            Topic::Echoes => point_cloud(),
            Topic::Events => log(),
            Topic::Control => control_state(),
        };
        schema.to_string()
    }
}

const SCENE_UPDATE: &str = "foxglove.SceneUpdate";

/// One message for a topic: its JSON, and the mission time it is logged at.
#[derive(Debug)]
pub(crate) struct Message {
    /// Its topic.
    pub topic: Topic,
    /// Its log time, mission clock ms.
    pub at_ms: u64,
    /// Its JSON text.
    pub data: Vec<u8>,
}

impl Message {
    /// `message` as JSON on `topic` at `at_ms`.
    pub(crate) fn new(
        topic: Topic,
        at_ms: u64,
        message: &impl Serialize,
    ) -> Result<Message, serde_json::Error> {
        Ok(Message {
            topic,
            at_ms,
            data: serde_json::to_vec(message)?,
        })
    }
}

// --- the messages' parts, as Foxglove names them ---

/// A time (`timestamp`) or a duration (`lifetime`): whole seconds and nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub(crate) struct Time {
    /// Seconds.
    pub sec: u64,
    /// Nanoseconds, below a second.
    pub nsec: u32,
}

impl Time {
    /// The mission clock's `ms` as a time.
    pub(crate) fn from_ms(ms: u64) -> Time {
        Time {
            sec: ms / 1000,
            // below 1e9: fits
            nsec: ((ms % 1000) * 1_000_000) as u32,
        }
    }
}

/// A point or a vector, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub(crate) struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Vector3 {
    /// The plane's `[x, y]` at height `z`.
    pub(crate) fn at(p: [f64; 2], z: f64) -> Vector3 {
        Vector3 {
            x: p[0],
            y: p[1],
            z,
        }
    }
}

/// An orientation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub(crate) struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Quaternion {
    /// No rotation.
    pub(crate) const IDENTITY: Quaternion = Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };

    /// A heading in the plane: `rad` counter-clockwise from +x, about +z.
    pub(crate) fn yaw(rad: f64) -> Quaternion {
        let half = rad / 2.0;
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: half.sin(),
            w: half.cos(),
        }
    }
}

/// A position and an orientation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub(crate) struct Pose {
    /// Position.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Pose {
    /// The frame's origin.
    pub(crate) const ORIGIN: Pose = Pose {
        position: Vector3 {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        orientation: Quaternion::IDENTITY,
    };
}

/// A colour, each channel 0..1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub(crate) struct Color {
    /// Red.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
    /// Opacity.
    pub a: f64,
}

/// `foxglove.LinePrimitive`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct LinePrimitive {
    /// 0 line strip, 1 line loop (closed), 2 line list (pairs of points).
    #[serde(rename = "type")]
    pub kind: u8,
    /// Origin of the points.
    pub pose: Pose,
    /// Thickness: pixels when `scale_invariant`, else metres.
    pub thickness: f64,
    /// Whether `thickness` is in pixels.
    pub scale_invariant: bool,
    /// The points.
    pub points: Vec<Vector3>,
    /// The line's colour.
    pub color: Color,
    /// Colours per point: none.
    pub colors: Vec<Color>,
    /// Indices into `points`: none (all, in order).
    pub indices: Vec<u32>,
}

impl LinePrimitive {
    /// A line strip.
    pub(crate) const STRIP: u8 = 0;
    /// A closed polygon.
    pub(crate) const LOOP: u8 = 1;
    /// Separate segments: points 0-1, 2-3, ...
    pub(crate) const LIST: u8 = 2;

    /// A line of `kind` through `points` (world frame, on the floor), `thickness` pixels.
    pub(crate) fn new(kind: u8, points: Vec<Vector3>, thickness: f64, color: Color) -> Self {
        LinePrimitive {
            kind,
            pose: Pose::ORIGIN,
            thickness,
            scale_invariant: true,
            points,
            color,
            colors: Vec::new(),
            indices: Vec::new(),
        }
    }
}

/// `foxglove.CubePrimitive`: a box.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct CubePrimitive {
    /// Its centre and orientation.
    pub pose: Pose,
    /// Its size along its axes.
    pub size: Vector3,
    /// Its colour.
    pub color: Color,
}

/// A primitive kind we never write: the field is there because the schema has it.
type None0 = [(); 0];

/// `foxglove.SceneEntity`: one thing of the 3D scene, made of primitives; a later entity
/// of the same `id` on the same topic replaces it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct SceneEntity {
    /// When.
    pub timestamp: Time,
    /// Its frame.
    pub frame_id: &'static str,
    /// Its id on the topic.
    pub id: &'static str,
    /// How long it shows: zero, until replaced.
    pub lifetime: Time,
    /// Whether it moves with its frame.
    pub frame_locked: bool,
    /// Key-value pairs shown when it is picked.
    pub metadata: Vec<KeyValue>,
    /// Arrows: none.
    pub arrows: None0,
    /// Boxes.
    pub cubes: Vec<CubePrimitive>,
    /// Spheres: none.
    pub spheres: None0,
    /// Cylinders: none.
    pub cylinders: None0,
    /// Lines.
    pub lines: Vec<LinePrimitive>,
    /// Triangles: none.
    pub triangles: None0,
    /// Texts: none.
    pub texts: None0,
    /// Models: none.
    pub models: None0,
}

impl SceneEntity {
    /// Entity `id` in the world frame at `at_ms`, without primitives yet.
    pub(crate) fn new(id: &'static str, at_ms: u64) -> SceneEntity {
        SceneEntity {
            timestamp: Time::from_ms(at_ms),
            frame_id: WORLD_FRAME,
            id,
            lifetime: Time::default(),
            frame_locked: false,
            metadata: Vec::new(),
            arrows: [],
            cubes: Vec::new(),
            spheres: [],
            cylinders: [],
            lines: Vec::new(),
            triangles: [],
            texts: [],
            models: [],
        }
    }
}

/// A key and its value.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct KeyValue {
    /// Key.
    pub key: String,
    /// Value.
    pub value: String,
}

/// `foxglove.SceneUpdate`: entities added or replaced.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct SceneUpdate {
    /// Deletions: none (an entity is replaced by its id instead).
    pub deletions: None0,
    /// The entities.
    pub entities: Vec<SceneEntity>,
}

impl SceneUpdate {
    /// An update of `entities`.
    pub(crate) fn of(entities: Vec<SceneEntity>) -> SceneUpdate {
        SceneUpdate {
            deletions: [],
            entities,
        }
    }
}

/// The frame everything is drawn in: the world's, metres.
pub(crate) const WORLD_FRAME: &str = "world";
/// The cart's frame: its rear axle, x ahead.
pub(crate) const CART_FRAME: &str = "cart";

/// `foxglove.FrameTransform`: where a child frame is in its parent.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct FrameTransform {
    /// When.
    pub timestamp: Time,
    /// The parent frame.
    pub parent_frame_id: &'static str,
    /// The child frame.
    pub child_frame_id: &'static str,
    /// The child's origin in the parent.
    pub translation: Vector3,
    /// The child's orientation in the parent.
    pub rotation: Quaternion,
}

/// `foxglove.PackedElementField`: a field of each point of a cloud's `data`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct PackedElementField {
    /// `x`, `y`, `z`, ...
    pub name: &'static str,
    /// Its offset in a point, bytes.
    pub offset: u32,
    /// Its numeric type: 7 is FLOAT32.
    #[serde(rename = "type")]
    pub kind: u8,
}

/// `foxglove.PointCloud`: points packed in bytes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct PointCloud {
    /// When.
    pub timestamp: Time,
    /// The frame of the points.
    pub frame_id: &'static str,
    /// The cloud's origin in its frame.
    pub pose: Pose,
    /// Bytes per point.
    pub point_stride: u32,
    /// The fields of each point.
    pub fields: Vec<PackedElementField>,
    /// The points, base64 (what JSON carries of Foxglove's `bytes`).
    pub data: String,
}

/// `foxglove.Log`: a log line.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub(crate) struct Log {
    /// When.
    pub timestamp: Time,
    /// 1 DEBUG, 2 INFO, 3 WARNING, 4 ERROR, 5 FATAL.
    pub level: u8,
    /// The text.
    pub message: String,
    /// Who: the node.
    pub name: String,
    /// Source file: none.
    pub file: &'static str,
    /// Source line: none.
    pub line: u32,
}

// --- the schema texts ---

fn typed(t: &str) -> Value {
    json!({ "type": t })
}

fn object(title: &str, properties: Value) -> Value {
    json!({ "title": title, "type": "object", "properties": properties })
}

fn array(items: Value) -> Value {
    json!({ "type": "array", "items": items })
}

fn time(description: &str) -> Value {
    json!({
        "type": "object", "title": "time", "description": description,
        "properties": { "sec": typed("integer"), "nsec": typed("integer") }
    })
}

fn vector3(title: &str) -> Value {
    let n = typed("number");
    object(title, json!({ "x": n, "y": n, "z": n }))
}

fn quaternion() -> Value {
    let n = typed("number");
    object(
        "foxglove.Quaternion",
        json!({ "x": n, "y": n, "z": n, "w": n }),
    )
}

fn pose() -> Value {
    object(
        "foxglove.Pose",
        json!({ "position": vector3("foxglove.Vector3"), "orientation": quaternion() }),
    )
}

fn color() -> Value {
    let n = typed("number");
    object("foxglove.Color", json!({ "r": n, "g": n, "b": n, "a": n }))
}

/// An enum of numbered values, as Foxglove's schemas write them.
fn numbered(title: &str, values: &[(&str, u8)]) -> Value {
    let one_of: Vec<Value> = values
        .iter()
        .map(|(name, n)| json!({ "title": name, "const": n }))
        .collect();
    json!({ "title": title, "oneOf": one_of })
}

/// The array of a primitive kind we never write.
fn unused(title: &str) -> Value {
    array(object(title, json!({})))
}

fn scene_update() -> Value {
    let line = object(
        "foxglove.LinePrimitive",
        json!({
            "type": numbered("foxglove.LineType", &[("LINE_STRIP", 0), ("LINE_LOOP", 1), ("LINE_LIST", 2)]),
            "pose": pose(),
            "thickness": typed("number"),
            "scale_invariant": typed("boolean"),
            "points": array(vector3("foxglove.Point3")),
            "color": color(),
            "colors": array(color()),
            "indices": array(typed("integer")),
        }),
    );
    let cube = object(
        "foxglove.CubePrimitive",
        json!({ "pose": pose(), "size": vector3("foxglove.Vector3"), "color": color() }),
    );
    let entity = object(
        "foxglove.SceneEntity",
        json!({
            "timestamp": time("Timestamp of the entity"),
            "frame_id": typed("string"),
            "id": typed("string"),
            "lifetime": time("How long the entity shows; zero: until replaced"),
            "frame_locked": typed("boolean"),
            "metadata": array(object("foxglove.KeyValuePair", json!({ "key": typed("string"), "value": typed("string") }))),
            "arrows": unused("foxglove.ArrowPrimitive"),
            "cubes": array(cube),
            "spheres": unused("foxglove.SpherePrimitive"),
            "cylinders": unused("foxglove.CylinderPrimitive"),
            "lines": array(line),
            "triangles": unused("foxglove.TriangleListPrimitive"),
            "texts": unused("foxglove.TextPrimitive"),
            "models": unused("foxglove.ModelPrimitive"),
        }),
    );
    let mut schema = object(
        SCENE_UPDATE,
        json!({
            "deletions": unused("foxglove.SceneEntityDeletion"),
            "entities": array(entity),
        }),
    );
    schema["description"] = json!("An update to the entities displayed in a 3D scene");
    schema
}

fn frame_transform() -> Value {
    object(
        "foxglove.FrameTransform",
        json!({
            "timestamp": time("Timestamp of transform"),
            "parent_frame_id": typed("string"),
            "child_frame_id": typed("string"),
            "translation": vector3("foxglove.Vector3"),
            "rotation": quaternion(),
        }),
    )
}

fn point_cloud() -> Value {
    let field = object(
        "foxglove.PackedElementField",
        json!({
            "name": typed("string"),
            "offset": typed("integer"),
            "type": numbered("foxglove.NumericType", &[
                ("UNKNOWN", 0), ("UINT8", 1), ("INT8", 2), ("UINT16", 3), ("INT16", 4),
                ("UINT32", 5), ("INT32", 6), ("FLOAT32", 7), ("FLOAT64", 8),
            ]),
        }),
    );
    object(
        "foxglove.PointCloud",
        json!({
            "timestamp": time("Timestamp of point cloud"),
            "frame_id": typed("string"),
            "pose": pose(),
            "point_stride": typed("integer"),
            "fields": array(field),
            "data": { "type": "string", "contentEncoding": "base64" },
        }),
    )
}

fn log() -> Value {
    object(
        "foxglove.Log",
        json!({
            "timestamp": time("Timestamp of log message"),
            "level": numbered("foxglove.LogLevel", &[
                ("UNKNOWN", 0), ("DEBUG", 1), ("INFO", 2), ("WARNING", 3), ("ERROR", 4), ("FATAL", 5),
            ]),
            "message": typed("string"),
            "name": typed("string"),
            "file": typed("string"),
            "line": typed("integer"),
        }),
    )
}

/// `/control`'s: see [`super::tree::ControlState`].
fn control_state() -> Value {
    let (s, i) = (typed("string"), typed("integer"));
    let item = object(
        "marie.TreeItem",
        json!({
            "id": i, "parent": i, "depth": i, "kind": s, "label": s, "detail": s,
            "status": s, "starts": i, "attempt": array(i.clone()), "told": i,
            "decisions": array(object("marie.Decision", json!({ "run_ms": i, "text": s }))),
        }),
    );
    let mut schema = object(
        "marie.ControlState",
        json!({
            "timestamp": time("When the state changed"),
            "run_ms": i,
            "event": s,
            "text": s,
            "mission": s,
            "outcome": s,
            "active": s,
            "running": array(s.clone()),
            "plan": i,
            "items": array(item),
        }),
    );
    schema["description"] = json!(
        "The mission's task tree after an event that changed it: the actions running, each node's status"
    );
    schema
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// What Foxglove's JSON Schema reader accepts: an object with `properties`, each with a
    /// type it knows (or numbered `oneOf`), arrays of anything but arrays.
    fn foxglove_reads(schema: &Value, at: &str) {
        assert_eq!(schema["type"], "object", "{at}: not an object");
        let props = schema["properties"]
            .as_object()
            .unwrap_or_else(|| panic!("{at}: no properties"));
        for (name, p) in props {
            let at = format!("{at}.{name}");
            if let Some(alts) = p["oneOf"].as_array() {
                assert!(alts.iter().all(|a| a["const"].is_number()), "{at}");
                continue;
            }
            match p["type"].as_str() {
                Some("boolean" | "number" | "integer") => {}
                Some("string") => assert!(
                    p.get("contentEncoding").is_none() || p["contentEncoding"] == "base64",
                    "{at}"
                ),
                Some("object") => foxglove_reads(p, &at),
                Some("array") => match p["items"]["type"].as_str() {
                    Some("boolean" | "number" | "integer" | "string") => {}
                    Some("object") => foxglove_reads(&p["items"], &at),
                    other => panic!("{at}: items of type {other:?}"),
                },
                other => panic!("{at}: type {other:?}"),
            }
        }
    }

    /// Every field of `message` is one `schema` declares, of its type.
    pub(crate) fn fits(message: &Value, schema: &Value, at: &str) {
        if schema.get("oneOf").is_some() {
            assert!(message.is_u64(), "{at}: {message}");
            return;
        }
        match schema["type"].as_str() {
            Some("object") => {
                let fields = message
                    .as_object()
                    .unwrap_or_else(|| panic!("{at}: {message} is not an object"));
                for (name, value) in fields {
                    let field = &schema["properties"][name];
                    assert!(!field.is_null(), "{at}.{name}: not in the schema");
                    fits(value, field, &format!("{at}.{name}"));
                }
            }
            Some("array") => {
                for (n, item) in message.as_array().into_iter().flatten().enumerate() {
                    fits(item, &schema["items"], &format!("{at}[{n}]"));
                }
                assert!(message.is_array(), "{at}: {message}");
            }
            Some("string") => assert!(message.is_string(), "{at}: {message}"),
            Some("number") => assert!(message.is_number(), "{at}: {message}"),
            Some("integer") => assert!(message.is_u64() || message.is_i64(), "{at}: {message}"),
            Some("boolean") => assert!(message.is_boolean(), "{at}: {message}"),
            other => panic!("{at}: schema type {other:?}"),
        }
    }

    #[test]
    fn every_schema_is_one_foxglove_reads_and_names_its_type() {
        for topic in Topic::ALL {
            let schema: Value = serde_json::from_str(&topic.schema()).unwrap();
            foxglove_reads(&schema, topic.name());
            assert_eq!(schema["title"], topic.schema_name(), "{}", topic.name());
            assert!(topic.name().starts_with('/'));
        }
        for (i, topic) in Topic::ALL.iter().enumerate() {
            assert_eq!(topic.index(), i, "{}", topic.name());
        }
    }

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        assert_eq!(
            Time::from_ms(63_650),
            Time {
                sec: 63,
                nsec: 650_000_000
            }
        );
        let q = Quaternion::yaw(std::f64::consts::PI);
        assert!((q.z - 1.0).abs() < 1e-12 && q.w.abs() < 1e-12);
    }
}

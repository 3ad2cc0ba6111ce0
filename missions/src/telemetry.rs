//! What the simulated robot tells the node's event bus while a run goes on: the live
//! counterpart of the [`picture`](crate::picture) drawn after it.
//!
//! # Why
//! The SVG picture is drawn once the run is over, from the cart's trace and the newest
//! records in the datamanagers. A live monitor, and a replay of an events file
//! (`marie run --events FILE`), have only the node's event stream. So the same things go
//! onto the stream *as they happen*, each as an
//! [`EventKind::Robot`] with a `what` naming it and its `data` as JSON (points are `[x, y]`
//! in metres, world frame; angles in radians, counter-clockwise from +x):
//!
//! | `what` | `data` | when | from |
//! |---|---|---|---|
//! | `world` | `{"walls": [[[x1,y1],[x2,y2]], ...], "dock": [[x,y],...] \| null, "goal": [[x,y],...] \| null, "cart": {"length", "width", "axle_to_centre"}}` | once when a run starts, before any other robot event of it; on a node that runs the cart but no dispatcher, when the node starts and every [`WORLD_REPEAT`] after | the world model: every wall and obstacle edge, the dock's recess and the goal area as their corners, the cart's size (the pose is the rear axle; the footprint's centre is `axle_to_centre` ahead of it) |
//! | `pose` | `{"x", "y", "heading"}` | every [`POSE_PERIOD`] of simulated time while the cart moves, every [`STILL_REPEAT`] while it stands still, from the first run on (on a node that runs the cart but no dispatcher: from the node's start) | the cart's true pose (what the picture's driven path shows) |
//! | `echoes` | `{"points": [[x,y], ...]}` | every [`ECHOES_PERIOD`] of scans | the echo points of the sonar scans since the last `echoes` event, as the robot placed them (feature DM, class `sonar`) |
//! | `planned-path` | `{"points": [[x,y], ...]}` | when the path planner stores a path | its waypoints, leg after leg (parameter DM, class `path`) |
//! | `followed-wall` | `{"from": [x,y], "to": [x,y]}` | when the wall sensor first stores the followed wall, and when either end moves more than [`WALL_MOVED`] | world DM, class `wall` |
//! | `dock-found` | `{"corners": [[x,y], ...]}` | when the docking detector stores a dock | its four corners, opening first (world DM, class `dock`) |
//!
//! # How, and what it costs
//! - The pose comes from the virtual cart itself ([`PoseSampler`], called on its physics
//!   ticks): sampled, not every 20 ms physics step, so a run of a minute adds about 600
//!   events.
//! - The rest is read from the datamanagers, where the operations store it anyway: one
//!   subscription (a long poll of `SelectWait` calls, [`marie_dm::Subscription`])
//!   per class, started when a run starts ([`tap_records`]). The operations know nothing of
//!   it. A tap ends when the node's next run starts, at the node's shutdown, or with its
//!   datamanager (one restarted mid-run is not followed again until the next run).
//! - Publishing never blocks: [`EventBus::publish`] is a send on a bounded broadcast (a
//!   slow subscriber loses the oldest events, the simulation never waits).
//! - Poses start with the first run: before it nobody has told a viewer the world, so the
//!   `world` event is always the first robot event of a node's stream.
//!
//! # In a cluster
//! The cart and the dispatcher may run on different nodes (`missions/clusters/thesis.toml`:
//! the cart on `cart`, which has no dispatcher; the dispatcher on the `run --join` member).
//! Each tells what it has, and a viewer of the whole cluster (`marie monitor --join`,
//! `up --monitor`, the relay into a `run --join --monitor`) gets both:
//! - The node that runs the cart but no dispatcher never hears of a run
//!   ([`SimRobot`](crate::robot::SimRobot)'s `Robot::dispatched_elsewhere`): it publishes
//!   `world` when it starts and its poses from then on. Its first `world` goes out before
//!   the node has joined anyone, and a viewer may join at any time; the relay forwards only
//!   to the watchers present, so the node repeats `world` every [`WORLD_REPEAT`] (wall-clock
//!   time; a late viewer may see a few poses before its first `world`, which a monitor
//!   draws once it comes). A repeated `world` replaces the one drawn, never the driven path.
//! - The record taps stay with the dispatcher's node (`world` and taps at each run start,
//!   as in one process): only that node knows when a run starts — the taps of the previous
//!   run end there, so no record is told twice — and a tap finds its datamanager through
//!   the cluster's registry wherever it runs. A tap on the cart's node as well would tell
//!   every record twice.

use crate::geom::{Point, Pose, Segment};
use crate::ops::records::{self, DockRecord, EchoScan, PathRecord, WallRecord};
use crate::world::World;
use marie_dm::{self as dm, DmClient, DmSpec, Query, Record, Subscription};
use marie_telemetry::{CartPose, CartSize, Corners, FromTo, Points, Telemetry, WorldData};
use marie_vocabulary::events::{EventBus, EventKind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::task::JoinHandle;

pub use marie_telemetry::{DOCK_FOUND, ECHOES, FOLLOWED_WALL, PLANNED_PATH, POSE, WORLD};

/// How often the pose of a cart standing still is told again, simulated time: a viewer that
/// joins late gets it, and the stream does not repeat it ten times a second.
pub const STILL_REPEAT: Duration = Duration::from_secs(2);

/// Wall-clock time between two `world` events of a node that runs the cart but no
/// dispatcher: how long a viewer that joins the cluster late waits for the walls.
pub const WORLD_REPEAT: Duration = Duration::from_secs(2);
/// Simulated time between two `pose` events.
pub const POSE_PERIOD: Duration = Duration::from_millis(100);
/// Scan time gathered into one `echoes` event (ten scans a second make one event).
pub const ECHOES_PERIOD: Duration = Duration::from_millis(500);
/// How far an end of the followed wall must move (m) for a new `followed-wall` event: the
/// wall sensor stores the wall at every step, growing it by centimetres.
pub const WALL_MOVED: f64 = 0.25;

/// The source name the taps read datamanagers as.
const SOURCE: &str = "telemetry";

fn point(p: &Point) -> marie_telemetry::Point {
    [p.x, p.y]
}

fn points<'a>(ps: impl IntoIterator<Item = &'a Point>) -> Vec<marie_telemetry::Point> {
    ps.into_iter().map(point).collect()
}

/// The `world` event of `world`.
pub fn world_event(world: &World) -> EventKind {
    Telemetry::World(WorldData {
        walls: world
            .segments()
            .iter()
            .map(|s| [point(&s.a), point(&s.b)])
            .collect(),
        dock: world.dock.map(|d| points(&d.rect().corners())),
        goal: world.goal.as_ref().map(|g| points(&g.area.corners())),
        cart: Some(CartSize {
            length: world.cart.length,
            width: world.cart.width,
            axle_to_centre: world.cart.center_offset(),
        }),
    })
    .event()
}

/// The `pose` event of `pose`.
pub fn pose_event(pose: &Pose) -> EventKind {
    Telemetry::Pose(CartPose {
        x: pose.x,
        y: pose.y,
        heading: pose.theta,
    })
    .event()
}

/// Publishes the cart's pose every [`POSE_PERIOD`] of simulated time, once a run has
/// started (its `live` flag is raised by the robot after it published the world).
#[derive(Clone, Debug)]
pub struct PoseSampler {
    events: EventBus,
    live: Arc<AtomicBool>,
    /// Simulated time of the next sample, ms.
    next_ms: u64,
    /// The latest pose published, and when (ms): a cart standing still is told again only
    /// every [`STILL_REPEAT`].
    last: Option<(Pose, u64)>,
}

impl PoseSampler {
    /// A sampler publishing on `events` while `live` is raised.
    pub fn new(events: EventBus, live: Arc<AtomicBool>) -> PoseSampler {
        PoseSampler {
            events,
            live,
            next_ms: 0,
            last: None,
        }
    }

    /// The cart is at `pose` at simulated time `time` (s): publish it if a sample is due.
    pub fn sample(&mut self, time: f64, pose: &Pose) {
        if !self.live.load(Ordering::Relaxed) || !time.is_finite() || time < 0.0 {
            return;
        }
        let ms = (time * 1000.0).round() as u64;
        if ms < self.next_ms {
            return;
        }
        let period = POSE_PERIOD.as_millis() as u64;
        // on the grid of the period, skipping what a long step jumped over
        self.next_ms = (ms / period + 1) * period;
        let still = STILL_REPEAT.as_millis() as u64;
        if self
            .last
            .is_some_and(|(last, at)| last == *pose && ms < at + still)
        {
            return; // standing still (a parked cart, a cluster between runs)
        }
        self.last = Some((*pose, ms));
        self.events.publish(pose_event(pose));
    }
}

/// Publish `world`'s event on `events` now (before this returns) and then every
/// [`WORLD_REPEAT`] of wall-clock time, until the returned task is aborted: a node that runs
/// the cart but no dispatcher cannot tell when a viewer joins (see the module docs).
pub fn repeat_world(events: EventBus, world: &World) -> JoinHandle<()> {
    let event = world_event(world);
    events.publish(event.clone());
    tokio::spawn(async move {
        let start = tokio::time::Instant::now() + WORLD_REPEAT;
        let mut every = tokio::time::interval_at(start, WORLD_REPEAT);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            events.publish(event.clone());
        }
    })
}

/// Start reading what the operations store for the picture — echoes, planned paths, the
/// followed wall, the dock — and publishing it on `events` as it comes: one task per class,
/// ending with its datamanager or when aborted (by the node, at its next run). A datamanager that is not running is left out with a
/// warning. Only records stored after this returns are read.
pub async fn tap_records(events: EventBus) -> Vec<JoinHandle<()>> {
    let mut echoes = Echoes::default();
    let mut wall: Option<Segment> = None;
    // subscribed side by side: in a cluster each is a round trip to another node, and
    // the run waits for them
    let (sonar, walls, docks, paths) = tokio::join!(
        subscribe(dm::FEATURE, records::SONAR.class()),
        subscribe(dm::WORLD, records::WALL.class()),
        subscribe(dm::WORLD, records::DOCK.class()),
        subscribe(dm::PARAMETER, records::PATH.class()),
    );
    let mut taps = Vec::new();
    if let Some(sub) = sonar {
        taps.push(tap(sub, events.clone(), move |r| echoes.scan(r)));
    }
    if let Some(sub) = walls {
        taps.push(tap(sub, events.clone(), move |r| {
            followed_wall(&mut wall, r)
        }));
    }
    if let Some(sub) = docks {
        taps.push(tap(sub, events.clone(), dock_found));
    }
    if let Some(sub) = paths {
        taps.push(tap(sub, events, planned_path));
    }
    taps
}

async fn subscribe(spec: DmSpec, class: &str) -> Option<Subscription> {
    let subscribed = match DmClient::lookup(spec.name, SOURCE) {
        Ok(client) => client.subscribe(Query::class(class)).await,
        Err(e) => Err(e),
    };
    subscribed
        .map_err(|e| tracing::warn!("no live `{class}` events from the {} DM: {e}", spec.name))
        .ok()
}

/// Publish what `event_of` makes of each record `sub` delivers.
fn tap(
    mut sub: Subscription,
    events: EventBus,
    mut event_of: impl FnMut(&Record) -> Option<EventKind> + Send + 'static,
) -> JoinHandle<()> {
    tokio::spawn(async move {
        while let Some(record) = sub.next().await {
            if let Some(kind) = event_of(&record) {
                events.publish(kind);
            }
        }
    })
}

fn decode<T: marie_dm::PayloadType>(record: &Record) -> Option<T> {
    record
        .decode::<T>()
        .map_err(|e| tracing::debug!(class = %record.class, "no event of a record: {e}"))
        .ok()
}

/// Echo points gathered over [`ECHOES_PERIOD`] of scans.
#[derive(Default)]
struct Echoes {
    /// Scan time at which the gathered points are told, s.
    due: Option<f64>,
    points: Vec<Point>,
}

impl Echoes {
    /// Gather `record`'s echoes; the points gathered before it once a period is over.
    fn scan(&mut self, record: &Record) -> Option<EventKind> {
        let scan: EchoScan = decode(record)?;
        let period = ECHOES_PERIOD.as_secs_f64();
        let due = *self.due.get_or_insert(scan.time + period);
        // a scan a little early by rounding still closes the period
        let event = (scan.time >= due - 1e-6).then(|| {
            self.due = Some(due.max(scan.time) + period);
            let gathered = std::mem::take(&mut self.points);
            Telemetry::Echoes(Points {
                points: points(&gathered),
            })
            .event()
        });
        self.points.extend(scan.points());
        event
    }
}

fn followed_wall(last: &mut Option<Segment>, record: &Record) -> Option<EventKind> {
    let wall: WallRecord = decode(record)?;
    let s = wall.segment;
    let moved = |l: &Segment| (l.a - s.a).norm() > WALL_MOVED || (l.b - s.b).norm() > WALL_MOVED;
    if last.as_ref().is_some_and(|l| !moved(l)) {
        return None;
    }
    *last = Some(s);
    Some(
        Telemetry::FollowedWall(FromTo {
            from: point(&s.a),
            to: point(&s.b),
        })
        .event(),
    )
}

fn dock_found(record: &Record) -> Option<EventKind> {
    let dock: DockRecord = decode(record)?;
    Some(
        Telemetry::DockFound(Corners {
            corners: points(&dock.corners),
        })
        .event(),
    )
}

fn planned_path(record: &Record) -> Option<EventKind> {
    let path: PathRecord = decode(record)?;
    Some(
        Telemetry::PlannedPath(Points {
            points: points(&path.waypoints()),
        })
        .event(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::clock::ManualClock;
    use serde_json::{json, Value};

    fn robot(what: &str, data: Value) -> EventKind {
        EventKind::Robot {
            what: what.to_string(),
            data,
        }
    }

    #[test]
    fn the_world_event_has_the_walls_dock_goal_and_cart() {
        let world = World::builtin("lab").expect("a shipped world");
        let EventKind::Robot { what, data } = world_event(&world) else {
            panic!("a robot event")
        };
        assert_eq!(what, WORLD);
        assert_eq!(
            data["walls"].as_array().map(Vec::len),
            Some(world.segments().len())
        );
        assert_eq!(data["walls"][0], json!([[0.0, 0.0], [4.0, 0.0]]));
        assert_eq!(data["dock"].as_array().map(Vec::len), Some(4));
        assert_eq!(data["goal"].as_array().map(Vec::len), Some(4));
        assert_eq!(data["cart"]["length"], json!(1.0));
        assert_eq!(data["cart"]["width"], json!(0.6));
        let nodock = World::builtin("nodock").expect("a shipped world");
        let EventKind::Robot { data, .. } = world_event(&nodock) else {
            panic!("a robot event")
        };
        assert_eq!((&data["dock"], &data["goal"]), (&Value::Null, &Value::Null));
    }

    #[tokio::test]
    async fn poses_are_sampled_every_period_once_live() {
        let clock = Arc::new(ManualClock::new());
        let bus = EventBus::new("n", clock.clone());
        let mut sub = bus.subscribe();
        let live = Arc::new(AtomicBool::new(false));
        let mut sampler = PoseSampler::new(bus, live.clone());
        let pose = Pose::new(1.0, 2.0, 0.5);
        sampler.sample(0.0, &pose);
        assert!(sub.drain().is_empty(), "not before a run");
        live.store(true, Ordering::Relaxed);
        // 50 physics steps of 20 ms, the cart moving: one second, ten samples
        for step in 0..50 {
            let moved = Pose::new(pose.x - f64::from(step) * 0.01, pose.y, pose.theta);
            sampler.sample(f64::from(step) * 0.02, &moved);
        }
        let got = sub.drain();
        assert_eq!(got.len(), 10);
        assert_eq!(
            got[0].kind,
            robot(POSE, json!({"x": 1.0, "y": 2.0, "heading": 0.5}))
        );
        // a long step samples once, on the grid
        sampler.sample(5.03, &Pose::new(3.0, 2.0, 0.5));
        sampler.sample(5.08, &Pose::new(3.1, 2.0, 0.5));
        sampler.sample(5.1, &Pose::new(3.2, 2.0, 0.5));
        assert_eq!(sub.drain().len(), 2);
        // standing still: told again only every STILL_REPEAT
        for step in 0..250 {
            sampler.sample(6.0 + f64::from(step) * 0.02, &Pose::new(3.2, 2.0, 0.5));
        }
        assert_eq!(
            sub.drain().len(),
            2,
            "at 7.1 s and 9.1 s: every 2 s since 5.1 s"
        );
    }

    fn record_of<T: serde::Serialize>(class: &str, value: &T) -> Record {
        Record {
            seq: 1,
            timestamp: Duration::ZERO,
            source: "test".into(),
            class: class.into(),
            sub1: None,
            sub2: None,
            payload: marie_dm::Payload::encode(value).expect("encodes"),
        }
    }

    #[test]
    fn the_followed_wall_is_told_when_an_end_moves() {
        let wall = |to_x: f64| WallRecord {
            segment: Segment::new(Point::new(12.5, 0.0), Point::new(to_x, 0.0)),
            distance: 1.5,
            relative_angle: 0.0,
            side: 1.0,
            pose: Pose::new(12.5, 1.5, std::f64::consts::PI),
            correction: Pose::default(),
            #[cfg(feature = "next-protocol")]
            seen_among: None,
        };
        let mut last = None;
        let told: Vec<bool> = [11.5, 11.4, 11.3, 11.2, 10.0]
            .iter()
            .map(|x| {
                followed_wall(&mut last, &record_of(records::WALL.class(), &wall(*x))).is_some()
            })
            .collect();
        assert_eq!(told, [true, false, false, true, true]);
        let event = followed_wall(&mut None, &record_of(records::WALL.class(), &wall(11.0)));
        assert_eq!(
            event,
            Some(robot(
                FOLLOWED_WALL,
                json!({"from": [12.5, 0.0], "to": [11.0, 0.0]})
            ))
        );
        // a record that does not decode is passed over
        assert_eq!(
            followed_wall(&mut None, &record_of(records::WALL.class(), &1u8)),
            None
        );
    }

    #[test]
    fn echoes_are_gathered_over_the_period() {
        use crate::ops::records::Echo;
        let mut echoes = Echoes::default();
        let record = |time: f64| {
            let scan = EchoScan {
                time,
                pose: Pose::new(0.0, 0.0, 0.0),
                echoes: vec![Echo {
                    sensor: 0,
                    narrow: true,
                    bearing: 0.0,
                    range: 1.0,
                    point: Point::new(time, 1.0),
                }],
                correction: Pose::default(),
            };
            record_of(records::SONAR.class(), &scan)
        };
        let mut out = Vec::new();
        // two seconds of scans, ten a second
        for i in 0..=20 {
            out.extend(echoes.scan(&record(f64::from(i) * 0.1)));
        }
        assert_eq!(out.len(), 4, "two a second");
        let EventKind::Robot { what, data } = &out[0] else {
            panic!("a robot event")
        };
        assert_eq!(what, ECHOES);
        assert_eq!(data["points"].as_array().map(Vec::len), Some(5));
    }
}

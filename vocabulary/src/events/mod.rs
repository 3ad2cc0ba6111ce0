//! One event stream: every dispatcher, binding, registry, supervisor, fault and robot event
//! as a typed, serializable value on the node's [`EventBus`] — the only channel of a run's facts.
//!
//! The bus is the only channel of a run's facts. The live lines, the fault injector,
//! `--events` files, a remote watcher and the monitor subscribe to it; the run report is a
//! [`ReportBuilder`](crate::report::ReportBuilder) folded over it — attached to the bus as a
//! [`Tap`], which sees every event in publish order and never lags — so the report a node
//! writes and [`RunReport::from_events`](crate::report::RunReport::from_events) of the run's
//! events are equal by construction; while the report keeps only the latest rebinds and
//! faults, the stream has them all.
//!
//! The vocabulary of the kinds (outcomes, loss causes, rebinds, choices, fault kinds) lives
//! below this module, in [`crate::run`]: the events know no dispatcher, and no robot — a
//! robot speaks through [`EventKind::Robot`] and the untyped section of
//! [`EventKind::Judged`].
//!
//! # JSON schema (`.jsonl`: one event per line)
//!
//! Every line is an object `{"at_ms": u64, "node": string, "kind": {...}}`: `at_ms` is the
//! node's mission clock in ms when the event was published, `node` the node's name, and
//! `kind` the [`EventKind`], an object whose `type` names it (snake_case, stable) and whose
//! other fields are the kind's. Times inside a kind (`run_ms`, `due_ms`) are ms since its
//! run began. Loss causes are objects tagged by `type` too ([`LossCause`](crate::run::LossCause));
//! `ended` is `running|finished|suspended|failed|lost|unresponsive`, `outcome`
//! `succeeded|failed`, `fault` one of [`FaultKind::ALL`](crate::run::FaultKind::ALL)'s names
//! (`kill|panic|hang|slow|stop-node|freeze-node|partition`); a `judged` line's fields beyond `outcome` and `reason` are
//! the robot's own; a fault that lasts (`freeze-node`, `partition`) has `lasting_ms` in its
//! `fault_injected`, and a `fault_healed` when it is undone. One example line per kind:
//!
//! ```json
//! {"at_ms":1199,"node":"marie@localhost","kind":{"type":"provenance","marie":{"version":"0.1.0","commit":"1f2e3d4c5b6a79881f2e3d4c5b6a79881f2e3d4c","uncommitted_changes":false},"command":["marie","run","m.toml","--seed","7"],"started_unix_ms":1795801800123,"started":"2026-11-27T17:50:00.123Z","files":[{"role":"mission","path":"m.toml","sha256":"ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad","text":"[mission]\nname = \"docking\"\n"}],"nodes":[{"node":"marie@localhost","marie":{"version":"0.1.0","commit":"1f2e3d4c5b6a79881f2e3d4c5b6a79881f2e3d4c","uncommitted_changes":false}}],"seed":7,"speed":"max","parameters":[]}}
//! {"at_ms":1200,"node":"marie@localhost","kind":{"type":"run_started","mission":"docking","actions":[{"name":"follow","when":["wall_found"],"ops":["wall-follower","docking-detector"],"ends_on":["docking-detector"]}],"success":["parked"]}}
//! {"at_ms":1240,"node":"marie@localhost","kind":{"type":"selected","choice":{"operation":"wall-follower","candidates":[{"address":"0.41","node":"marie@localhost","version":"1.0.0","schema":["distance"],"flags":["aligned"],"verdict":{"type":"chosen"}},{"address":"0.42","node":"marie@localhost","version":"2.0.0","schema":["distance","mode"],"flags":["aligned"],"verdict":{"type":"lost","reason":"its schema also declares mode the mission does not supply; 0.41 (version 1.0.0) fits exactly"}}]}}}
//! {"at_ms":1250,"node":"marie@localhost","kind":{"type":"bound","operations":[{"name":"wall-follower","version":"1.0.0","node":"marie@localhost","epoch":1250000,"address":"0.41"}]}}
//! {"at_ms":1260,"node":"marie@localhost","kind":{"type":"action_started","action":"follow","run_ms":60,"operations":[{"key":"wall-follower","name":"wall-follower","id":1512,"version":"1.0.0","node":"marie@localhost","address":"0.41","params":[{"name":"distance","value":{"Float":0.5},"source":"mission"},{"name":"gain","value":{"Float":1.0},"source":"default"}]}]}}
//! {"at_ms":9800,"node":"marie@localhost","kind":{"type":"op_ended","action":"follow","key":"wall-follower","ended":"suspended","flags":[]}}
//! {"at_ms":9810,"node":"marie@localhost","kind":{"type":"action_ended","action":"follow","run_ms":8610,"flags":["dock_found"],"status":4,"result":"succeeded"}}
//! {"at_ms":1201,"node":"marie@localhost","kind":{"type":"control_plan","items":[{"id":0,"parent":null,"kind":"schedule","label":"mission"},{"id":1,"parent":0,"kind":"retry","label":"retry(follow)","detail":"2 attempts, 1.0 s apart"},{"id":2,"parent":1,"kind":"action","label":"follow","detail":"wall-follower, docking-detector"}]}}
//! {"at_ms":9811,"node":"marie@localhost","kind":{"type":"control","item":"retry(follow)","decision":"retry 2 of 2","run_ms":8611}}
//! {"at_ms":9000,"node":"marie@localhost","kind":{"type":"reparameterized","operation":"wall-follower","address":"0.41","values":[{"name":"distance","value":{"Float":0.7},"source":"reparameterized"}]}}
//! {"at_ms":30000,"node":"marie@localhost","kind":{"type":"run_ended","outcome":"succeeded","reason":"","run_ms":28800,"status":12,"flags":["dock_found","parked"]}}
//! {"at_ms":5000,"node":"marie@localhost","kind":{"type":"lost","operation":"wall-follower","cause":{"type":"died_in_action","action":"follow"}}}
//! {"at_ms":5001,"node":"marie@localhost","kind":{"type":"rebound","operation":"wall-follower","cause":{"type":"died_in_action","action":"follow"},"from":"0.41","to":"0.57","from_node":"n1","to_node":"n2","downtime_ms":1,"epoch":1250001}}
//! {"at_ms":8000,"node":"marie@localhost","kind":{"type":"rebind_gave_up","operation":"planner","cause":{"type":"hung","deadline_ms":300},"waited_ms":3000}}
//! {"at_ms":21400,"node":"spare","kind":{"type":"takeover","run":"up-4242-1764216000000","from":"features","to":"spare","term":2,"gap_ms":84,"since_checkpoint_ms":2130,"unix_ms":1764216021400}}
//! {"at_ms":23000,"node":"features","kind":{"type":"dispatcher_fenced","run":"up-4242-1764216000000","term":1,"newer":2}}
//! {"at_ms":100,"node":"marie@localhost","kind":{"type":"joined","module":"Operation","name":"wall-follower","id":1512,"node":"marie@localhost","address":"0.41"}}
//! {"at_ms":5000,"node":"marie@localhost","kind":{"type":"left","module":"Operation","name":"wall-follower","id":1512,"node":"marie@localhost","address":"0.41"}}
//! {"at_ms":90,"node":"marie@localhost","kind":{"type":"child_started","supervisor":"operations","child":"wall-follower","actor":"0.41"}}
//! {"at_ms":5000,"node":"marie@localhost","kind":{"type":"child_exited","supervisor":"operations","child":"wall-follower","reason":"killed"}}
//! {"at_ms":5001,"node":"marie@localhost","kind":{"type":"child_restarted","supervisor":"operations","child":"wall-follower","actor":"0.57","restarts":1,"reason":"killed"}}
//! {"at_ms":9000,"node":"marie@localhost","kind":{"type":"supervisor_gave_up","supervisor":"operations","reason":"reached_max_restart_intensity"}}
//! {"at_ms":5000,"node":"marie@localhost","kind":{"type":"fault_injected","fault":"kill","operation":"wall-follower","actor":"0.41","node":"marie@localhost","due_ms":3800}}
//! {"at_ms":12000,"node":"marie@localhost","kind":{"type":"fault_healed","fault":"freeze-node","operation":"features"}}
//! {"at_ms":6000,"node":"marie@localhost","kind":{"type":"fault_not_injected","fault":"hang","operation":"nobody","why":"no operation `nobody` is running","due_ms":4800}}
//! {"at_ms":700,"node":"marie@localhost","kind":{"type":"node_up","peer":"cart","address":"127.0.0.1:7101"}}
//! {"at_ms":9100,"node":"marie@localhost","kind":{"type":"node_back","peer":"cart","address":"127.0.0.1:7101","down_ms":420}}
//! {"at_ms":9500,"node":"marie@localhost","kind":{"type":"node_down","peer":"cart","silent_ms":1530}}
//! {"at_ms":9501,"node":"marie@localhost","kind":{"type":"node_lost","peer":"cart","address":"127.0.0.1:7101"}}
//! {"at_ms":9900,"node":"marie@localhost","kind":{"type":"node_frozen","silent_ms":4200}}
//! {"at_ms":800,"node":"marie@localhost","kind":{"type":"node_refused","peer":"far","theirs":4,"ours":3,"theirs_speak":{"oldest":4,"newest":4},"ours_speak":{"oldest":2,"newest":3}}}
//! {"at_ms":850,"node":"marie@localhost","kind":{"type":"connection_refused","from":"127.0.0.1:45042","reason":"TLS: invalid peer certificate: UnknownIssuer"}}
//! {"at_ms":20003,"node":"features","kind":{"type":"dm_recovered","dm":"feature","records":1210,"bytes":139150,"ms":4,"dropped_bytes":0,"dropped_records":0,"torn":null}}
//! {"at_ms":20090,"node":"operations","kind":{"type":"dm_promoted","dm":"feature","node":"operations","term":3}}
//! {"at_ms":21000,"node":"features","kind":{"type":"dm_fenced","dm":"feature","node":"features","term":2,"why":"a newer term"}}
//! {"at_ms":26400,"node":"features","kind":{"type":"dm_retention","dm":"feature","node":"features","class":"sonar","bound":10000}}
//! {"at_ms":22000,"node":"features","kind":{"type":"dm_state","dm":"feature","durability":"process","records":1210,"journal_bytes":139150,"role":"leader","term":3,"lag":{"operations":0,"spare":2}}}
//! {"at_ms":4100,"node":"operations","kind":{"type":"dm_acked","dm":"world","source":"wall-sensor","class":"wall","seq":212,"digest":1311768467463790320}}
//! {"at_ms":4200,"node":"operations","kind":{"type":"dm_deleted","dm":"parameter","source":"path-planner","class":"path","deleted":3}}
//! {"at_ms":4300,"node":"operations","kind":{"type":"dm_applied","dm":"feature","spans":[{"class":"sonar","from":1201,"to":1263,"records":32,"digest":9034127731160021514}]}}
//! {"at_ms":20004,"node":"embedded","kind":{"type":"dm_inherited","dm":"feature","records":1210,"refused":0}}
//! {"at_ms":40100,"node":"features","kind":{"type":"dm_replica_added","dm":"feature","node":"spare","voters":["features","operations","robot"]}}
//! {"at_ms":41300,"node":"features","kind":{"type":"dm_replica_promoted","dm":"feature","node":"spare","voters":["features","operations","robot","spare"]}}
//! {"at_ms":41500,"node":"features","kind":{"type":"dm_replica_removed","dm":"feature","node":"robot","voters":["features","operations","spare"]}}
//! {"at_ms":58200,"node":"robot","kind":{"type":"dm_replica_out","dm":"feature","node":"robot","voters":["features","operations","spare"]}}
//! {"at_ms":41600,"node":"features","kind":{"type":"dm_replica_replaced","dm":"feature","gone":"robot","by":"spare","after_secs":30.2,"voters":["features","operations","spare"]}}
//! {"at_ms":64100,"node":"marie@localhost","kind":{"type":"dm_checked","dm":"world","node":"features","acknowledged":412,"held":410,"dropped_by_retention":0,"deleted":0,"unchecked":0,"lost":2}}
//! {"at_ms":30001,"node":"marie@localhost","kind":{"type":"judged","outcome":"succeeded","reason":"","collisions":0,"final_pose":[1.5,0.25,0.01],"inside_goal":true,"judgement":"success: inside the goal area","refused_commands":{},"seed":7}}
//! {"at_ms":4000,"node":"marie@localhost","kind":{"type":"robot","what":"collision","data":{"x":1.0,"y":2.0}}}
//! ```
//!
//! (A test reads these lines back and writes them again, so they stay exact.)
//!
//! ## The robot's live events
//!
//! A robot reports what it sees as `robot` events, `what` naming it. The simulated robot
//! (`marie_missions::telemetry` has the table of when and from where) puts onto the stream
//! what its after-run picture shows, so a live monitor, or a replay of an events file, can
//! draw the run from the stream alone. Points are `[x, y]` in metres in the world frame,
//! angles radians counter-clockwise from +x; `world` comes once when a run starts, before
//! any other robot event of it; `pose` (the cart's rear axle) every 100 ms of mission time;
//! `echoes` the sonar echo points gathered over half a second of scans; `followed-wall`,
//! `dock-found` and `planned-path` when the operations find them:
//!
//! ```json
//! {"at_ms":0,"node":"embedded","kind":{"type":"robot","what":"world","data":{"cart":{"axle_to_centre":0.35,"length":1.0,"width":0.6},"dock":[[4.0,-0.8],[6.8,-0.8],[6.8,0.0],[4.0,0.0]],"goal":[[6.8,0.0],[4.0,0.0],[4.0,-0.8],[6.8,-0.8]],"walls":[[[0.0,0.0],[4.0,0.0]],[[4.0,0.0],[4.0,-0.8]]]}}}
//! {"at_ms":20,"node":"embedded","kind":{"type":"robot","what":"pose","data":{"heading":3.14,"x":12.5,"y":1.5}}}
//! {"at_ms":2000,"node":"embedded","kind":{"type":"robot","what":"echoes","data":{"points":[[12.1,0.02],[11.9,-0.01]]}}}
//! {"at_ms":2250,"node":"embedded","kind":{"type":"robot","what":"followed-wall","data":{"from":[12.5,0.0],"to":[11.52,0.0]}}}
//! {"at_ms":38750,"node":"embedded","kind":{"type":"robot","what":"dock-found","data":{"corners":[[6.75,0.0],[4.09,0.02],[4.08,-0.8],[6.75,-0.82]]}}}
//! {"at_ms":38750,"node":"embedded","kind":{"type":"robot","what":"planned-path","data":{"points":[[4.66,0.82],[4.61,0.82],[5.4,-0.4]]}}}
//! ```
//!
//! # Invariants
//! - Publishing never blocks: the bus is bounded, a slow subscriber loses the oldest events
//!   and is told how many ([`BusError::Lagged`]).
//! - Every event of a node carries the node's clock and name, stamped by the bus; events
//!   are stamped, tapped and broadcast in one order, so their times never go back.
//! - A [`Tap`] sees every event published while it is attached, in that order: what must
//!   not lose an event (a run's report, the fault injector's view of the bindings) taps;
//!   what may fall behind (printers, files, the monitor) subscribes.
//! - The supervision crate knows nothing of this module: a node translates its supervisors'
//!   events into the plain-data supervisor kinds.

mod bus;
mod kind;
mod registry_bridge;
mod spoken;
mod voice;
mod words;

pub use bus::{BusError, EventBus, EventSubscription, Tap, DEFAULT_CAPACITY};
pub use kind::{
    ActionPlan, ActionResult, BoundOp, EventKind, Family, ModuleInfo, OpStarted, PlanItem,
};
pub use registry_bridge::{bridge_registry, RegistryBridge};
pub use voice::DispatcherVoice;
pub use words::{gravity, mark, no_majority, Gravity, Mark, RobotWords, Teller, Words, TEXT_LIMIT};

use serde::{Deserialize, Serialize};

/// One event: what happened ([`EventKind`]), on which node, at which mission clock time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// The node's mission clock when it was published, in ms.
    pub at_ms: u64,
    /// The node that published it.
    pub node: String,
    /// What happened.
    pub kind: EventKind,
}

impl Event {
    /// The event as one line of a `.jsonl` file (no newline).
    pub fn to_json_line(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string(self)
    }

    /// Read one line of a `.jsonl` file.
    pub fn from_json_line(line: &str) -> Result<Event, serde_json::Error> {
        serde_json::from_str(line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// The example lines of the `n`-th JSON block of the module docs.
    fn doc_examples(n: usize) -> Vec<String> {
        let src = include_str!("mod.rs");
        let mut lines = src.lines();
        for _ in 0..n {
            lines.by_ref().find(|l| *l == "//! ```json");
            lines.by_ref().find(|l| *l == "//! ```");
        }
        lines
            .skip_while(|l| *l != "//! ```json")
            .skip(1)
            .take_while(|l| *l != "//! ```")
            .map(|l| l.trim_start_matches("//! ").to_string())
            .collect()
    }

    /// `line` reads and writes back exactly, also over the wire; its `kind.type`.
    fn reads_back(line: &str) -> serde_json::Value {
        let event = Event::from_json_line(line).unwrap_or_else(|e| panic!("{line}: {e}"));
        assert_eq!(&event.to_json_line().unwrap(), line);
        let bytes = crate::wire::encode(&event).unwrap();
        assert_eq!(
            crate::wire::decode::<Event>(&bytes).unwrap(),
            event,
            "{line}"
        );
        serde_json::from_str(line).unwrap()
    }

    /// Every kind's `type`. The match has no catch-all arm: a new kind does not compile
    /// here until it is named, and [`KINDS`] then wants its documented line.
    fn type_of(kind: &EventKind) -> &'static str {
        match kind {
            EventKind::Provenance(_) => "provenance",
            EventKind::Reparameterized { .. } => "reparameterized",
            EventKind::RunStarted { .. } => "run_started",
            EventKind::Bound { .. } => "bound",
            EventKind::ActionStarted { .. } => "action_started",
            EventKind::OpEnded { .. } => "op_ended",
            EventKind::ActionEnded { .. } => "action_ended",
            EventKind::Control { .. } => "control",
            EventKind::ControlPlan { .. } => "control_plan",
            EventKind::RunEnded { .. } => "run_ended",
            EventKind::Lost { .. } => "lost",
            EventKind::Rebound(_) => "rebound",
            EventKind::BindingUpgraded(_) => "binding_upgraded",
            EventKind::BindingRolledBack(_) => "binding_rolled_back",
            EventKind::BindingUpgradeRefused { .. } => "binding_upgrade_refused",
            EventKind::RebindGaveUp { .. } => "rebind_gave_up",
            EventKind::Takeover { .. } => "takeover",
            EventKind::DispatcherFenced { .. } => "dispatcher_fenced",
            EventKind::Joined(_) => "joined",
            EventKind::Left(_) => "left",
            EventKind::ChildStarted { .. } => "child_started",
            EventKind::ChildExited { .. } => "child_exited",
            EventKind::ChildRestarted { .. } => "child_restarted",
            EventKind::SupervisorGaveUp { .. } => "supervisor_gave_up",
            EventKind::FaultInjected { .. } => "fault_injected",
            EventKind::FaultNotInjected { .. } => "fault_not_injected",
            EventKind::FaultHealed { .. } => "fault_healed",
            EventKind::NodeUp { .. } => "node_up",
            EventKind::NodeBack { .. } => "node_back",
            EventKind::NodeLost { .. } => "node_lost",
            EventKind::NodeDown { .. } => "node_down",
            EventKind::NodeFrozen { .. } => "node_frozen",
            EventKind::NodeRefused { .. } => "node_refused",
            EventKind::ConnectionRefused { .. } => "connection_refused",
            EventKind::Selected { .. } => "selected",
            EventKind::DmRecovered { .. } => "dm_recovered",
            EventKind::DmPromoted { .. } => "dm_promoted",
            EventKind::DmFenced { .. } => "dm_fenced",
            EventKind::DmRetention { .. } => "dm_retention",
            EventKind::DmState { .. } => "dm_state",
            EventKind::DmNoMajority { .. } => "dm_no_majority",
            EventKind::DmAcked { .. } => "dm_acked",
            EventKind::DmDeleted { .. } => "dm_deleted",
            EventKind::DmApplied { .. } => "dm_applied",
            EventKind::DmInherited { .. } => "dm_inherited",
            EventKind::DmReplicaAdded { .. } => "dm_replica_added",
            EventKind::DmReplicaPromoted { .. } => "dm_replica_promoted",
            EventKind::DmReplicaRemoved { .. } => "dm_replica_removed",
            EventKind::DmReplicaOut { .. } => "dm_replica_out",
            EventKind::DmReplicaReplaced { .. } => "dm_replica_replaced",
            EventKind::DmReplicaCaughtUp { .. } => "dm_replica_caught_up",
            EventKind::DmRedundancyRestored { .. } => "dm_redundancy_restored",
            EventKind::DmChecked(_) => "dm_checked",
            EventKind::Judged { .. } => "judged",
            EventKind::Robot { .. } => "robot",
        }
    }

    /// The `type` of every kind, as [`type_of`] names them.
    const KINDS: [&str; 49] = [
        "provenance",
        "reparameterized",
        "run_started",
        "bound",
        "action_started",
        "op_ended",
        "action_ended",
        "control_plan",
        "control",
        "run_ended",
        "lost",
        "rebound",
        "rebind_gave_up",
        "takeover",
        "dispatcher_fenced",
        "joined",
        "left",
        "child_started",
        "child_exited",
        "child_restarted",
        "supervisor_gave_up",
        "fault_injected",
        "fault_not_injected",
        "fault_healed",
        "node_up",
        "node_back",
        "node_lost",
        "node_down",
        "node_frozen",
        "node_refused",
        "connection_refused",
        "selected",
        "dm_recovered",
        "dm_promoted",
        "dm_fenced",
        "dm_retention",
        "dm_state",
        "dm_acked",
        "dm_deleted",
        "dm_applied",
        "dm_inherited",
        "dm_replica_added",
        "dm_replica_promoted",
        "dm_replica_removed",
        "dm_replica_out",
        "dm_replica_replaced",
        "dm_checked",
        "judged",
        "robot",
    ];

    #[test]
    fn every_kind_has_a_documented_line_that_reads_and_writes_back_exactly() {
        let lines = doc_examples(0);
        let mut types = BTreeSet::new();
        for line in &lines {
            let value = reads_back(line);
            let event = Event::from_json_line(line).unwrap();
            assert_eq!(value["kind"]["type"], type_of(&event.kind), "{line}");
            types.insert(type_of(&event.kind));
        }
        assert_eq!(types.len(), lines.len(), "one line per kind");
        assert_eq!(types, BTreeSet::from(KINDS), "every kind is documented");
    }

    #[test]
    fn a_stream_written_before_the_tree_said_item_still_reads() {
        // `control` and `control_plan` named the tree's items `node` and `nodes` before
        let old = [
            r#"{"at_ms":1201,"node":"n","kind":{"type":"control_plan","nodes":[{"id":0,"parent":null,"kind":"schedule","label":"mission"}]}}"#,
            r#"{"at_ms":9811,"node":"n","kind":{"type":"control","node":"retry(follow)","decision":"retry 2 of 2","run_ms":8611}}"#,
        ];
        let plan = Event::from_json_line(old[0]).unwrap();
        assert!(
            matches!(&plan.kind, EventKind::ControlPlan { items } if items[0].label == "mission")
        );
        let control = Event::from_json_line(old[1]).unwrap();
        assert!(
            matches!(&control.kind, EventKind::Control { item, .. } if item == "retry(follow)")
        );
        // and is written with today's names
        assert!(control
            .to_json_line()
            .unwrap()
            .contains(r#""item":"retry(follow)""#));
    }

    #[test]
    fn every_documented_kind_is_told_in_words_of_its_own() {
        let mut teller = Teller::default();
        for line in doc_examples(0) {
            let event = Event::from_json_line(&line).unwrap();
            let words = teller.tell(&event);
            let generic = format!("{} {{", type_of(&event.kind));
            assert!(!words.text.is_empty(), "{line}");
            assert!(
                !words.text.starts_with(&generic) || type_of(&event.kind) == "robot",
                "{line} is told only as its fields: {}",
                words.text
            );
            // every mark is one the legend (`Mark`'s docs) explains
            assert!(
                ">?<!~*# =+-^@%.".contains(words.mark),
                "{line}: {:?}",
                words.mark
            );
        }
    }

    #[test]
    fn the_robots_live_events_are_documented_lines_that_read_and_write_back_exactly() {
        let lines = doc_examples(1);
        let whats: Vec<String> = lines
            .iter()
            .map(|line| {
                let value = reads_back(line);
                assert_eq!(value["kind"]["type"], "robot", "{line}");
                value["kind"]["what"].as_str().unwrap().to_string()
            })
            .collect();
        assert_eq!(
            whats,
            [
                "world",
                "pose",
                "echoes",
                "followed-wall",
                "dock-found",
                "planned-path"
            ]
        );
    }
}

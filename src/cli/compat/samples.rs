//! One sample of every message variant that crosses nodes, and of the frames and records
//! this build writes, each encoded as the node encodes it.
//!
//! Each message enum's samples are listed with [`samples!`], which also writes an exhaustive
//! `match` over the enum from the same list (its remote variants, then its `local` ones): a
//! variant added to the enum without a sample here is a compile error in this file, so a
//! new message cannot ship without its place in the corpus.

use marie::cluster::net::heartbeat::BeatMsg;
use marie::cluster::node::desk::DeskMsg;
use marie::cluster::relay::WatcherMsg;
use marie::cluster::replicas::{Declaration, HostMsg};
use marie::dispatcher::DispatcherMsg;
use marie::dm::{Change, DmMsg, Durability, NewRecord, Payload, Query, Take};
use marie::eo::EoMsg;
use marie::events::{Event, EventKind};
use marie::fence::{Fence, FenceMsg};
use marie::property::{Collection, Group, PropertyRequest, Value};
use marie::provision::ProvisionMsg;
use marie::run::{FaultKind, LossCause, Outcome};
use marie::wire::Envelope;
use marie_missions::hardware::CartMsg;
use ractor::message::SerializedMessage;
use ractor::{Message, RpcReplyPort};
use std::collections::BTreeMap;
use std::time::Duration;

/// How a sample travels, and so how it is decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum Form {
    /// A message variant sent without an answer: `SerializedMessage::Cast`, its fields a map.
    Cast,
    /// A message variant that asks for an answer: `SerializedMessage::Call`.
    Call,
    /// A frame in the versioned [`Envelope`] (events relayed to watchers).
    Envelope,
    /// A serde value encoded with `wire::encode` (records stored in a datamanager).
    Value,
    /// A datamanager's journal directory, beside the file of the records it keeps.
    Journal,
    /// A run report: JSON, not MessagePack.
    Report,
}

/// One encoded sample.
#[derive(Debug)]
pub(crate) struct Sample {
    /// The Rust type (`EoMsg`, `Event`, `NewRecord`).
    pub ty: &'static str,
    /// The variant (of a message enum, of an event's kind), or `-` for a plain value.
    pub variant: String,
    /// A second sample of one variant (another form of its fields) is told apart by this
    /// label in its file name.
    pub label: Option<String>,
    /// How it travels.
    pub form: Form,
    /// The bytes a node sends or stores.
    pub bytes: Vec<u8>,
}

impl Sample {
    /// The sample's file name in a corpus.
    pub(crate) fn file(&self) -> String {
        let ext = match self.form {
            Form::Report => "json",
            _ => "msgpack",
        };
        match &self.label {
            Some(label) => format!("{}.{}.{label}.{ext}", self.ty, self.variant),
            None => format!("{}.{}.{ext}", self.ty, self.variant),
        }
    }
}

/// Every sample of this build. Call variants bridge their reply ports, which needs a tokio
/// runtime.
pub(crate) fn all() -> Result<Vec<Sample>, String> {
    let mut out = Vec::new();
    for group in [
        eo(),
        provision(),
        dispatcher(),
        fence(),
        cart(),
        dm(),
        desk(),
        beat(),
        host(),
        watcher(),
    ] {
        out.extend(group?);
    }
    out.extend(events()?);
    out.extend(records()?);
    Ok(out)
}

/// The samples of one message enum, with an exhaustive match over the variants named (see
/// the module's doc). `local { .. }` names the variants that never cross nodes.
macro_rules! samples {
    ($ty:ident {
        $( $variant:ident { $( $field:ident : $value:expr ),* $(,)? } ),* $(,)?
    } $( local { $( $local:ident ),* $(,)? } )?) => {{
        // never called: it exists to stop the build when a variant has no sample
        #[allow(dead_code)]
        fn every_variant_has_a_sample(m: &$ty) {
            match m {
                $( $ty::$variant { .. } => {} )*
                $($( $ty::$local { .. } => {} )*)?
            }
        }
        let samples: Vec<Result<Sample, String>> = vec![
            $( message(stringify!($ty), $ty::$variant { $( $field: $value, )* }), )*
        ];
        samples.into_iter().collect::<Result<Vec<Sample>, String>>()
    }};
}

/// A message encoded as ractor_cluster sends it: the variant's name and its fields' map.
fn message<M: Message + std::fmt::Debug>(ty: &'static str, m: M) -> Result<Sample, String> {
    let name = format!("{m:?}");
    let (variant, args, form) = match m.serialize() {
        Ok(SerializedMessage::Cast { variant, args, .. }) => (variant, args, Form::Cast),
        Ok(SerializedMessage::Call { variant, args, .. }) => (variant, args, Form::Call),
        Ok(_) => return Err(format!("{ty}::{name}: neither a cast nor a call")),
        Err(_) => return Err(format!("{ty}::{name}: does not serialize")),
    };
    Ok(Sample {
        ty,
        variant,
        label: None,
        form,
        bytes: args,
    })
}

/// A reply port no one listens to: a call's sample needs one to be built.
fn port<T>() -> RpcReplyPort<T> {
    let (tx, _rx) = ractor::concurrency::oneshot();
    RpcReplyPort::from((tx, Duration::from_secs(5)))
}

fn params() -> BTreeMap<String, Value> {
    BTreeMap::from([
        ("speed".to_string(), Value::Float(0.4)),
        ("side".to_string(), Value::Text("left".into())),
        ("laps".to_string(), Value::Int(2)),
        ("reverse".to_string(), Value::Bool(false)),
        (
            "gains".to_string(),
            Value::Array(vec![Value::Float(1.5), Value::Float(0.2)]),
        ),
        (
            "goal".to_string(),
            Value::Struct(BTreeMap::from([
                ("x".to_string(), Value::Float(3.0)),
                ("y".to_string(), Value::Float(-1.0)),
            ])),
        ),
    ])
}

fn eo() -> Result<Vec<Sample>, String> {
    samples!(EoMsg {
        Activate { params: params(), epoch: 7, reply: port() },
        Resume { params: params(), epoch: 8, reply: port() },
        Attach { epoch: 8, since: 3, reply: port() },
        Suspend { epoch: 8 },
        Parameterize { values: params(), epoch: 8, reply: port() },
        Property { request: PropertyRequest::Get("param.speed".into()), reply: port() },
        Inject { fault: FaultKind::Hang },
    } local { Tick, ModuleAbsent })
    .and_then(|mut v| {
        // the other forms of a property request
        for (label, request) in [
            ("group", PropertyRequest::Group(Group::Identification)),
            (
                "collection",
                PropertyRequest::Collection(Collection::Limits),
            ),
        ] {
            let mut s = message(
                "EoMsg",
                EoMsg::Property {
                    request,
                    reply: port(),
                },
            )?;
            s.label = Some(label.into());
            v.push(s);
        }
        Ok(v)
    })
}

fn provision() -> Result<Vec<Sample>, String> {
    samples!(ProvisionMsg {
        Start { operation: "wall-follower".into(), version: "2.0.0".into(), reply: port() },
    })
}

fn dispatcher() -> Result<Vec<Sample>, String> {
    samples!(DispatcherMsg {
        Run { reply: port() },
        Inject { fault: FaultKind::Kill },
        Alive { reply: port() },
    } local {
        OpEnded, Registry, NodeDown, NodeUp, Probe, ProbeDone, ProvisionDue, RebindDeadline,
        ActionDeadline, SuspendGrace, MissionDeadline, Wake, Fenced, NoMajority, Launch,
        Conclude, Abort,
    })
}

fn fence() -> Result<Vec<Sample>, String> {
    samples!(FenceMsg {
        Advance {
            fences: vec![Fence::new("wall-follower", 8), Fence::new("sonar", 3)],
            reply: port(),
        },
    })
}

fn cart() -> Result<Vec<Sample>, String> {
    let fence = || Fence::new("wall-follower", 8);
    samples!(CartMsg {
        Drive { speed: 0.35, steer: -0.1, fence: fence() },
        Halt { fence: fence() },
        EmergencyStop { on: true, fence: fence() },
        SpeedCap { max: Some(0.5), fence: fence() },
        Scan { reply: port() },
        Status { reply: port() },
        Trace { reply: port() },
        Restart { reply: port() },
    } local { Tick })
}

fn record(n: u64) -> NewRecord {
    NewRecord {
        source: "wall-follower".into(),
        class: "feature".into(),
        sub1: Some("corner".into()),
        sub2: None,
        payload: Payload::from_bytes(vec![0x92, 0x01, 0xa1, 0x61]),
        epoch: 8,
        producer: 41,
        producer_seq: n,
    }
}

fn query() -> Box<Query> {
    Box::new(Query {
        class: Some("feature".into()),
        sub1: Some("corner".into()),
        sub2: None,
        source: Some("wall-follower".into()),
        seq_from: Some(10),
        seq_to: None,
        time_from: Some(Duration::from_millis(1500)),
        time_to: None,
        take: Some(Take::Newest(5)),
    })
}

fn dm() -> Result<Vec<Sample>, String> {
    samples!(DmMsg {
        Store { record: Box::new(record(1)), reply: port() },
        Put { record: record(2) },
        PutBatch { records: vec![record(3), record(4)] },
        Select { query: query(), reply: port() },
        SelectWait { query: query(), timeout_ms: 2000, reply: port() },
        SelectWaitPage { query: query(), timeout_ms: 2000, max_bytes: 65536, reply: port() },
        Delete { query: query(), reply: port() },
        Stats { reply: port() },
        Inject { fault: FaultKind::Panic },
        Digest { reply: port() },
        ReplicaStats { reply: port() },
        SelectPage { query: query(), max_bytes: 65536, reply: port() },
        ChangeReplicas { change: Change::Add("gamma".into()), reply: port() },
        // the replicas' own messages, crate-private to marie-dm: sampled there (its
        // `replica_samples`, exhaustive over their variants) and added below
    } local {
        Replica,
        WaitExpired, JournalFlush, JournalRefused, AnswerStats, ReplicaTick, TellApplied,
        ReplicaDurable,
    })
    .and_then(|mut v| {
        for (label, m) in marie::dm::replica_samples() {
            let mut s = message("DmMsg", m)?;
            s.label = Some(label);
            v.push(s);
        }
        Ok(v)
    })
}

fn desk() -> Result<Vec<Sample>, String> {
    samples!(DeskMsg {
        Start {
            run: "run-7f3a".into(),
            mission: b"[mission]\nname = \"demo\"\n".to_vec(),
            watcher_node: "alpha@127.0.0.1:7101".into(),
            watcher_pid: 42,
            reply: port(),
        },
    } local { Lost, Resume, TakeOver })
}

fn beat() -> Result<Vec<Sample>, String> {
    // the beat's own payload is private to marie-cluster's net module: the frame here is an
    // envelope of the right kind whose payload the corpus does not pin (see the report)
    let frame = Envelope::new("heartbeat", &0u64)
        .and_then(|e| e.to_bytes())
        .map_err(|e| e.to_string())?;
    samples!(BeatMsg { Beat { frame: frame } } local { Tick, Said, Reach })
}

fn host() -> Result<Vec<Sample>, String> {
    let declaration = Declaration {
        name: "world".into(),
        id: 3,
        durability: Some(Durability::Process),
        catch_up: Some(4096),
        retention: Some(10_000),
        class_retention: BTreeMap::from([("feature".to_string(), 500)]),
        replace_after: Some(Duration::from_secs(30)),
        spares: vec!["delta".into()],
    };
    samples!(HostMsg {
        Start { declaration: declaration, voters: vec!["alpha".into(), "beta".into()], reply: port() },
        Drop { dm: "world".into(), reply: port() },
        Declared { dm: "world".into(), reply: port() },
    })
}

fn watcher() -> Result<Vec<Sample>, String> {
    let frame = event_frame(&run_ended())?;
    samples!(WatcherMsg { Numbered { stream: 1, seq: 17, frame: frame } })
}

fn run_ended() -> Event {
    Event {
        at_ms: 5200,
        node: "alpha".into(),
        kind: EventKind::RunEnded {
            outcome: Outcome::Succeeded,
            reason: String::new(),
            run_ms: 5100,
            status: 0x11,
            flags: vec!["DONE".into(), "DOCKED".into()],
        },
    }
}

/// The kind of an event frame (marie-cluster's relay names it so; private there).
const EVENT_KIND: &str = "event";

pub(crate) fn event_frame(event: &Event) -> Result<Vec<u8>, String> {
    Envelope::new(EVENT_KIND, event)
        .and_then(|e| e.to_bytes())
        .map_err(|e| e.to_string())
}

/// Event frames as the relay forwards them to watchers.
fn events() -> Result<Vec<Sample>, String> {
    let lost = Event {
        at_ms: 2300,
        node: "beta".into(),
        kind: EventKind::Lost {
            operation: "wall-follower".into(),
            cause: LossCause::DiedInAction {
                action: "follow-wall".into(),
            },
        },
    };
    [("run_ended", run_ended()), ("lost", lost)]
        .into_iter()
        .map(|(variant, event)| {
            Ok(Sample {
                ty: "Event",
                variant: variant.into(),
                label: None,
                form: Form::Envelope,
                bytes: event_frame(&event)?,
            })
        })
        .collect()
}

/// Values a datamanager stores.
fn records() -> Result<Vec<Sample>, String> {
    let bytes = marie::wire::encode(&record(9)).map_err(|e| e.to_string())?;
    Ok(vec![Sample {
        ty: "NewRecord",
        variant: "-".into(),
        label: None,
        form: Form::Value,
        bytes,
    }])
}

//! # marie-dm
//!
//! The dm-interface: datamanagers, the only way operations share data.
//!
//! In MARIE (thesis 3.2.5.2 and appendix B) elementary operations never talk to each other;
//! they store records in, and select records from, *datamanagers*. A record carries a class
//! and up to two sub-class levels chosen by its producer and an opaque payload; on storing,
//! the DM adds a sequence number, a time stamp and the source. One select retrieves by almost
//! any criterion — class, sub-classes, source, sequence number, time — and a select can be
//! held open until a matching record arrives or a timeout passes. The thesis runs three DMs:
//! [`WORLD`] (world map, walls), [`FEATURE`] (sensor features) and [`PARAMETER`] (parameters
//! planned for a later task).
//!
//! Here a DM is a ractor actor ([`Datamanager`], spawned with [`spawn_datamanager`]) that
//! speaks [`DmMsg`] and publishes itself in the [registry](marie_vocabulary::registry) by name and id;
//! [`DmClient`] is the typed way to talk to it, locally or across nodes:
//!
//! - [`Record`] / [`NewRecord`] / [`Payload`] — what is stored; payloads are MessagePack, with
//!   typed helpers ([`Payload::encode`], [`Record::decode`]); a record read in the DM's own
//!   process is decoded once for all its readers ([`PayloadType`]), and its names are the
//!   store's, shared ([`Name`]);
//! - [`Query`] — what to select, delete, wait for or subscribe to;
//! - [`Store`] — the indexed store itself, usable without an actor;
//! - [`Subscription`] — new records as a stream, built as a long poll over `SelectWait`;
//! - `credits` and `outbox` — puts to a DM on another node: held to a window, and
//!   coalesced in flight into batches.
//!
//! # Indexing invariant: select cost grows with the answer, not with the store
//! Each class keeps its records in seq order, with sorted seq sets per first sub-class, per
//! (first, second) sub-class and per source; a time index maps time stamps to seqs (they never
//! decrease with seq, so a time range is a seq range). A select walks only the narrowest set
//! its query names, only over the seq range it allows, backwards for "newest N" and stopping
//! after N; a query without a class does so in each class and merges them by seq. Selecting
//! the newest 10 front sonar readings costs the same with a thousand or a million records
//! stored. Storing is a few appends (no tree to rebalance), so a high-rate sensor can `Put`
//! at close to the speed of a bare actor message (see `benches/dm.rs`).
//!
//! # Retention
//! Each class keeps at most a bounded number of records ([`DmConfig`]: a default bound,
//! [`DmConfig::DEFAULT_RETENTION`] = 10 000 unless set, and per-class bounds; on a node,
//! `retention` and `class_retention` of its `[[datamanager]]`); storing one more drops the
//! oldest record *of that class*, so a high-rate sensor cannot grow memory without limit nor
//! push out a rarely written world map. It is never silent: the first record a class drops
//! is told — a warning in the log and a `dm_retention` event on the node's bus, once per
//! class — and [`DmStats::dropped_by_class`] counts them. A subscriber sees dropped records
//! as a gap in seq numbers.
//!
//! # What a client's `Ok` promises
//! [`DmClient::store`] and [`DmClient::put_all`] answer once the datamanager has stored the
//! record at its durability (on a replicated one, in a majority of its replicas' journals):
//! the road for a producer that must not drop records. [`DmClient::put`],
//! [`DmClient::put_batch`] and [`DmClient::put_waiting`] answer once it is handed over —
//! lost if the datamanager's instance is lost before storing it. Every road follows the
//! datamanager to its next instance; [`DmClient`] says how, road by road.
//!
//! ```
//! use marie_vocabulary::clock::RealClock;
//! use marie_dm::{self as dm, DmClient, Query};
//!
//! # #[tokio::main(flavor = "current_thread")] async fn main() {
//! let mut args = dm::WORLD.args(RealClock::shared());
//! args.name = "world-doc".into(); // registry names are process-wide
//! let (actor, handle) = dm::spawn_datamanager(args).await.unwrap();
//! let client = DmClient::new(actor.clone(), "wall-sensor");
//! let seq = client.store("wall", Some("left"), None, &(0.0, 1.5)).await.unwrap();
//! let walls = client
//!     .select_typed::<(f64, f64)>(Query::class("wall").sub1("left").newest(1))
//!     .await
//!     .unwrap();
//! assert_eq!(walls[0].0.seq, seq);
//! assert_eq!(walls[0].0.source, "wall-sensor");
//! assert_eq!(walls[0].1, (0.0, 1.5));
//! actor.stop(None);
//! handle.await.unwrap();
//! # }
//! ```

#![warn(missing_docs)]

mod acks;
mod actor;
mod applied;
mod args;
mod audit;
mod client;
mod credits;
mod entry;
mod error;
mod follow;
mod forward;
mod handlers;
mod heir;
mod index;
mod journal;
mod kind;
mod majority;
mod messages;
mod name;
mod outbox;
mod packed;
mod page;
pub mod probe;
mod producers;
mod query;
mod reads;
mod record;
mod replica;
mod replica_state;
mod replicated;
mod shared;
mod start;
mod state;
mod storage;
mod store;
mod subscription;
mod waits;

pub use acks::{digest, Ack, AckSink};
pub use actor::{spawn_datamanager, spawn_datamanager_linked, Datamanager};
pub use args::{DmArgs, DmSpec, FEATURE, PARAMETER, RUN, WORLD};
pub use audit::Ledger;
pub use client::DmClient;
pub use credits::{
    BATCH as PUT_BATCH, REPLICATED_WINDOW as REPLICATED_PUT_WINDOW, WINDOW as PUT_WINDOW,
};
pub use error::DmError;
pub use heir::{Heir, Inherited};
pub use journal::{
    journal_dir, DirLock, Durability, FormatError, LockError, Recovery, UnknownDurability,
    FORMAT as JOURNAL_FORMAT, OLDEST_FORMAT as OLDEST_JOURNAL_FORMAT, SNAPSHOT_MIN,
};
pub use kind::RecordKind;
pub use majority::{
    caught_up, leaderless, newest_leader, replica_nodes, replica_views, without_leader, NoMajority,
    MAJORITY_WAIT, VIEW_TIMEOUT,
};
pub use messages::{DmMsg, DmStats, Held, ReplicaStats, StoreDigest};
pub use name::Name;
pub use page::{Page, PAGE_BYTES};
pub use query::{Query, Take};
pub use record::{NewRecord, Payload, Record, RecordHeader, MAX_NAME_LEN};
/// One sample of each message the replicas of a replicated datamanager send each other, as
/// the `DmMsg::Replica` that carries it: the compatibility corpus's (`marie compat`).
#[doc(hidden)]
pub use replica::samples::samples as replica_samples;
pub use replica::{
    Change, ChangeError, Members, Replication, ReplicationError, Timing as ReplicationTiming,
    MIN_VOTERS, SCOPE as REPLICA_SCOPE, UNCHECKED_READS_ENV,
};
pub use shared::PayloadType;
pub use state::DatamanagerState;
pub use store::{DmConfig, Plan, Store};
pub use subscription::Subscription;

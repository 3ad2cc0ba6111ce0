//! A run's vocabulary: how a run and an operation's part end ([`Outcome`], [`OpEnd`]), why
//! an instance was lost ([`LossCause`]), a rebind ([`RebindRecord`]), a
//! dispatcher's run taken over by a standby ([`TakeoverRecord`]), a choice among
//! instances ([`Choice`]), the faults injected on purpose ([`FaultKind`]), what the check
//! of the datamanagers found at the end ([`DmCheck`]), what a robot says of a run
//! ([`RobotSection`]) and what ran ([`Provenance`]: the build, the files, the parameters).
//!
//! Why a module of its own: these are the words both the event stream ([`crate::events`])
//! and the dispatcher (`marie_actors::dispatcher`) speak, and the report ([`crate::report`]) is
//! written in. Kept below all three, they make one layering — `run` ← `events` ← `report`,
//! and `dispatcher` above them — with no module importing one above it (checked by
//! `tests/layers.rs`). Every type here is plain serializable data under stable names.
//!
//! ```
//! use marie_vocabulary::run::{FaultKind, LossCause, Outcome};
//! assert_eq!(serde_json::to_string(&Outcome::Succeeded).unwrap(), "\"succeeded\"");
//! assert_eq!("stop-node".parse::<FaultKind>(), Ok(FaultKind::StopNode));
//! assert_eq!(LossCause::Killed.to_string(), "died: killed");
//! ```

mod check;
mod choice;
mod fault;
mod loss;
mod outcome;
pub mod provenance;
mod rebind;
mod takeover;
mod upgrade;

pub use check::{AppliedSpan, DmCheck};
pub use choice::{Candidate, Choice, Verdict};
pub use fault::{Aim, FaultKind, UnknownFault};
pub use loss::LossCause;
pub use outcome::{OpEnd, Outcome};
pub use provenance::{
    Build, Digest, FileRead, FileRole, NodeBuild, ParamSetting, ParamSource, ParamValue, Provenance,
};
pub use rebind::RebindRecord;
pub use takeover::TakeoverRecord;
pub use upgrade::{RollbackRecord, UpgradeRecord};

/// What a robot said of a run — its judgement beside the dispatcher's (for marie's
/// simulated cart: where it ended, collisions, the seed, whether it ended in the goal area,
/// the world's verdict, the commands its drivers refused by epoch) — as JSON fields this
/// crate does not type: it knows no robot. The `judged` event carries it and the report
/// writes it beside its own fields.
pub type RobotSection = serde_json::Map<String, serde_json::Value>;

//! What a datamanager is started with: its identity ([`DmSpec`], and the thesis' well-known
//! ones) and its start-up arguments ([`DmArgs`]) — what the user says. The actor turns the
//! durability, journal directory and replication said here into one storage mode at its
//! start (`storage`), and refuses a combination that cannot work (`start`).

use super::heir::Heir;
use super::journal::Durability;
use super::replica::Replication;
use super::store::DmConfig;
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::EventBus;
use std::path::PathBuf;

/// Identity of a well-known datamanager.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DmSpec {
    /// Numeric id (the thesis' DM ids are 1201–1203).
    pub id: u32,
    /// Registry name.
    pub name: &'static str,
}

impl DmSpec {
    /// The identity of a datamanager named `name` with numeric id `id`: an embedder's own
    /// well-known datamanager, as a constant operations name it by
    /// (`marie_actors::declare::DmName`).
    pub const fn new(name: &'static str, id: u32) -> DmSpec {
        DmSpec { id, name }
    }

    /// Start-up arguments for this DM with `clock` and the default limits.
    pub fn args(self, clock: SharedClock) -> DmArgs {
        DmArgs {
            id: self.id,
            name: self.name.to_string(),
            clock,
            config: DmConfig::default(),
            durability: Durability::Memory,
            journal_dir: None,
            replication: None,
            events: None,
            heir: Some(Heir::new()),
        }
    }
}

/// The world datamanager: world map, walls.
pub const WORLD: DmSpec = DmSpec {
    id: 1203,
    name: "world",
};

/// The feature datamanager: sensor features such as sonar points and line segments.
pub const FEATURE: DmSpec = DmSpec {
    id: 1201,
    name: "feature",
};

/// The parameter datamanager: parameters planned for a later task, e.g. the path to drive.
pub const PARAMETER: DmSpec = DmSpec {
    id: 1202,
    name: "parameter",
};

/// The run datamanager: where a dispatcher records its run's progress at every
/// transition (its checkpoints, see `marie_actors::dispatcher`), kept in replicas on other
/// nodes so that a standby dispatcher can take the run over.
pub const RUN: DmSpec = DmSpec {
    id: 1204,
    name: "run",
};

/// Start-up arguments of a [`Datamanager`](super::Datamanager).
#[derive(Clone)]
pub struct DmArgs {
    /// Numeric id it is published under.
    pub id: u32,
    /// Name it is published under (letters, digits, `-`, `_`, `.`; not all digits).
    pub name: String,
    /// Source of time stamps and wait timeouts.
    pub clock: SharedClock,
    /// Retention and payload limits.
    pub config: DmConfig,
    /// How durable acknowledged writes are: at `memory` nothing is written to disk, at
    /// `process` and `sync` the datamanager keeps a journal in `journal_dir` (`journal`).
    pub durability: Durability,
    /// Where the journal is (required unless `durability` is `memory`); see
    /// [`super::journal::journal_dir`] for a node's layout.
    pub journal_dir: Option<PathBuf>,
    /// Replicas on other nodes (`replica`): this is one of them. Needs a journal.
    pub replication: Option<Replication>,
    /// Where it tells what it does on its own: a replica that became the leader or stepped
    /// down (`dm_promoted`, `dm_fenced`), a class that started dropping records by retention
    /// (`dm_retention`), what its puts applied (`dm_applied`); a node gives its bus.
    pub events: Option<EventBus>,
    /// At durability `memory`: where its records wait for its next incarnation when it
    /// ends — a crash, a kill, a stop — so that a datamanager restarted from clones of these
    /// arguments starts with them ([`Heir`]: memory survives the datamanager's crash, not
    /// its process's). `None`: a restarted memory datamanager starts empty. Ignored with a
    /// journal, which is read back instead.
    pub heir: Option<Heir>,
}

impl DmArgs {
    /// Keep a journal in `dir` at `durability`.
    pub fn with_journal(mut self, dir: impl Into<PathBuf>, durability: Durability) -> DmArgs {
        self.journal_dir = Some(dir.into());
        self.durability = durability;
        self
    }

    /// Start empty at every start, as if nothing had been kept (no [`Heir`]).
    pub fn without_heir(mut self) -> DmArgs {
        self.heir = None;
        self
    }

    /// Be one of the replicas `replication` names (with a journal: see
    /// [`DmArgs::with_journal`]).
    pub fn with_replication(mut self, replication: Replication) -> DmArgs {
        self.replication = Some(replication);
        self
    }
}

impl std::fmt::Debug for DmArgs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DmArgs")
            .field("id", &self.id)
            .field("name", &self.name)
            .field("config", &self.config)
            .field("durability", &self.durability)
            .field("journal_dir", &self.journal_dir)
            .field("replication", &self.replication)
            .field("heir", &self.heir)
            .finish_non_exhaustive()
    }
}

//! A datamanager's start, step by step: its arguments checked and turned into a storage
//! mode ([`Mode`]), its journal opened and read back, a replica's side of the protocol
//! started. Whatever cannot work fails the spawn here, with a [`StartError`] that says why,
//! before anything is published.

use super::args::DmArgs;
use super::error::DmError;
use super::heir::{Inheritance, Inherited};
use super::journal::{Durability, Hooks, Journal, Opened, Recovery};
use super::messages::DmMsg;
use super::producers::Producers;
use super::replica::{Replication, ReplicationError};
use super::replica_state::{ReplicaStartError, ReplicaState};
use super::storage::Storage;
use super::store::Store;
use marie_vocabulary::fence::FenceTable;
use ractor::ActorRef;
use std::path::Path;

/// Why a datamanager did not start (the reason its spawn fails with).
#[derive(Debug, thiserror::Error)]
pub(crate) enum StartError {
    /// Its name is not a registry name.
    #[error("invalid datamanager name {0:?}: use letters, digits, '-', '_' or '.'")]
    InvalidName(String),
    /// Its replication cannot work (too few replicas, this node not among them, ...).
    #[error("datamanager {name}: {problem}")]
    Replication {
        /// The datamanager.
        name: String,
        /// What is wrong.
        problem: ReplicationError,
    },
    /// Replicated at durability `memory`.
    #[error(
        "datamanager {0}: replicas need a journal (durability process or sync): a replica's \
         vote must survive its restart"
    )]
    ReplicasWithoutJournal(String),
    /// A durability that keeps a journal, and no directory for it.
    #[error("datamanager {name}: durability {durability} needs a journal directory")]
    NoJournalDir {
        /// The datamanager.
        name: String,
        /// Its durability.
        durability: Durability,
    },
    /// The journal could not be opened or read back.
    #[error("datamanager {name}: {error}")]
    Journal {
        /// The datamanager.
        name: String,
        /// Why.
        error: DmError,
    },
    /// The replica's side of the protocol could not start.
    #[error("datamanager {name}: {error}")]
    Replica {
        /// The datamanager.
        name: String,
        /// Why.
        error: ReplicaStartError,
    },
}

/// The storage a datamanager's arguments ask for, checked: what [`Storage`] it will be.
#[derive(Clone, Copy)]
pub(crate) enum Mode<'a> {
    /// Nothing on disk.
    Memory,
    /// A journal in `dir`.
    Journaled {
        dir: &'a Path,
        durability: Durability,
    },
    /// A journal in `dir`, as one of the replicas `replication` names.
    Replicated {
        dir: &'a Path,
        durability: Durability,
        replication: &'a Replication,
    },
}

impl<'a> Mode<'a> {
    /// The mode `args` ask for, or why they cannot work. Checked first in `pre_start`, so a
    /// bad name or combination fails the spawn before anything is opened or published.
    pub(crate) fn of(args: &'a DmArgs) -> Result<Mode<'a>, StartError> {
        if !valid_name(&args.name) {
            return Err(StartError::InvalidName(args.name.clone()));
        }
        if let Some(replication) = &args.replication {
            replication
                .check()
                .map_err(|problem| StartError::Replication {
                    name: args.name.clone(),
                    problem,
                })?;
        }
        let durability = args.durability;
        if durability == Durability::Memory {
            return match args.replication {
                // a replica's vote must survive its restart
                Some(_) => Err(StartError::ReplicasWithoutJournal(args.name.clone())),
                None => Ok(Mode::Memory),
            };
        }
        let dir = args
            .journal_dir
            .as_deref()
            .ok_or_else(|| StartError::NoJournalDir {
                name: args.name.clone(),
                durability,
            })?;
        Ok(match &args.replication {
            None => Mode::Journaled { dir, durability },
            Some(replication) => Mode::Replicated {
                dir,
                durability,
                replication,
            },
        })
    }
}

/// Same rule as the registry's: a single word of letters, digits, `-`, `_`, `.`, not all
/// digits (those are ids).
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        && !name.chars().all(|c| c.is_ascii_digit())
}

/// What a datamanager starts with: its store as its journal left it, or at `memory` as its
/// previous incarnation left it (`heir`; empty at the first start).
pub(crate) struct Held {
    pub(crate) store: Store,
    pub(crate) fences: FenceTable,
    pub(crate) producers: Producers,
    /// What the start read back from the journal (`None` at `memory`).
    pub(crate) recovery: Option<Recovery>,
    /// What the start took from its previous incarnation (at `memory`, if it was left
    /// anything).
    pub(crate) inherited: Option<Inherited>,
}

/// Open the storage `mode` names: the journal read back (and a replica's protocol state
/// restored from it and joined to its group), or in memory what the previous incarnation
/// left its heir. From here the heir is held: the state made of what this returns must be
/// built before anything else can fail, so that its drop leaves the records again.
pub(crate) async fn open(
    myself: &ActorRef<DmMsg>,
    args: &DmArgs,
    mode: Mode<'_>,
) -> Result<(Held, Storage), StartError> {
    match mode {
        Mode::Memory => {
            let inheritance = match &args.heir {
                Some(heir) => heir.inherit(&args.name).await,
                None => Inheritance::nothing(),
            };
            let held = match inheritance.estate {
                Some(estate) => Held {
                    inherited: Some(Inherited {
                        records: estate.store.len() as u64,
                        refused: inheritance.refused,
                    }),
                    store: estate.store,
                    fences: estate.fences,
                    producers: estate.producers,
                    recovery: None,
                },
                None => Held {
                    store: Store::new(args.config.clone()),
                    fences: FenceTable::default(),
                    producers: Producers::default(),
                    recovery: None,
                    inherited: None,
                },
            };
            Ok((held, Storage::Memory))
        }
        Mode::Journaled { dir, durability } => {
            let mut opened = open_journal(myself, args, dir, durability).await?;
            rebase(&mut opened, args);
            let (held, journal) = split(opened);
            Ok((held, Storage::Journaled(journal)))
        }
        Mode::Replicated {
            dir,
            durability,
            replication,
        } => {
            // (no rebase: a replica's time stamps are the leader's, the same on every replica)
            let mut opened = open_journal(myself, args, dir, durability).await?;
            // the pairs of what is committed only: a journal of an older build kept those of
            // proposals past it too (`Producers::each_upto`); the tail's are noted as it is
            // applied
            if let Some(log) = &opened.log {
                opened.producers.forget_after(log.committed.0);
            }
            let replica = ReplicaState::start(
                &args.name,
                replication,
                dir.to_path_buf(),
                opened.log.take(),
                &opened.store,
                myself,
                args.events.clone(),
            )
            .map_err(|error| StartError::Replica {
                name: args.name.clone(),
                error,
            })?;
            let (held, journal) = split(opened);
            Ok((
                held,
                Storage::Replicated {
                    journal,
                    replica: Box::new(replica),
                },
            ))
        }
    }
}

/// Lock the journal in `dir` and read it back; its hooks send the datamanager its
/// `JournalFlush` and `JournalRefused`.
async fn open_journal(
    myself: &ActorRef<DmMsg>,
    args: &DmArgs,
    dir: &Path,
    durability: Durability,
) -> Result<Opened, StartError> {
    let hooks = {
        let (me, me_too) = (myself.clone(), myself.clone());
        Hooks {
            flush: Box::new(move || me.cast(DmMsg::JournalFlush {}).is_ok()),
            refused: Box::new(move |seqs| {
                let _ = me_too.cast(DmMsg::JournalRefused { seqs });
            }),
        }
    };
    Journal::open(dir, durability, args.config.clone(), hooks)
        .await
        .map_err(|error| StartError::Journal {
            name: args.name.clone(),
            error,
        })
}

/// A journal whose time stamps run ahead of this clock was written under another (an
/// earlier process's): its stamps are moved back onto this one, and the epochs its sources
/// had — numbered by that clock's runs (`dispatcher::healing`'s epoch base) — are
/// forgotten, or a new run's first epochs would be refused as stale.
fn rebase(opened: &mut Opened, args: &DmArgs) {
    let shifted = opened.store.rebase_times(args.clock.now());
    if !shifted.is_zero() {
        opened.fences = FenceTable::default();
        tracing::info!(dm = %args.name, by = ?shifted, "journal written under an earlier clock: time stamps moved back onto this one, epochs forgotten");
    }
}

/// What was read back, apart from the journal it was read from.
fn split(opened: Opened) -> (Held, Journal) {
    let held = Held {
        store: opened.store,
        fences: opened.fences,
        producers: opened.producers,
        recovery: Some(opened.recovery),
        inherited: None,
    };
    (held, opened.journal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert!(valid_name("world"));
        assert!(valid_name("dm-test.1"));
        assert!(!valid_name("1203"));
        assert!(!valid_name("a b"));
        assert!(!valid_name(""));
        use crate::{FEATURE, PARAMETER, WORLD};
        assert_eq!((WORLD.id, FEATURE.id, PARAMETER.id), (1203, 1201, 1202));
    }

    #[test]
    fn a_combination_that_cannot_work_says_why() {
        let clock = marie_vocabulary::clock::RealClock::shared();
        let why = |args: DmArgs| Mode::of(&args).err().map(|e| e.to_string());
        let args = crate::WORLD.args(clock);
        assert_eq!(why(args.clone()), None);
        let mut bad = args.clone();
        bad.name = "12".into();
        assert_eq!(
            why(bad).as_deref(),
            Some(r#"invalid datamanager name "12": use letters, digits, '-', '_' or '.'"#)
        );
        let replicated = args
            .clone()
            .with_replication(Replication::new("a", ["a", "b", "c"]));
        assert_eq!(
            why(replicated.clone()).as_deref(),
            Some(
                "datamanager world: replicas need a journal (durability process or sync): a \
                 replica's vote must survive its restart"
            )
        );
        let mut no_dir = replicated;
        no_dir.durability = Durability::Process;
        assert_eq!(
            why(no_dir).as_deref(),
            Some("datamanager world: durability process needs a journal directory")
        );
        let too_few = args.with_replication(Replication::new("a", ["a", "b"]));
        assert_eq!(
            why(too_few).as_deref(),
            Some(
                "datamanager world: 2 replicas: a majority of them cannot survive the loss of \
                 one; keep three or more"
            )
        );
    }
}

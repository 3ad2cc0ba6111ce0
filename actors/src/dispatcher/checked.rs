//! The choices a mission's check made, handed to the dispatcher that runs it — so that a
//! run selects each operation once, not once at the check and again at the bind.
//!
//! Checking a mission against the running instances ([`RegistryCatalog::for_mission`], what
//! `Node::check_mission` and so `marie run` do) asks every live instance of every operation
//! it uses for its properties and chooses among them ([`selection`](super::selection)). A
//! mission validated against that catalog carries those choices
//! ([`Mission::checked`](super::mission::Mission::checked)): per
//! operation, the need it was chosen for, the choice with every candidate's verdict (what
//! the run's `selected` event tells), the chosen instance as the check saw it (address,
//! node, identity, schema, flags, epoch, deadline) and every instance the registry listed
//! then.
//!
//! When the run starts, the dispatcher *confirms* each choice ([`CheckedChoice::confirm`])
//! instead of asking every candidate again: a registry lookup (a local read, no message) and
//! one request, to the chosen instance, for its general group. The choice holds unless an
//! instance changed since ([`Changed`]):
//!
//! - the chosen instance left the registry, its node was declared down, or it does not
//!   answer within its declared deadline;
//! - an instance the check did not see joined (a restart, a spare, a better fit: any of them
//!   could change the choice, so the operation is chosen again rather than guessed at);
//! - the chosen instance is in use now (an instance in use ranks below every free one);
//! - its schema is not the one the check saw (its parameter count differs), or the mission's
//!   needs of the operation are not those the choice was made for.
//!
//! Then that operation alone is selected again among every live instance, exactly as a
//! mission without a check is; the others bind at once. Either way the binding's epoch
//! starts above the one the instance reports *now* (its general group is asked at the bind
//! in both cases), so an epoch accepted between the check and the run is never undercut.
//!
//! # What a confirmation does not see
//! An instance the check saw and did not choose is not asked again: if it was in use then
//! and is free now, or has restarted its up-time, the ranking among instances that fit the
//! mission equally may differ from a fresh selection's. The chosen instance still passes
//! the same [`admits`](super::selection::admits) and fits the mission as well as any; only
//! the order among equals is the check's. A mission is checked ahead of its run by the
//! caller's choice; how long ago does not matter, only what changed.
//!
//! The choices are not serialized: a mission read back from JSON has none, and its run
//! selects everything.

use super::candidates::{self, ExamineError, Examined, Prospect};
use super::selection::Need;
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::Choice;
use ractor::ActorId;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::sync::Arc;

/// The choices a mission's check made, by operation name: what a mission checked against
/// the running instances ([`RegistryCatalog::for_mission`](super::RegistryCatalog::for_mission))
/// carries to its run ([`Mission::checked`](super::mission::Mission::checked)), so that the
/// run selects once.
///
/// Per operation it holds the need the choice was made for, the choice with every
/// candidate's verdict (what the run's `selected` event tells), the chosen instance as the
/// check saw it, and every instance the registry listed then. When the run starts, the
/// dispatcher confirms each choice — a registry read and one request to the chosen instance
/// for its general group (epoch, deadline, in use) — and binds it; it selects that operation
/// again among every live instance only when something changed since: the chosen instance
/// is gone, on a node declared down, silent, in use or declares another schema, an instance
/// the check did not see joined, or the mission needs something else of the operation. A
/// losing candidate is not asked again, so one that was busy at the check and is free now
/// does not displace the choice among instances that fit the mission equally.
///
/// Empty for a mission not checked against the running instances (validated against a
/// [`StaticCatalog`](super::mission::StaticCatalog), or read back from JSON: the choices
/// are never serialized).
#[derive(Clone, Default)]
pub struct CheckedChoices(Arc<BTreeMap<String, CheckedChoice>>);

/// The check's choice for one operation: what it was chosen for, among which instances,
/// and the chosen one as the check saw it.
#[derive(Clone, Debug)]
pub(crate) struct CheckedChoice {
    /// What the mission needed of the operation at the check.
    need: Need,
    /// Every candidate with its verdict, as the check chose.
    choice: Choice,
    /// The chosen instance, as the check saw it.
    chosen: Prospect,
    /// Every instance the registry listed at the check, answered or not.
    seen: BTreeSet<ActorId>,
}

/// What changed since the check, so that its choice for an operation no longer holds and
/// the dispatcher selects that operation again.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum Changed {
    /// The mission's needs of the operation are not those the choice was made for.
    #[error("the mission's needs of the operation changed since the check")]
    Need,
    /// The chosen instance left the registry.
    #[error("the chosen instance {address} is gone")]
    Gone {
        /// The chosen instance.
        address: String,
    },
    /// The chosen instance's node was declared down by the failure detector.
    #[error("the chosen instance {address}'s node {node} was declared down")]
    NodeDown {
        /// The chosen instance.
        address: String,
        /// Its node.
        node: String,
    },
    /// Instances the check did not see joined the registry.
    #[error("{} instance(s) joined since the check: {}", .addresses.len(), .addresses.join(", "))]
    Joined {
        /// The newcomers.
        addresses: Vec<String>,
    },
    /// The chosen instance did not answer within its deadline.
    #[error("the chosen instance {address} does not answer: {error}")]
    Silent {
        /// The chosen instance.
        address: String,
        /// What happened.
        error: ExamineError,
    },
    /// The chosen instance runs an activation now, for another binding.
    #[error("the chosen instance {address} is in use now")]
    InUse {
        /// The chosen instance.
        address: String,
    },
    /// The chosen instance declares another number of parameters than at the check.
    #[error(
        "the chosen instance {address} declares {now} parameter(s), not {checked} as at the check"
    )]
    Schema {
        /// The chosen instance.
        address: String,
        /// Parameters its schema had at the check.
        checked: usize,
        /// Parameters it declares now.
        now: usize,
    },
}

impl CheckedChoices {
    /// The choices for a mission among the instances a check examined, by mission key
    /// (`examined`). `needs` are the mission's operations
    /// ([`Mission::operation_needs`](super::mission::Mission::operation_needs)): the key each one's
    /// instances were examined under and what the whole mission needs of it (every action's
    /// parameters, its `[requires]`). Each gets the choice among the instances of it the
    /// check found — the choice the dispatcher would make among them. An operation without
    /// a choice (no instance fits) is left out: the run selects it again.
    pub(crate) fn gather<'a>(
        needs: impl IntoIterator<Item = (&'a str, Need)>,
        examined: &BTreeMap<String, Examined>,
    ) -> Self {
        let mut choices = BTreeMap::new();
        for (key, need) in needs {
            let Some(found) = examined.get(key) else {
                continue;
            };
            let name = need.operation.as_str();
            let fit: Vec<Prospect> = found
                .found
                .iter()
                .filter(|c| c.info.name == name)
                .cloned()
                .collect();
            let choice = candidates::choose(&need, &fit);
            let Some(index) = choice.chosen_index() else {
                continue;
            };
            let chosen = fit[index].clone();
            let seen = found.seen.iter().copied().collect();
            choices.insert(
                name.to_string(),
                CheckedChoice {
                    need,
                    choice,
                    chosen,
                    seen,
                },
            );
        }
        CheckedChoices(Arc::new(choices))
    }

    /// True when the mission carries no choice (it was not checked against the running
    /// instances, or no instance fitted).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// How many operations the check chose an instance for.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// The check's choice for `operation` (its canonical name): every candidate with its
    /// verdict — what the run's `selected` event tells if the choice still holds when the
    /// run starts.
    pub fn choice(&self, operation: &str) -> Option<&Choice> {
        self.0.get(operation).map(|c| &c.choice)
    }

    /// The operations the check chose an instance for.
    pub fn operations(&self) -> impl Iterator<Item = &str> + '_ {
        self.0.keys().map(String::as_str)
    }

    /// The check's choice for `operation`, to confirm.
    pub(crate) fn get(&self, operation: &str) -> Option<&CheckedChoice> {
        self.0.get(operation)
    }
}

impl CheckedChoice {
    /// The choice, with every candidate's verdict.
    pub(crate) fn choice(&self) -> &Choice {
        &self.choice
    }

    /// The chosen instance, as it is now, if the choice still holds for `need`: nothing
    /// changed since the check (see the module docs). Asks the chosen instance its
    /// general group, within the deadline it declared; nobody else is asked.
    pub(crate) async fn confirm(&self, need: &Need) -> Result<Prospect, Changed> {
        let chosen = &self.chosen;
        let id = chosen.client.actor().get_id();
        let address = id.to_string();
        if *need != self.need {
            return Err(Changed::Need);
        }
        let listed = registry::lookup(ModuleKind::Operation, &need.operation);
        if !listed.iter().any(|i| i.actor_id() == id) {
            return Err(Changed::Gone { address });
        }
        if registry::is_declared_down(&chosen.node) {
            return Err(Changed::NodeDown {
                address,
                node: chosen.node.clone(),
            });
        }
        let joined: Vec<String> = listed
            .iter()
            .filter(|i| !self.seen.contains(&i.actor_id()))
            .map(|i| i.actor_id().to_string())
            .collect();
        if !joined.is_empty() {
            return Err(Changed::Joined { addresses: joined });
        }
        let client = chosen.client.clone().with_timeout(chosen.deadline);
        let general = candidates::general(&client)
            .await
            .map_err(|error| Changed::Silent {
                address: address.clone(),
                error,
            })?;
        if general.in_use {
            return Err(Changed::InUse { address });
        }
        let checked = chosen.info.schema.len();
        if general.param_count != checked {
            return Err(Changed::Schema {
                address,
                checked,
                now: general.param_count,
            });
        }
        Ok(chosen.clone().refreshed(&general))
    }
}

impl PartialEq for CheckedChoices {
    /// Equal when both chose the same instances among the same ones, for the same needs,
    /// with the same verdicts.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
            || (self.0.len() == other.0.len()
                && self.0.iter().zip(other.0.iter()).all(|((a, x), (b, y))| {
                    a == b
                        && x.need == y.need
                        && x.choice == y.choice
                        && x.seen == y.seen
                        && x.chosen.client.actor().get_id() == y.chosen.client.actor().get_id()
                }))
    }
}

impl fmt::Debug for CheckedChoices {
    /// Each operation with the address of the instance chosen for it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map()
            .entries(
                self.0
                    .iter()
                    .map(|(op, c)| (op, c.chosen.client.actor().get_id().to_string())),
            )
            .finish()
    }
}

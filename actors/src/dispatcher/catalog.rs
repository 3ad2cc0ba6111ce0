//! A mission [`Catalog`] built from the live registry and the property interface.

use super::candidates::{describe, select, Examined};
use super::checked::CheckedChoices;
use super::mission::{Catalog, Mission, OpInfo, ParsedMission};
use crate::eo::{EoClient, EoError};
use marie_vocabulary::registry::{self, ModuleKind};
use std::collections::BTreeMap;

/// The operations a mission may use, as the running system describes them: each key is
/// looked up in the registry and its first live instance asked for its identity and
/// parameter declarations. Keys with no live instance are absent, so validation reports them
/// as unknown operations.
#[derive(Clone, Debug, Default)]
pub struct RegistryCatalog {
    ops: BTreeMap<String, OpInfo>,
    names: Vec<String>,
    /// Operations with live instances none of which fits the mission, and why.
    unfit: BTreeMap<String, String>,
    /// What [`RegistryCatalog::for_mission`] found of each mission key: the instances the
    /// registry listed and those that answered — the check's choices are made among them.
    examined: BTreeMap<String, Examined>,
}

impl RegistryCatalog {
    /// Ask the registry about every key in `keys` (names or ids).
    pub async fn gather<I, S>(keys: I) -> Result<Self, EoError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        let mut ops = BTreeMap::new();
        for key in keys {
            let key = key.as_ref();
            if let Some(inst) = registry::lookup(ModuleKind::Operation, key)
                .into_iter()
                .next()
            {
                ops.insert(
                    key.to_string(),
                    describe(EoClient::from_cell(inst.actor)).await?,
                );
            }
        }
        let names = running_names();
        Ok(RegistryCatalog {
            ops,
            names,
            unfit: BTreeMap::new(),
            examined: BTreeMap::new(),
        })
    }

    /// The operations that run but have no instance fitting the mission
    /// ([`RegistryCatalog::for_mission`]), each with every candidate's reason.
    pub fn unfit(&self) -> &BTreeMap<String, String> {
        &self.unfit
    }

    /// The operations [`RegistryCatalog::for_mission`] asked for that no instance answered
    /// for, each with how many the registry listed (0: none runs, or this member has not
    /// heard of it yet; more: listed, but silent — a remote module of a session that just
    /// ended, or one that did not answer in time).
    pub fn unanswered(&self) -> BTreeMap<String, usize> {
        self.examined
            .iter()
            .filter(|(_, e)| e.found.is_empty())
            .map(|(key, e)| (key.clone(), e.seen.len()))
            .collect()
    }
}

impl RegistryCatalog {
    /// Ask the registry about every operation `mission` uses, describing each with the
    /// instance selection would choose for it ([`crate::dispatcher::selection`]: every live
    /// instance asked, the best fit for what the mission supplies and requires) — so that
    /// a mission is validated against the instance that will run it. When none fits, the
    /// first instance is described, and validation names what it refuses.
    ///
    /// The mission validated against this catalog carries the choices made here to its
    /// dispatcher ([`Mission::checked`]), which binds them without asking every instance
    /// again unless one changed since ([`CheckedChoices`]).
    pub async fn for_mission(mission: &ParsedMission) -> Result<Self, EoError> {
        let mut ops = BTreeMap::new();
        let mut unfit = BTreeMap::new();
        let mut examined = BTreeMap::new();
        for key in mission.ops() {
            let (found, choice) = select(&mission.need(key), EoClient::DEFAULT_TIMEOUT).await;
            if !found.found.is_empty() && choice.chosen_index().is_none() {
                unfit.insert(key.to_string(), choice.why_none());
            }
            let pick = choice.chosen_index().unwrap_or(0);
            if let Some(cand) = found.found.get(pick) {
                ops.insert(key.to_string(), cand.info.clone());
            }
            examined.insert(key.to_string(), found);
        }
        let names = running_names();
        Ok(RegistryCatalog {
            ops,
            names,
            unfit,
            examined,
        })
    }
}

/// The names of the operations running now, for "available: ..." hints.
fn running_names() -> Vec<String> {
    let mut names: Vec<String> = registry::list()
        .into_iter()
        .filter(|i| i.kind == ModuleKind::Operation)
        .map(|i| i.name)
        .collect();
    names.dedup();
    names
}

impl Catalog for RegistryCatalog {
    fn operation(&self, key: &str) -> Option<OpInfo> {
        self.ops.get(key).cloned()
    }

    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    fn checked(&self, mission: &Mission) -> CheckedChoices {
        CheckedChoices::gather(mission.operation_needs(), &self.examined)
    }
}

//! Bindings: the dispatcher's hold on an operation, across failures of its instances.
//!
//! A restart makes a new actor, so the dispatcher never keeps a raw `ActorRef` as "the
//! operation". It keeps a [`Binding`]: the operation's logical name, what an
//! instance must be to stand in for it (same id, a semver-compatible version, a parameter
//! schema that accepts the parameters the mission gave), the current incarnation and the
//! binding's epoch. When the incarnation dies the binding is *lost*; a live instance that
//! passes the same selection is *adopted* and gets the last parameters back.
//!
//! # Invariants
//! - Commands carry the binding's epoch, and adopting an instance raises the epoch above both
//!   the binding's and the one the instance accepted last, so the dispatcher's commands are
//!   never ignored as stale and an older dispatcher's are.
//! - The incarnation number grows with every loss: reports and probe results that carry an
//!   older number are about an instance the dispatcher has let go of, and are ignored.

use super::candidates::Prospect;
use super::mission::op_info::OpInfo;
use super::selection::{self, Need, Offer};
use crate::eo::EoClient;
use marie_vocabulary::clock::Timer;
use marie_vocabulary::property::ParamMap;
use marie_vocabulary::run::LossCause;
use ractor::ActorId;
use semver::VersionReq;
use std::time::Duration;

/// Why a binding's instance was let go.
#[derive(Clone, Debug)]
pub(crate) struct Lost {
    /// Clock time of the loss.
    pub(crate) since: Duration,
    /// What happened, for the report.
    pub(crate) cause: LossCause,
    /// Address of the instance that was lost.
    pub(crate) from: String,
    /// The node it ran on.
    pub(crate) from_node: String,
    /// Its actor id, never to be adopted again.
    pub(crate) dead: ActorId,
    /// Why instances that showed up since could not stand in, by address.
    pub(crate) refused: Vec<(String, String)>,
}

/// A move to a newer version on trial: the binding moved at the start of action
/// `generation` and its new instance has not reported that first activation yet. If it
/// fails, the binding may go back to the instance it moved from ([`super::upgrade`]).
#[derive(Clone, Debug)]
pub(crate) struct Trial {
    /// The action whose start moved the binding (its generation number).
    pub(crate) generation: u64,
    /// Its name, for the rollback's record.
    pub(crate) action: String,
    /// The instance the binding moved from.
    pub(crate) from: ActorId,
    /// Its declared deadline: how long it may take to answer whether it still lives.
    pub(crate) from_deadline: Duration,
}

/// The dispatcher's hold on one operation.
pub(crate) struct Binding {
    pub(crate) client: EoClient,
    pub(crate) name: String,
    pub(crate) id: u32,
    pub(crate) version: String,
    pub(crate) node: String,
    pub(crate) epoch: u64,
    /// Grows with every loss; see the module invariants.
    pub(crate) incarnation: u64,
    pub(crate) defaults: ParamMap,
    /// The instance's parameter declarations and migrations: what the mission supplies
    /// reaches it as [`Binding::supplied`] maps it.
    pub(crate) info: OpInfo,
    pub(crate) flag_names: Vec<String>,
    /// The parameters sent last (restored on a new instance).
    pub(crate) params: ParamMap,
    /// How long the instance may take to answer (its declared deadline).
    pub(crate) deadline: Duration,
    /// Set while the instance is gone and no stand-in has been adopted.
    pub(crate) lost: Option<Lost>,
    /// When the instance last showed it was alive (answered a probe, was adopted); a hung
    /// instance's downtime counts from here, not from when its deadline ran out.
    pub(crate) last_alive: Option<Duration>,
    /// The rebind deadline's timer while lost; dropped (cancelled) when a stand-in is
    /// adopted, so a run with many failovers does not keep a sleeping task per loss.
    pub(crate) deadline_timer: Option<Timer>,
    /// The provisioning grace's timer while lost (see `healing`).
    pub(crate) provision_timer: Option<Timer>,
    /// A liveness probe is under way.
    pub(crate) probing: bool,
    /// An instance of a newer compatible version that appeared while this one lives: the
    /// binding moves to it at the next action's start that uses the operation
    /// ([`super::upgrade`]); forgotten if it leaves the registry first.
    pub(crate) due: Option<Prospect>,
    /// When the current instance last reported the end of its part of an action, in ms
    /// since the run began (an upgrade's record carries it).
    pub(crate) last_report_ms: Option<u64>,
    /// Set from a move to a newer version until the new instance's first activation
    /// reports (see [`Trial`]).
    pub(crate) trial: Option<Trial>,
    /// The instances the binding rolled back from, with why: never taken to again in this
    /// run, neither as an upgrade nor as a stand-in.
    pub(crate) spurned: Vec<(ActorId, String)>,
    /// What the mission needs of the operation: a stand-in must meet it, as the first
    /// instance did (see [`super::selection`]).
    need: Need,
}

impl Binding {
    /// Bind to `cand`, chosen for `need`, at an epoch above both its own and `base`.
    pub(crate) fn new(cand: Prospect, base: u64, mut need: Need) -> Binding {
        pin_by_node(&mut need, &cand);
        Binding {
            client: cand.client,
            name: cand.info.name.clone(),
            id: cand.info.id,
            version: cand.info.version.clone(),
            node: cand.node,
            epoch: (cand.epoch + 1).max(base),
            incarnation: 0,
            defaults: cand.info.schema.defaults(),
            flag_names: cand.info.flags.iter().map(|f| f.name.clone()).collect(),
            info: cand.info,
            params: ParamMap::new(),
            deadline: cand.deadline,
            lost: None,
            last_alive: None,
            deadline_timer: None,
            provision_timer: None,
            probing: false,
            due: None,
            last_report_ms: None,
            trial: None,
            spurned: Vec::new(),
            need,
        }
    }

    /// The parameters an action sends the instance for what the mission `supplied`: its
    /// declared defaults, then the mission's values as its migrations map them (see
    /// [`crate::declare::Migrations`]) — so values left by an earlier action never leak.
    pub(crate) fn supplied(&self, supplied: &ParamMap) -> ParamMap {
        let mut params = self.defaults.clone();
        params.extend(self.info.migrated(supplied));
        params
    }

    /// What the mission needs of the operation.
    pub(crate) fn need(&self) -> &Need {
        &self.need
    }

    /// The versions a stand-in may have (the mission's requirement; any without one).
    pub(crate) fn versions(&self) -> VersionReq {
        self.need.version.clone().unwrap_or(VersionReq::STAR)
    }

    /// Choose a stand-in for the lost instance among `cands` as the mission's start chose
    /// ([`selection::choose`] on the binding's need), after ruling out what cannot stand in
    /// whatever the mission needs: the lost actor itself, an instance on a node declared
    /// down, another operation's. Gives the explanation (every candidate with its verdict,
    /// [`Choice::replacing`](marie_vocabulary::run::Choice::replacing) the lost address) and the index
    /// of the chosen one in `cands`.
    pub(crate) fn choose_stand_in(
        &self,
        cands: &[Prospect],
        here: &str,
    ) -> (marie_vocabulary::run::Choice, Option<usize>) {
        let (mut fit, mut ruled_out) = (Vec::new(), Vec::new());
        for (i, cand) in cands.iter().enumerate() {
            match self.cannot_stand_in(cand) {
                Some(why) => ruled_out.push((i, why)),
                None => fit.push(i),
            }
        }
        let offers: Vec<Offer> = fit.iter().map(|&i| cands[i].offer()).collect();
        let mut choice = selection::choose(&self.need, &offers, here);
        let chosen = choice.chosen_index().map(|k| fit[k]);
        for (i, reason) in ruled_out {
            let verdict = marie_vocabulary::run::Verdict::Rejected { reason };
            choice.candidates.push(cands[i].offer().candidate(verdict));
        }
        choice.replacing = self.lost.as_ref().map(|l| l.from.clone());
        (choice, chosen)
    }

    /// Why the instance `actor` on `node` cannot stand in, known before asking it anything:
    /// it is the lost one, or its node was declared down (it may linger in the registry a
    /// moment after).
    pub(crate) fn ruled_out_unasked(&self, actor: ActorId, node: &str) -> Option<String> {
        if self.lost.as_ref().is_some_and(|lost| actor == lost.dead) {
            return Some("it is the instance that was lost".to_string());
        }
        if marie_vocabulary::registry::is_declared_down(node) {
            return Some(format!("its node {node} was declared down"));
        }
        None
    }

    /// Why the binding rolled back from instance `actor` earlier in the run, if it did.
    pub(crate) fn spurned(&self, actor: ActorId) -> Option<&str> {
        self.spurned
            .iter()
            .find(|(id, _)| *id == actor)
            .map(|(_, why)| why.as_str())
    }

    /// Why `cand` cannot stand in for this binding whatever the mission needs, if it cannot.
    fn cannot_stand_in(&self, cand: &Prospect) -> Option<String> {
        if let Some(why) = self.ruled_out_unasked(cand.client.actor().get_id(), &cand.node) {
            return Some(why);
        }
        if let Some(why) = self.spurned(cand.client.actor().get_id()) {
            return Some(format!(
                "the binding rolled back from it earlier in this run: {why}"
            ));
        }
        if cand.info.name != self.name || cand.info.id != self.id {
            return Some(format!(
                "it is {} ({}), not {} ({})",
                cand.info.name, cand.info.id, self.name, self.id
            ));
        }
        None
    }

    /// Take `cand` as the new incarnation; returns the record's `(from, downtime)` if the
    /// binding was lost.
    pub(crate) fn adopt(&mut self, cand: Prospect, now: Duration) -> Option<(Lost, Duration)> {
        pin_by_node(&mut self.need, &cand);
        self.epoch = self.epoch.max(cand.epoch) + 1;
        self.client = cand.client;
        self.version = cand.info.version.clone();
        self.node = cand.node;
        self.defaults = cand.info.schema.defaults();
        self.flag_names = cand.info.flags.iter().map(|f| f.name.clone()).collect();
        self.info = cand.info;
        self.deadline = cand.deadline;
        self.probing = false;
        self.deadline_timer = None;
        self.provision_timer = None;
        self.last_alive = Some(now);
        self.last_report_ms = None;
        if self
            .due
            .as_ref()
            .is_some_and(|d| d.client.actor().get_id() == self.client.actor().get_id())
        {
            self.due = None; // the rebind took the newer instance itself
        }
        self.lost
            .take()
            .map(|lost| (lost.clone(), now.saturating_sub(lost.since)))
    }

    /// The current instance's actor.
    pub(crate) fn actor_id(&self) -> ActorId {
        self.client.actor().get_id()
    }

    /// The current instance's address, as reports show it.
    pub(crate) fn address(&self) -> String {
        self.actor_id().to_string()
    }

    /// Let the current instance go. Its downtime starts `now` — or, for a hung instance
    /// (found out only when its deadline ran out), at its last sign of life.
    pub(crate) fn lose(&mut self, cause: LossCause, now: Duration) {
        let since = match cause {
            LossCause::Hung { .. } => self.last_alive.map_or(now, |t| t.min(now)),
            _ => now,
        };
        self.incarnation += 1;
        self.probing = false;
        self.trial = None;
        self.lost = Some(Lost {
            since,
            cause,
            from: self.address(),
            from_node: self.node.clone(),
            dead: self.actor_id(),
            refused: Vec::new(),
        });
    }
}

/// If `cand`'s node pins it (`pin = true` on its `[[operation]]`) and nothing pins the
/// binding yet, the binding runs on `cand`'s exact version for the rest of the mission
/// ([`Need::node_pin`]; the mission's own pin, if any, wins).
fn pin_by_node(need: &mut Need, cand: &Prospect) {
    if !cand.info.pinned || need.pin_in_force().is_some() {
        return;
    }
    match VersionReq::parse(&format!("={}", cand.info.version)) {
        Ok(req) => need.node_pin = Some((req, cand.node.clone())),
        Err(e) => {
            tracing::warn!(op = %cand.info.name, version = %cand.info.version, error = %e, "a node pins a version that is not semver: not pinned")
        }
    }
}

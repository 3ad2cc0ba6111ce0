//! Candidates: the live instances of an operation, asked through their property interface
//! what they are (identity, parameter schema, flags, epoch, deadline, in use, up-time), and
//! the selection among them — what binding, surveying, healing and validating a mission all
//! start from.

use super::mission::op_info::OpInfo;
use super::selection::{self, Need, Offer};
use crate::declare::Migrations;
use crate::eo::PINNED;
use crate::eo::{EoClient, EoError};
use marie_vocabulary::property::{General, Group, PropertyReply, PropertyRequest, Value};
use marie_vocabulary::registry::Instance;
use ractor::ActorId;
use std::time::Duration;

/// Describe one operation through its property interface.
pub async fn describe(client: EoClient) -> Result<OpInfo, EoError> {
    let ident = client
        .property(PropertyRequest::Group(Group::Identification))
        .await?;
    let specific = client
        .property(PropertyRequest::Group(Group::Specific))
        .await?;
    // a build before migrations answers NotFound: it declares none
    let migrations = match client
        .property(PropertyRequest::Get(Migrations::PROPERTY.to_string()))
        .await?
    {
        PropertyReply::Value(v) => Migrations::from_value(&v).unwrap_or_else(|e| {
            tracing::warn!(actor = %client.actor().get_id(), error = %e, "migrations unreadable: taken as none");
            Migrations::default()
        }),
        _ => Migrations::default(),
    };
    let pinned = matches!(
        client
            .property(PropertyRequest::Get(PINNED.to_string()))
            .await?,
        PropertyReply::Value(Value::Bool(true))
    );
    match (ident, specific) {
        (PropertyReply::Identification(i), PropertyReply::Specific(s)) => Ok(OpInfo {
            name: i.name.to_string(),
            id: i.id,
            version: i.version.to_string(),
            schema: marie_vocabulary::property::ParamSchema::new(s.params),
            flags: s.flags,
            migrations,
            pinned,
        }),
        _ => Err(EoError::Gone(client.actor().get_id().to_string())),
    }
}

/// A live instance the dispatcher looked at through its property interface.
#[derive(Clone, Debug)]
pub(crate) struct Prospect {
    pub(crate) info: OpInfo,
    pub(crate) client: EoClient,
    pub(crate) node: String,
    /// The epoch the instance accepted last.
    pub(crate) epoch: u64,
    /// How long it may take to answer a command.
    pub(crate) deadline: Duration,
    /// Bound by another binding.
    pub(crate) in_use: bool,
    /// How long it has run, ms.
    pub(crate) uptime_ms: u64,
}

impl Prospect {
    /// The candidate as selection sees it.
    pub(crate) fn offer(&self) -> Offer {
        Offer {
            address: self.client.actor().get_id().to_string(),
            node: self.node.clone(),
            info: self.info.clone(),
            in_use: self.in_use,
            uptime_ms: self.uptime_ms,
        }
    }

    /// The candidate with what its general group says now: the epoch it accepted last,
    /// its deadline, whether it is in use, its up-time.
    pub(crate) fn refreshed(mut self, general: &General) -> Prospect {
        self.epoch = general.epoch;
        self.deadline = Duration::from_millis(general.deadline_ms.max(1));
        self.in_use = general.in_use;
        self.uptime_ms = general.uptime_ms;
        self
    }
}

/// Why an instance could not be looked at: it did not answer, or answered out of turn.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum ExamineError {
    /// It did not answer within the time given, or is gone.
    #[error(transparent)]
    Unreachable(#[from] EoError),
    /// It answered a group request with something else.
    #[error("answered {answer:?} to the {group:?} group")]
    Answer {
        /// The group asked.
        group: Group,
        /// What came back.
        answer: Box<PropertyReply>,
    },
}

/// Ask `client` for its general group: epoch, deadline, in use, up-time.
pub(crate) async fn general(client: &EoClient) -> Result<General, ExamineError> {
    match client
        .property(PropertyRequest::Group(Group::General))
        .await?
    {
        PropertyReply::General(g) => Ok(g),
        other => Err(ExamineError::Answer {
            group: Group::General,
            answer: Box::new(other),
        }),
    }
}

/// Ask `inst` who it is, what it takes and which epoch it is at; `timeout` bounds each request.
pub(crate) async fn examine(inst: &Instance, timeout: Duration) -> Result<Prospect, ExamineError> {
    let client = EoClient::from_cell(inst.actor.clone()).with_timeout(timeout);
    let info = describe(client.clone()).await?;
    let general = general(&client).await?;
    let cand = Prospect {
        info,
        client: client.with_timeout(EoClient::DEFAULT_TIMEOUT),
        node: inst.node.clone(),
        epoch: 0,
        deadline: Duration::ZERO,
        in_use: false,
        uptime_ms: 0,
    };
    Ok(cand.refreshed(&general))
}

/// The instances of an operation found in the registry, and those of them that answered.
#[derive(Clone, Debug, Default)]
pub(crate) struct Examined {
    /// Every instance the registry listed, answered or not.
    pub(crate) seen: Vec<ActorId>,
    /// The instances that answered, in registry order.
    pub(crate) found: Vec<Prospect>,
}

/// Every live instance of `operation`, asked at once (selection needs them all), in
/// registry order; those that do not answer within `timeout` are left out of `found`.
pub(crate) async fn candidates(operation: &str, timeout: Duration) -> Examined {
    let listed = marie_vocabulary::registry::lookup(
        marie_vocabulary::registry::ModuleKind::Operation,
        operation,
    );
    let seen = listed.iter().map(Instance::actor_id).collect();
    let found = examine_all(operation, listed, timeout).await;
    Examined { seen, found }
}

/// Every live instance of the operation `need` names, asked at once, and the choice among
/// them for `need` on this node — what binding, surveying and validating a mission share,
/// so the instance a mission is checked against is the one it binds.
pub(crate) async fn select(
    need: &Need,
    timeout: Duration,
) -> (Examined, marie_vocabulary::run::Choice) {
    let examined = candidates(&need.operation, timeout).await;
    let choice = choose(need, &examined.found);
    (examined, choice)
}

/// The choice among `found` for `need` on this node.
pub(crate) fn choose(need: &Need, found: &[Prospect]) -> marie_vocabulary::run::Choice {
    let offers: Vec<Offer> = found.iter().map(Prospect::offer).collect();
    selection::choose(
        need,
        &offers,
        &marie_vocabulary::registry::local_node_name(),
    )
}

/// Every instance of `found` (of `operation`), asked at once, in the given order; those
/// that do not answer within `timeout` are left out.
pub(crate) async fn examine_all(
    operation: &str,
    found: Vec<Instance>,
    timeout: Duration,
) -> Vec<Prospect> {
    let mut asked = tokio::task::JoinSet::new();
    for (i, inst) in found.into_iter().enumerate() {
        asked.spawn(async move { (i, examine(&inst, timeout).await) });
    }
    let mut answers = Vec::new();
    while let Some(joined) = asked.join_next().await {
        match joined {
            Ok((i, Ok(cand))) => answers.push((i, cand)),
            Ok((_, Err(e))) => {
                tracing::debug!(op = %operation, error = %e, "a candidate does not answer")
            }
            Err(e) => tracing::debug!(op = %operation, error = %e, "asking a candidate failed"),
        }
    }
    answers.sort_by_key(|(i, _)| *i);
    answers.into_iter().map(|(_, c)| c).collect()
}

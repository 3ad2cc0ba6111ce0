//! The check of a mission against the newer versions of its operations: a newer compatible
//! version whose parameters the mission's could not become (a renamed parameter without a
//! declared migration, a value outside a changed range) would leave a binding on its old
//! version mid-mission without a word until the run says so — `marie check` refuses the
//! mission instead, before anything runs ([`upgrade::parameters_refused`]).
//!
//! Which versions the check knows:
//! - the declarations this build knows — every operation factory of its catalogue, newer
//!   versions hosted nowhere yet included (`known`, built from
//!   [`OperationFactory::declared`](crate::eo::OperationFactory::declared));
//! - the instances the registry offers: the check's own node's, or, when it checks against
//!   a joined cluster, every node's — a newer build's versions the checking binary does not
//!   have among them (each asked through its property interface, migrations included).
//!
//! Each is judged against the version the mission would bind now (the selection's choice).

use super::candidates::select;
use super::mission::op_info::OpInfo;
use super::mission::Mission;
use super::upgrade;
use crate::eo::EoClient;
use serde::Serialize;

/// A newer compatible version of an operation that could not take the mission's parameters.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UpgradeRefusal {
    /// The operation.
    pub operation: String,
    /// The version the mission would bind now.
    pub current: String,
    /// The newer version.
    pub newer: String,
    /// Where the check knows it from: `this build`, or an instance's address and node.
    pub known_from: String,
    /// Why it could not take the mission's parameters.
    pub reason: String,
}

impl std::fmt::Display for UpgradeRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "operation `{}`: version {} (known from {}) could not take over from {} mid-mission: {} \
             (declare a migration in that version, change the parameter, or pin the operation: \
             [pin] {} = \"{}\")",
            self.operation,
            self.newer,
            self.known_from,
            self.current,
            self.reason,
            self.operation,
            self.current
        )
    }
}

/// Every newer compatible version of `mission`'s operations — among `known` (this build's
/// declarations) and the live instances in the registry — that could not take the
/// mission's parameters, against the version each operation would be bound to now.
pub async fn refusing_versions(mission: &Mission, known: &[OpInfo]) -> Vec<UpgradeRefusal> {
    let mut out = Vec::new();
    for name in mission.operation_names() {
        let need = mission.need(name);
        let (examined, choice) = select(&need, EoClient::DEFAULT_TIMEOUT).await;
        let Some(index) = choice.chosen_index() else {
            continue; // no instance fits: the mission's validation says so
        };
        let current = examined.found[index].info.version.clone();
        let offered = examined.found.iter().map(|p| {
            let from = format!("{} on {}", p.client.actor().get_id(), p.node);
            (&p.info, from)
        });
        let built = known
            .iter()
            .filter(|i| i.name == need.operation)
            .map(|i| (i, "this build".to_string()));
        let mut seen = std::collections::BTreeSet::new();
        for (info, known_from) in built.chain(offered) {
            if !seen.insert(info.version.clone()) {
                continue; // one line per version
            }
            if let Some(reason) = upgrade::parameters_refused(&current, &need, info) {
                out.push(UpgradeRefusal {
                    operation: need.operation.clone(),
                    current: current.clone(),
                    newer: info.version.clone(),
                    known_from,
                    reason,
                });
            }
        }
    }
    out
}

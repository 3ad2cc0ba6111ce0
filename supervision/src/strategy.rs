//! Restart strategies: which children restart together when one of them has to be restarted.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Which children a supervisor restarts when one child must be restarted (OTP's strategies).
/// Children keep their position in the start order across restarts, so "after" below always
/// means "started later".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// Only the child that stopped: the children are independent.
    #[default]
    OneForOne,
    /// All children: stop the others in reverse start order, then start all in order. For
    /// children that cannot work without each other.
    OneForAll,
    /// The child and every child started after it: later children depend on earlier ones.
    RestForOne,
    /// One-for-one over instances of a single [`crate::ChildTemplate`], all started at run
    /// time with an argument each ([`crate::SupervisorRef::start_dynamic`]); see
    /// [`crate::SupervisorSpec::simple_one_for_one`].
    SimpleOneForOne,
}

impl Strategy {
    /// The keys, in start order, of the children restarted together with `failed`, given all
    /// children keyed by their position in the start order.
    pub(crate) fn scope<V>(self, children: &BTreeMap<u64, V>, failed: u64) -> Vec<u64> {
        match self {
            Strategy::OneForOne | Strategy::SimpleOneForOne => vec![failed],
            Strategy::OneForAll => children.keys().copied().collect(),
            Strategy::RestForOne => children.range(failed..).map(|(k, _)| *k).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scopes() {
        let children: BTreeMap<u64, ()> = [1, 3, 5, 8].into_iter().map(|k| (k, ())).collect();
        assert_eq!(Strategy::OneForOne.scope(&children, 3), vec![3]);
        assert_eq!(Strategy::SimpleOneForOne.scope(&children, 3), vec![3]);
        assert_eq!(Strategy::OneForAll.scope(&children, 3), vec![1, 3, 5, 8]);
        assert_eq!(Strategy::RestForOne.scope(&children, 3), vec![3, 5, 8]);
        assert_eq!(Strategy::RestForOne.scope(&children, 8), vec![8]);
    }
}

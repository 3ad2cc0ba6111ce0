//! Choosing an instance of an operation by its properties — the self-configuration the
//! thesis designed the property interface for.
//!
//! Every live instance of an operation the mission needs is an [`Offer`]: its identity and
//! parameter schema (asked through the property interface), its node, whether it is in use,
//! its up-time. [`choose`] first rejects the instances the mission cannot use — a schema
//! that refuses a parameter the mission supplies (an unknown name, a wrong type, a value out
//! of range), a version outside the mission's requirement — then ranks the rest, in order:
//!
//! 1. the schema that fits the supplied parameters best: exactly (it declares nothing the
//!    mission leaves unsupplied) before a compatible superset, and a smaller superset
//!    before a larger one;
//! 2. not in use by another binding;
//! 3. on this node before another;
//! 4. the longer up-time.
//!
//! Every other candidate gets the reason it lost or was rejected ([`Verdict`]). The same
//! test ([`admits`]) decides whether a stand-in may replace a lost instance, so a rebind
//! never takes an instance the mission could not have chosen at the start.
//!
//! ```
//! use marie_actors::dispatcher::mission::OpInfo;
//! use marie_actors::dispatcher::selection::{choose, Need, Offer};
//! use marie_vocabulary::run::Verdict;
//! use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
//!
//! let v1 = OpInfo::new("wall-follower", 1514, "1.0.0")
//!     .params(ParamSchema::new(vec![ParamDecl::float("distance", 0.6)]));
//! let v2 = OpInfo::new("wall-follower", 1514, "2.0.0").params(ParamSchema::new(vec![
//!     ParamDecl::float("distance", 0.6),
//!     ParamDecl::choice("mode", &["wall", "corridor"], "wall"),
//! ]));
//! let offers = [Offer::new("0.1", "n1", v1), Offer::new("0.2", "n1", v2)];
//! // a mission that supplies only the distance gets version 1 ...
//! let need = Need::new("wall-follower").supplies([("distance", Value::Float(0.7))]);
//! assert_eq!(choose(&need, &offers, "n1").chosen().unwrap().version, "1.0.0");
//! // ... one that also supplies the mode gets version 2
//! let need = need.supplies([("mode", Value::Text("corridor".into()))]);
//! let choice = choose(&need, &offers, "n1");
//! assert_eq!(choice.chosen().unwrap().version, "2.0.0");
//! assert!(matches!(choice.candidates[0].verdict, Verdict::Rejected { .. }));
//! ```

use super::mission::op_info::OpInfo;
use marie_vocabulary::property::{ParamMap, Rejection, Value};
use marie_vocabulary::run::{Candidate, Choice, Verdict};
use semver::{Version, VersionReq};
use std::cmp::Ordering;
use std::collections::BTreeSet;

/// Who pinned an operation's version ([`Need::pin_in_force`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PinnedBy<'a> {
    /// The mission's `[pin]` table.
    Mission,
    /// The node config of the bound instance (`pin = true` on its `[[operation]]`): that
    /// node.
    Node(&'a str),
}

impl std::fmt::Display for PinnedBy<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PinnedBy::Mission => write!(f, "the mission"),
            PinnedBy::Node(node) => write!(f, "node {node}'s config"),
        }
    }
}

/// What a mission needs of one operation.
#[derive(Clone, Debug, PartialEq)]
pub struct Need {
    /// The operation's name (or id), as the mission names it.
    pub operation: String,
    /// The parameters the mission supplies to it, one set per action that runs it.
    pub supplied: Vec<ParamMap>,
    /// The versions the mission accepts (`None`: any).
    pub version: Option<VersionReq>,
    /// The versions the mission pins the operation to (`[pin]`; `None`: not pinned): an
    /// instance must match it as it must match `version`, and a binding never moves to a
    /// newer version (see [`super::upgrade`]).
    pub pin: Option<VersionReq>,
    /// The version the node config of the bound instance pins the operation to (its
    /// `[[operation]]`'s `pin = true`), and that node: set on a binding once it is bound
    /// to a pinning node's instance, for the rest of the mission. It acts as the mission's
    /// pin does — stand-ins must match it, the binding never moves to a newer version —
    /// unless the mission pins the operation itself: then the mission's pin alone counts
    /// (the mission's author wrote it for this run and these parameters; a node's pin is a
    /// standing default for whatever runs there).
    pub node_pin: Option<(VersionReq, String)>,
}

impl Need {
    /// A need of `operation` with nothing supplied and any version.
    pub fn new(operation: impl Into<String>) -> Self {
        Need {
            operation: operation.into(),
            supplied: Vec::new(),
            version: None,
            pin: None,
            node_pin: None,
        }
    }

    /// Also supply these parameters (in one more action's set).
    pub fn supplies<'a>(mut self, params: impl IntoIterator<Item = (&'a str, Value)>) -> Self {
        let mut map = ParamMap::new();
        for (k, v) in params {
            map.insert(k.to_string(), v);
        }
        // one set per call, merged into the first for the common one-action case
        match self.supplied.first_mut() {
            Some(first) => first.extend(map),
            None => self.supplied.push(map),
        }
        self
    }

    /// The pin in force: the mission's, else the node's — and who set it.
    pub fn pin_in_force(&self) -> Option<(&VersionReq, PinnedBy<'_>)> {
        match (&self.pin, &self.node_pin) {
            (Some(pin), _) => Some((pin, PinnedBy::Mission)),
            (None, Some((pin, node))) => Some((pin, PinnedBy::Node(node))),
            (None, None) => None,
        }
    }

    /// Pin the operation to the versions matching `req` for the whole mission.
    pub fn pinned(mut self, req: VersionReq) -> Self {
        self.pin = Some(req);
        self
    }

    /// Accept only versions matching `req`.
    pub fn version(mut self, req: VersionReq) -> Self {
        self.version = Some(req);
        self
    }

    /// Every parameter name supplied in any action.
    pub fn names(&self) -> BTreeSet<&str> {
        self.supplied
            .iter()
            .flat_map(|m| m.keys().map(String::as_str))
            .collect()
    }
}

/// A live instance, as its properties describe it.
#[derive(Clone, Debug, PartialEq)]
pub struct Offer {
    /// Its actor's address.
    pub address: String,
    /// Its node.
    pub node: String,
    /// Identity, version, schema, flags.
    pub info: OpInfo,
    /// Bound by another dispatcher's binding.
    pub in_use: bool,
    /// How long it has run, ms.
    pub uptime_ms: u64,
}

impl Offer {
    /// An instance not in use, just started.
    pub fn new(address: impl Into<String>, node: impl Into<String>, info: OpInfo) -> Self {
        Offer {
            address: address.into(),
            node: node.into(),
            info,
            in_use: false,
            uptime_ms: 0,
        }
    }
}

impl Offer {
    /// The offer as a choice shows it, with `verdict`.
    pub fn candidate(&self, verdict: Verdict) -> Candidate {
        Candidate {
            address: self.address.clone(),
            node: self.node.clone(),
            version: self.info.version.clone(),
            schema: self
                .info
                .schema
                .params
                .iter()
                .map(|d| d.name.clone())
                .collect(),
            flags: self.info.flags.iter().map(|f| f.name.clone()).collect(),
            verdict,
        }
    }
}

/// Why the mission cannot use an instance: what [`admits`] finds, and what a candidate's
/// [`Verdict::Rejected`] says in words (the same words the check and the report show).
#[derive(Debug, thiserror::Error)]
pub enum Inadmissible {
    /// The instance's version is not a semantic version, so no requirement can match it.
    #[error("its version `{version}` is not semver: {error}")]
    NotSemver {
        /// The version as the instance declares it.
        version: String,
        /// Why it does not parse.
        error: semver::Error,
    },
    /// The instance's version is outside the mission's `[requires]`.
    #[error("its version {version} does not match the mission's requirement {required}")]
    Version {
        /// The instance's version.
        version: Version,
        /// What the mission requires.
        required: VersionReq,
    },
    /// The instance's version is outside the versions the mission (or the bound instance's
    /// node config) pins the operation to.
    #[error("its version {version} does not match {whose} {pin}")]
    Pinned {
        /// The instance's version.
        version: Version,
        /// The pin.
        pin: VersionReq,
        /// Whose pin: `the mission's pin`, or `the pin of node NAME's config`.
        whose: String,
    },
    /// The instance's schema refuses a parameter the mission supplies (an unknown name, a
    /// wrong type, a value out of range).
    #[error("its schema refuses what the mission supplies: {}", list(.rejections))]
    Schema {
        /// Every value refused, with why.
        rejections: Vec<Rejection>,
    },
}

/// Rejections joined as one sentence.
fn list(rejections: &[Rejection]) -> String {
    let list: Vec<String> = rejections.iter().map(Rejection::to_string).collect();
    list.join("; ")
}

/// Whether the mission can use an instance described by `info`: the version it requires,
/// and every parameter it supplies accepted by the schema (names, types, ranges). What
/// stands in the way when not.
pub fn admits(need: &Need, info: &OpInfo) -> Result<(), Inadmissible> {
    if let Some(req) = &need.version {
        let version = Version::parse(&info.version).map_err(|error| Inadmissible::NotSemver {
            version: info.version.clone(),
            error,
        })?;
        if !req.matches(&version) {
            return Err(Inadmissible::Version {
                version,
                required: req.clone(),
            });
        }
    }
    if let Some((pin, by)) = need.pin_in_force() {
        let version = Version::parse(&info.version).map_err(|error| Inadmissible::NotSemver {
            version: info.version.clone(),
            error,
        })?;
        if !pin.matches(&version) {
            return Err(Inadmissible::Pinned {
                version,
                pin: pin.clone(),
                whose: match by {
                    PinnedBy::Mission => "the mission's pin".to_string(),
                    PinnedBy::Node(_) => format!("the pin of {by}"),
                },
            });
        }
    }
    let defaults = info.schema.defaults();
    for supplied in &need.supplied {
        // written for an older version perhaps: as the instance's migrations map it
        if let Err(rejections) = info
            .schema
            .apply(&defaults, &info.migrated(supplied), false)
        {
            return Err(Inadmissible::Schema { rejections });
        }
    }
    Ok(())
}

/// The parameters `info` declares that the mission does not supply: none for an exact fit.
fn unsupplied<'a>(need: &Need, info: &'a OpInfo) -> Vec<&'a str> {
    let names = need.names();
    info.schema
        .params
        .iter()
        .map(|d| d.name.as_str())
        .filter(|n| !names.contains(n))
        .collect()
}

/// Choose among `offers` for `need`, preferring instances on node `here`; see the module
/// docs for the order.
pub fn choose(need: &Need, offers: &[Offer], here: &str) -> Choice {
    let admitted: Vec<Result<(), Inadmissible>> =
        offers.iter().map(|o| admits(need, &o.info)).collect();
    let key = |o: &Offer| (unsupplied(need, &o.info).len(), o.in_use, o.node != here);
    let better = |a: &Offer, b: &Offer| -> Ordering {
        key(a)
            .cmp(&key(b))
            .then_with(|| b.uptime_ms.cmp(&a.uptime_ms))
    };
    let best = (0..offers.len())
        .filter(|&i| admitted[i].is_ok())
        .min_by(|&a, &b| better(&offers[a], &offers[b]).then(a.cmp(&b)));
    let candidates = offers
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let verdict = match (&admitted[i], best) {
                (Err(why), _) => Verdict::Rejected {
                    reason: why.to_string(),
                },
                (Ok(()), Some(b)) if b == i => Verdict::Chosen,
                (Ok(()), Some(b)) => Verdict::Lost {
                    reason: why_lost(need, o, &offers[b], here),
                },
                (Ok(()), None) => unreachable!("an admitted offer makes a best one"),
            };
            o.candidate(verdict)
        })
        .collect();
    Choice {
        operation: need.operation.clone(),
        candidates,
        replacing: None,
    }
}

/// Why `loser` ranked below `winner`: the first criterion that told them apart.
fn why_lost(need: &Need, loser: &Offer, winner: &Offer, here: &str) -> String {
    let (l, w) = (
        unsupplied(need, &loser.info),
        unsupplied(need, &winner.info),
    );
    if l.len() != w.len() {
        let fit = if w.is_empty() {
            "fits exactly".to_string()
        } else {
            format!("declares {} unsupplied", w.len())
        };
        return format!(
            "its schema also declares {} the mission does not supply; {} (version {}) {fit}",
            l.join(", "),
            winner.address,
            winner.info.version
        );
    }
    if loser.in_use != winner.in_use {
        return "it is in use by another binding".to_string();
    }
    if (loser.node == here) != (winner.node == here) {
        return format!(
            "it runs on {}; {} runs on this node ({here})",
            loser.node, winner.address
        );
    }
    if loser.uptime_ms != winner.uptime_ms {
        return format!(
            "up {:.1} s; {} has been up longer ({:.1} s)",
            loser.uptime_ms as f64 / 1000.0,
            winner.address,
            winner.uptime_ms as f64 / 1000.0
        );
    }
    format!("equal to {}, which was offered first", winner.address)
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::property::{ParamDecl, ParamSchema};

    fn v1() -> OpInfo {
        OpInfo::new("wall-follower", 1514, "1.0.0").params(ParamSchema::new(vec![
            ParamDecl::float("distance", 0.6).range(0.2, 2.0),
        ]))
    }

    fn v2() -> OpInfo {
        OpInfo::new("wall-follower", 1514, "2.0.0").params(ParamSchema::new(vec![
            ParamDecl::float("distance", 0.6).range(0.2, 2.0),
            ParamDecl::choice("mode", &["wall", "corridor"], "wall"),
        ]))
    }

    fn distance() -> Need {
        Need::new("wall-follower").supplies([("distance", Value::Float(0.7))])
    }

    fn corridor() -> Need {
        distance().supplies([("mode", Value::Text("corridor".into()))])
    }

    fn verdict(c: &Choice, i: usize) -> &Verdict {
        &c.candidates[i].verdict
    }

    #[test]
    fn an_exact_schema_wins_over_a_compatible_superset_and_says_why() {
        let offers = [Offer::new("0.2", "a", v2()), Offer::new("0.1", "a", v1())];
        let c = choose(&distance(), &offers, "a");
        assert_eq!(c.chosen().unwrap().version, "1.0.0");
        let Verdict::Lost { reason } = verdict(&c, 0) else {
            panic!("{c:?}")
        };
        assert!(reason.contains("also declares mode"), "{reason}");
        assert!(reason.contains("fits exactly"), "{reason}");
    }

    #[test]
    fn a_schema_that_refuses_a_supplied_parameter_is_rejected() {
        let offers = [Offer::new("0.1", "a", v1()), Offer::new("0.2", "b", v2())];
        let c = choose(&corridor(), &offers, "a");
        assert_eq!(c.chosen().unwrap().address, "0.2");
        let Verdict::Rejected { reason } = verdict(&c, 0) else {
            panic!("{c:?}")
        };
        assert!(reason.contains("mode"), "{reason}");
        // a value out of range rejects too
        let far = Need::new("wall-follower").supplies([("distance", Value::Float(5.0))]);
        let c = choose(&far, &offers, "a");
        assert_eq!(c.chosen(), None);
        assert!(c.why_none().contains("0.1 on a"), "{}", c.why_none());
        assert!(c.why_none().contains("0.2 on b"), "{}", c.why_none());
    }

    #[test]
    fn the_mission_needing_version_two_where_only_version_one_runs_gets_nothing() {
        let offers = [Offer::new("0.1", "a", v1())];
        let c = choose(&corridor(), &offers, "a");
        assert!(c.chosen().is_none());
        let need = distance().version(VersionReq::parse("^2").unwrap());
        let c = choose(&need, &offers, "a");
        assert!(c.why_none().contains("does not match"), "{}", c.why_none());
        assert!(choose(&need, &[], "a")
            .why_none()
            .contains("no live instance"));
    }

    #[test]
    fn among_equals_a_free_local_long_running_instance_wins_in_that_order() {
        let mut busy = Offer::new("0.1", "here", v1());
        busy.in_use = true;
        busy.uptime_ms = 90_000;
        let mut remote = Offer::new("1.1", "there", v1());
        remote.uptime_ms = 90_000;
        let mut young = Offer::new("0.2", "here", v1());
        young.uptime_ms = 1_000;
        let mut old = Offer::new("0.3", "here", v1());
        old.uptime_ms = 60_000;
        let offers = [busy, remote, young, old];
        let c = choose(&distance(), &offers, "here");
        assert_eq!(c.chosen().unwrap().address, "0.3");
        let reasons: Vec<String> = c
            .candidates
            .iter()
            .filter_map(|c| match &c.verdict {
                Verdict::Lost { reason } => Some(reason.clone()),
                _ => None,
            })
            .collect();
        assert!(reasons[0].contains("in use"), "{reasons:?}");
        assert!(reasons[1].contains("runs on there"), "{reasons:?}");
        assert!(reasons[2].contains("up 1.0 s"), "{reasons:?}");
    }

    #[test]
    fn a_stand_in_is_admitted_only_if_the_mission_could_have_chosen_it() {
        assert!(admits(&corridor(), &v2()).is_ok());
        assert!(matches!(
            admits(&corridor(), &v1()),
            Err(Inadmissible::Schema { rejections }) if rejections[0].name == "mode"
        ));
        assert!(admits(&distance(), &v1()).is_ok());
        let two = distance().version(VersionReq::parse("^2").unwrap());
        let Err(why) = admits(&two, &v1()) else {
            panic!("version 1 admitted for ^2")
        };
        assert!(matches!(&why, Inadmissible::Version { version, .. } if version.major == 1));
        assert_eq!(
            why.to_string(),
            "its version 1.0.0 does not match the mission's requirement ^2"
        );
        let odd = OpInfo::new("wall-follower", 1514, "one");
        assert!(matches!(
            admits(&two, &odd),
            Err(Inadmissible::NotSemver { version, .. }) if version == "one"
        ));
    }
}

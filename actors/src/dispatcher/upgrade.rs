//! Upgrades: a binding moves to a newer compatible version of its operation at an action's
//! start, never in the middle of one.
//!
//! Issue 44: an operation's new build is started beside the old one (a node restarted with
//! another binary, or one added), and the mission should run on it without stopping. A
//! binding cannot change instance while the operation runs an action — the new instance
//! would start the action's work from its beginning, and the old one's state would be
//! thrown away mid-way —, so the dispatcher notes the newer instance when it appears
//! ([`judge`]) and moves the binding to it when the next action that uses the operation
//! starts ([`moves_at_start`]), sending it that action's parameters with its activation.
//! If the old instance is lost first, the ordinary rebind (`healing`) applies, and its
//! selection may pick the newer one.
//!
//! Which instance is a newer *compatible* version:
//! - its version and the bound one's are semantic versions, and it is greater;
//! - it is compatible by semver's rule: the same major version (for `0.x`, the same minor),
//!   so a new major version — another contract — never takes a binding by itself; a
//!   pre-release of the next minor (`1.1.0-rc.1` for `1.0.0`) is compatible;
//! - the mission could have chosen it ([`selection::admits`]): the mission's `[requires]`
//!   matches it and its schema takes every parameter the mission supplies.
//!
//! A binding the mission pins (`[pin]`) never moves: a newer version is refused, saying so.
//!
//! An instance that is newer and compatible but that the mission could not have chosen is
//! *refused*, and the run says why (`binding_upgrade_refused`); an older, equal or
//! incompatible one is ignored without a word (a restart of the bound version is no news).

use super::mission::op_info::OpInfo;
use super::selection::{self, Need};
use semver::Version;

/// What the dispatcher makes of an instance of a bound operation that appeared.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Judgement {
    /// A newer compatible version the mission can use: the binding moves to it at the
    /// next action's start that uses the operation.
    Newer,
    /// Newer and compatible, but the mission cannot use it: why, for the run's events.
    Refused(String),
    /// No upgrade (not newer, another major version, no semantic version, or not newer than
    /// the instance already due): why, for the logs.
    Ignored(String),
}

/// Judge `candidate`, an instance of the operation bound at version `current` for `need`;
/// `due` is the version of a newer instance already noted, if any (only a newer one still
/// replaces it).
pub fn judge(current: &str, need: &Need, candidate: &OpInfo, due: Option<&str>) -> Judgement {
    let (Ok(bound), Ok(offered)) = (Version::parse(current), Version::parse(&candidate.version))
    else {
        return Judgement::Ignored(format!(
            "version {} or the bound {current} is not semver",
            candidate.version
        ));
    };
    if offered <= bound {
        return Judgement::Ignored(format!("version {offered} is not newer than {bound}"));
    }
    if !compatible(&bound, &offered) {
        return Judgement::Ignored(format!(
            "version {offered} is not compatible with {bound} (another {})",
            if bound.major == 0 { "minor" } else { "major" }
        ));
    }
    if let Some(pin) = &need.pin {
        return Judgement::Refused(format!("the mission pins it to {pin}"));
    }
    if let Some(due) = due.and_then(|d| Version::parse(d).ok()) {
        if offered <= due {
            return Judgement::Ignored(format!(
                "version {offered} is not newer than {due}, already due"
            ));
        }
    }
    match selection::admits(need, candidate) {
        Ok(()) => Judgement::Newer,
        Err(why) => Judgement::Refused(why.to_string()),
    }
}

/// Whether `offered` may replace `bound` by semver's rule for a caret requirement: the same
/// major version, or for `0.x` the same minor.
fn compatible(bound: &Version, offered: &Version) -> bool {
    match bound.major {
        0 => offered.major == 0 && offered.minor == bound.minor,
        major => offered.major == major,
    }
}

/// Whether a binding with a newer instance due moves to it as an action that uses the
/// operation starts: only while its instance lives (a lost binding is rebound by `healing`,
/// whose selection may take the newer one) and while no other action runs the operation (a
/// parallel branch: the move waits for that action's end — never mid-action).
pub fn moves_at_start(due: bool, lost: bool, running_elsewhere: bool) -> bool {
    due && !lost && !running_elsewhere
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
    use semver::VersionReq;

    fn follower(version: &str, speed: bool) -> OpInfo {
        let mut params = vec![ParamDecl::float("distance", 0.6).range(0.3, 3.0)];
        if speed {
            params.push(ParamDecl::float("speed", 0.3).range(0.1, 0.5));
        }
        OpInfo::new("wall-follower", 1514, version).params(ParamSchema::new(params))
    }

    fn wall() -> Need {
        Need::new("wall-follower").supplies([("distance", Value::Float(0.8))])
    }

    #[test]
    fn a_newer_minor_with_one_more_optional_parameter_is_taken() {
        assert_eq!(
            judge("1.0.0", &wall(), &follower("1.1.0", true), None),
            Judgement::Newer
        );
        // a release candidate of the next minor is newer too
        assert_eq!(
            judge("1.0.0", &wall(), &follower("1.1.0-rc.1", true), None),
            Judgement::Newer
        );
        // and a patch
        assert_eq!(
            judge("1.0.0", &wall(), &follower("1.0.1", false), None),
            Judgement::Newer
        );
    }

    #[test]
    fn the_same_an_older_or_another_major_version_is_ignored() {
        for (version, why) in [
            ("1.0.0", "not newer"),
            ("0.9.0", "not newer"),
            ("2.0.0", "another major"),
            ("one", "not semver"),
        ] {
            let Judgement::Ignored(reason) =
                judge("1.0.0", &wall(), &follower(version, false), None)
            else {
                panic!("{version} not ignored")
            };
            assert!(reason.contains(why), "{version}: {reason}");
        }
        // below 1.0, a minor is another contract
        let Judgement::Ignored(reason) = judge("0.3.0", &wall(), &follower("0.4.0", false), None)
        else {
            panic!("0.4 taken for 0.3")
        };
        assert!(reason.contains("another minor"), "{reason}");
        assert_eq!(
            judge("0.3.0", &wall(), &follower("0.3.2", false), None),
            Judgement::Newer
        );
    }

    #[test]
    fn only_a_version_newer_than_the_one_already_due_replaces_it() {
        let later = follower("1.1.0", true);
        assert!(matches!(
            judge("1.0.0", &wall(), &later, Some("1.1.0")),
            Judgement::Ignored(_)
        ));
        assert!(matches!(
            judge("1.0.0", &wall(), &later, Some("1.2.0")),
            Judgement::Ignored(_)
        ));
        assert_eq!(
            judge("1.0.0", &wall(), &later, Some("1.0.5")),
            Judgement::Newer
        );
    }

    #[test]
    fn a_newer_version_the_mission_could_not_choose_is_refused_with_the_reason() {
        // its schema refuses the distance the mission supplies
        let narrow = OpInfo::new("wall-follower", 1514, "1.1.0").params(ParamSchema::new(vec![
            ParamDecl::float("distance", 0.6).range(0.3, 0.5),
        ]));
        let Judgement::Refused(why) = judge("1.0.0", &wall(), &narrow, None) else {
            panic!("an instance refusing the distance taken")
        };
        assert!(why.contains("distance"), "{why}");
        // outside the mission's requirement (a pre-release matches no plain requirement)
        let need = wall().version(VersionReq::parse("^1").unwrap());
        let Judgement::Refused(why) = judge("1.0.0", &need, &follower("1.1.0-rc.1", true), None)
        else {
            panic!("a pre-release taken against ^1")
        };
        assert!(why.contains("requirement ^1"), "{why}");
        assert_eq!(
            judge("1.0.0", &need, &follower("1.1.0", true), None),
            Judgement::Newer
        );
    }

    #[test]
    fn a_pinned_binding_never_moves_and_says_why() {
        let pinned = wall().pinned(VersionReq::parse("=1.0.0").unwrap());
        let Judgement::Refused(why) = judge("1.0.0", &pinned, &follower("1.1.0", true), None)
        else {
            panic!("a pinned binding moved")
        };
        assert_eq!(why, "the mission pins it to =1.0.0");
        // a requirement pin holds too, even for a version inside it
        let pinned = wall().pinned(VersionReq::parse("~1.0").unwrap());
        assert!(matches!(
            judge("1.0.0", &pinned, &follower("1.0.1", false), None),
            Judgement::Refused(_)
        ));
        // and the same version restarting is no news
        assert!(matches!(
            judge("1.0.0", &pinned, &follower("1.0.0", false), None),
            Judgement::Ignored(_)
        ));
        // a stand-in after a loss must match the pin (the selection's test)
        assert!(selection::admits(&pinned, &follower("1.0.3", false)).is_ok());
        let Err(why) = selection::admits(&pinned, &follower("1.1.0", true)) else {
            panic!("a stand-in outside the pin admitted")
        };
        assert!(why.to_string().contains("the mission's pin ~1.0"), "{why}");
    }

    #[test]
    fn a_binding_moves_at_start_only_while_its_instance_lives_and_nothing_else_runs_it() {
        assert!(moves_at_start(true, false, false));
        assert!(!moves_at_start(false, false, false));
        assert!(!moves_at_start(true, true, false));
        assert!(!moves_at_start(true, false, true));
    }
}

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
//! **Rollback.** The move is on trial until the new instance's first activation — the
//! action the binding moved at — reports ([`first_activation`]). If it fails (an error
//! reply, its actor gone, or no answer to a probe within its declared deadline) while the
//! action still runs and the old instance still lives, the binding goes back to the old
//! instance, which starts the action again ([`after_failed_first_activation`]); the newer
//! instance is then refused for the rest of the run ([`judge`]'s `spurned`, and never a
//! stand-in). If the old instance is gone too, or the action no longer runs, nothing
//! changes: the failure takes the path it always took (a lost instance is rebound, an
//! error reply fails the action).
//!
//! An instance that is newer and compatible but that the mission could not have chosen is
//! *refused*, and the run says why (`binding_upgrade_refused`); an older, equal or
//! incompatible one is ignored without a word (a restart of the bound version is no news).

use super::mission::op_info::OpInfo;
use super::selection::{self, Need};
use crate::eo::EoReport;
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
/// replaces it); `spurned` is why the binding rolled back from this very instance earlier
/// in the run, if it did (it is never taken to again).
pub fn judge(
    current: &str,
    need: &Need,
    candidate: &OpInfo,
    due: Option<&str>,
    spurned: Option<&str>,
) -> Judgement {
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
    if let Some(reason) = spurned {
        return Judgement::Refused(format!(
            "the binding rolled back from it earlier in this run: {reason}"
        ));
    }
    if let Some((pin, by)) = need.pin_in_force() {
        return Judgement::Refused(format!("{by} pins it to {pin}"));
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

/// Why `candidate`, a newer compatible version of the operation bound (or to be bound) at
/// version `current`, could not take the parameters the mission supplies, if it could not —
/// what `marie check` refuses a mission for (before anything runs, rather than a binding
/// that silently stays at run time). `None` when it could take them, when it is not a newer
/// compatible version, when the mission's requirement excludes it anyway, or when the
/// mission pins the operation (a pinned binding never moves).
pub fn parameters_refused(current: &str, need: &Need, candidate: &OpInfo) -> Option<String> {
    if need.pin_in_force().is_some() {
        return None;
    }
    let (Ok(bound), Ok(offered)) = (Version::parse(current), Version::parse(&candidate.version))
    else {
        return None;
    };
    if offered <= bound || !compatible(&bound, &offered) {
        return None;
    }
    match selection::admits(need, candidate) {
        Err(why @ selection::Inadmissible::Schema { .. }) => Some(why.to_string()),
        _ => None,
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

/// How the first activation of an instance a binding moved to ended, from its report.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FirstActivation {
    /// It finished, or was suspended (its action ended by another operation): the move
    /// holds.
    Passed,
    /// It replied with an error, or refused the action's parameters: why.
    Failed(String),
    /// Its reply port closed unanswered: the instance died. The loss is noticed as any
    /// loss is (`healing`), where the trial still stands and decides a rollback.
    Lost,
}

/// How the first activation after a move ended, from its `report` (`None`: the instance
/// died first). A stale or idle answer is about another dispatcher's command, not this
/// instance's health: passed, as far as the rollback is concerned.
pub fn first_activation(report: Option<&EoReport>) -> FirstActivation {
    match report {
        None => FirstActivation::Lost,
        Some(EoReport::Failed { reason, .. }) => {
            FirstActivation::Failed(format!("its first activation failed: {reason}"))
        }
        Some(EoReport::Rejected { rejections, .. }) => {
            let refused: Vec<String> = rejections.iter().map(ToString::to_string).collect();
            FirstActivation::Failed(format!(
                "it refused the action's parameters: {}",
                refused.join("; ")
            ))
        }
        Some(
            EoReport::Finished { .. }
            | EoReport::Suspended { .. }
            | EoReport::Stale { .. }
            | EoReport::Idle { .. },
        ) => FirstActivation::Passed,
    }
}

/// What a failed first activation after a move leads to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AfterFailure {
    /// The binding goes back to the old instance, which starts the action again.
    RollBack,
    /// Nothing to go back to (the old instance is gone) or nothing to start again (the
    /// action ended meanwhile): the failure takes the path it takes without an upgrade.
    AsWithoutUpgrade,
}

/// Whether a binding whose new instance failed its first activation rolls back: only if
/// the old instance still lives (answers as the same operation) and the action the move
/// happened at still runs.
pub fn after_failed_first_activation(old_lives: bool, action_runs: bool) -> AfterFailure {
    match old_lives && action_runs {
        true => AfterFailure::RollBack,
        false => AfterFailure::AsWithoutUpgrade,
    }
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
            judge("1.0.0", &wall(), &follower("1.1.0", true), None, None),
            Judgement::Newer
        );
        // a release candidate of the next minor is newer too
        assert_eq!(
            judge("1.0.0", &wall(), &follower("1.1.0-rc.1", true), None, None),
            Judgement::Newer
        );
        // and a patch
        assert_eq!(
            judge("1.0.0", &wall(), &follower("1.0.1", false), None, None),
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
                judge("1.0.0", &wall(), &follower(version, false), None, None)
            else {
                panic!("{version} not ignored")
            };
            assert!(reason.contains(why), "{version}: {reason}");
        }
        // below 1.0, a minor is another contract
        let Judgement::Ignored(reason) =
            judge("0.3.0", &wall(), &follower("0.4.0", false), None, None)
        else {
            panic!("0.4 taken for 0.3")
        };
        assert!(reason.contains("another minor"), "{reason}");
        assert_eq!(
            judge("0.3.0", &wall(), &follower("0.3.2", false), None, None),
            Judgement::Newer
        );
    }

    #[test]
    fn only_a_version_newer_than_the_one_already_due_replaces_it() {
        let later = follower("1.1.0", true);
        assert!(matches!(
            judge("1.0.0", &wall(), &later, Some("1.1.0"), None),
            Judgement::Ignored(_)
        ));
        assert!(matches!(
            judge("1.0.0", &wall(), &later, Some("1.2.0"), None),
            Judgement::Ignored(_)
        ));
        assert_eq!(
            judge("1.0.0", &wall(), &later, Some("1.0.5"), None),
            Judgement::Newer
        );
    }

    #[test]
    fn a_newer_version_the_mission_could_not_choose_is_refused_with_the_reason() {
        // its schema refuses the distance the mission supplies
        let narrow = OpInfo::new("wall-follower", 1514, "1.1.0").params(ParamSchema::new(vec![
            ParamDecl::float("distance", 0.6).range(0.3, 0.5),
        ]));
        let Judgement::Refused(why) = judge("1.0.0", &wall(), &narrow, None, None) else {
            panic!("an instance refusing the distance taken")
        };
        assert!(why.contains("distance"), "{why}");
        // outside the mission's requirement (a pre-release matches no plain requirement)
        let need = wall().version(VersionReq::parse("^1").unwrap());
        let Judgement::Refused(why) =
            judge("1.0.0", &need, &follower("1.1.0-rc.1", true), None, None)
        else {
            panic!("a pre-release taken against ^1")
        };
        assert!(why.contains("requirement ^1"), "{why}");
        assert_eq!(
            judge("1.0.0", &need, &follower("1.1.0", true), None, None),
            Judgement::Newer
        );
    }

    #[test]
    fn a_pinned_binding_never_moves_and_says_why() {
        let pinned = wall().pinned(VersionReq::parse("=1.0.0").unwrap());
        let Judgement::Refused(why) = judge("1.0.0", &pinned, &follower("1.1.0", true), None, None)
        else {
            panic!("a pinned binding moved")
        };
        assert_eq!(why, "the mission pins it to =1.0.0");
        // a requirement pin holds too, even for a version inside it
        let pinned = wall().pinned(VersionReq::parse("~1.0").unwrap());
        assert!(matches!(
            judge("1.0.0", &pinned, &follower("1.0.1", false), None, None),
            Judgement::Refused(_)
        ));
        // and the same version restarting is no news
        assert!(matches!(
            judge("1.0.0", &pinned, &follower("1.0.0", false), None, None),
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

    #[test]
    fn a_first_activation_fails_on_an_error_reply_or_a_refusal_and_is_lost_on_a_closed_port() {
        use crate::eo::EoReport;
        use marie_vocabulary::property::{RejectReason, Rejection};
        use marie_vocabulary::status::StatusFlags;
        let flags = StatusFlags::EMPTY;
        let failed = EoReport::Failed {
            reason: "no wall".into(),
            flags,
            epoch: 3,
        };
        assert_eq!(
            first_activation(Some(&failed)),
            FirstActivation::Failed("its first activation failed: no wall".into())
        );
        let rejected = EoReport::Rejected {
            rejections: vec![Rejection::new("speed", RejectReason::UnknownName)],
            epoch: 3,
        };
        let FirstActivation::Failed(why) = first_activation(Some(&rejected)) else {
            panic!("a refusal passed")
        };
        assert!(
            why.contains("refused the action's parameters") && why.contains("speed"),
            "{why}"
        );
        assert_eq!(first_activation(None), FirstActivation::Lost);
        for passed in [
            EoReport::Finished { flags, epoch: 3 },
            EoReport::Suspended { flags, epoch: 3 },
            EoReport::Stale {
                epoch: 3,
                current: 4,
            },
        ] {
            assert_eq!(first_activation(Some(&passed)), FirstActivation::Passed);
        }
    }

    #[test]
    fn a_failed_first_activation_rolls_back_only_to_a_living_old_instance_of_a_running_action() {
        assert_eq!(
            after_failed_first_activation(true, true),
            AfterFailure::RollBack
        );
        // the old instance is gone too: the ordinary rebind (or the action's failure)
        assert_eq!(
            after_failed_first_activation(false, true),
            AfterFailure::AsWithoutUpgrade
        );
        // the action ended meanwhile: nothing to start again
        assert_eq!(
            after_failed_first_activation(true, false),
            AfterFailure::AsWithoutUpgrade
        );
    }

    #[test]
    fn an_instance_rolled_back_from_is_never_taken_to_again() {
        let Judgement::Refused(why) = judge(
            "1.0.0",
            &wall(),
            &follower("1.1.0", true),
            None,
            Some("its first activation failed: no wall"),
        ) else {
            panic!("an instance rolled back from taken again")
        };
        assert_eq!(
            why,
            "the binding rolled back from it earlier in this run: its first activation failed: no wall"
        );
        // an older one is still no news, whatever happened
        assert!(matches!(
            judge("1.0.0", &wall(), &follower("0.9.0", false), None, Some("x")),
            Judgement::Ignored(_)
        ));
    }

    /// Version 1.1 of the wall follower as a test declares it: `distance` renamed
    /// `wall_distance` (with the migration if `migrated`), its range narrowed to 2.5 m.
    fn renamed(migrated: bool) -> OpInfo {
        let info = OpInfo::new("wall-follower", 1514, "1.1.0").params(ParamSchema::new(vec![
            ParamDecl::float("wall_distance", 0.6).range(0.3, 2.5),
        ]));
        match migrated {
            true => info
                .migrations(crate::declare::Migrations::new().rename("distance", "wall_distance")),
            false => info,
        }
    }

    #[test]
    fn a_renamed_parameter_is_taken_through_its_migration_and_refused_without_one() {
        assert_eq!(
            judge("1.0.0", &wall(), &renamed(true), None, None),
            Judgement::Newer
        );
        assert_eq!(parameters_refused("1.0.0", &wall(), &renamed(true)), None);
        let Judgement::Refused(why) = judge("1.0.0", &wall(), &renamed(false), None, None) else {
            panic!("a rename without a migration taken")
        };
        assert!(why.contains("distance"), "{why}");
        let refused = parameters_refused("1.0.0", &wall(), &renamed(false)).expect("refused");
        assert!(refused.contains("distance: unknown parameter"), "{refused}");
    }

    #[test]
    fn a_value_outside_a_narrowed_range_is_refused_not_clamped() {
        let far = Need::new("wall-follower").supplies([("distance", Value::Float(2.8))]);
        let Judgement::Refused(why) = judge("1.0.0", &far, &renamed(true), None, None) else {
            panic!("a value out of the new range taken")
        };
        assert!(why.contains("wall_distance"), "{why}");
        let refused = parameters_refused("1.0.0", &far, &renamed(true)).expect("refused");
        assert!(refused.contains("wall_distance"), "{refused}");
        // pinned, it never moves: nothing to refuse
        let pinned = far.clone().pinned(VersionReq::parse("=1.0.0").unwrap());
        assert_eq!(parameters_refused("1.0.0", &pinned, &renamed(true)), None);
        // outside the mission's requirement, or not newer, or another major: not a move
        let req = far.clone().version(VersionReq::parse("~1.0").unwrap());
        assert_eq!(parameters_refused("1.0.0", &req, &renamed(true)), None);
        assert_eq!(parameters_refused("1.1.0", &far, &renamed(true)), None);
        assert_eq!(parameters_refused("0.9.0", &far, &renamed(true)), None);
    }

    #[test]
    fn a_node_config_pin_holds_the_binding_and_the_missions_own_pin_wins() {
        let pinned = |need: Need| Need {
            node_pin: Some((VersionReq::parse("=1.0.0").unwrap(), "wf-one".to_string())),
            ..need
        };
        let by_node = pinned(wall());
        let Judgement::Refused(why) =
            judge("1.0.0", &by_node, &follower("1.1.0", true), None, None)
        else {
            panic!("a binding its node pins moved")
        };
        assert_eq!(why, "node wf-one's config pins it to =1.0.0");
        // a stand-in must be of the pinned version
        let Err(why) = selection::admits(&by_node, &follower("1.0.1", false)) else {
            panic!("a stand-in outside the node's pin admitted")
        };
        assert!(
            why.to_string()
                .contains("the pin of node wf-one's config =1.0.0"),
            "{why}"
        );
        assert!(selection::admits(&by_node, &follower("1.0.0", false)).is_ok());
        // the mission pins it too: the mission's pin alone counts
        let both = pinned(wall().pinned(VersionReq::parse("~1.0").unwrap()));
        let Judgement::Refused(why) = judge("1.0.0", &both, &follower("1.1.0", true), None, None)
        else {
            panic!("a pinned binding moved")
        };
        assert_eq!(why, "the mission pins it to ~1.0");
        assert!(selection::admits(&both, &follower("1.0.1", false)).is_ok());
        // no upgrade to refuse a mission for at check time: it never moves
        assert_eq!(parameters_refused("1.0.0", &by_node, &renamed(false)), None);
    }
}

//! The control keys of a mission file (`retry`, `timeout_s`, `on_failure`, `while`,
//! `unless`, `[[group]]`): every diagnostic at its position, the tree they build, and the
//! thesis' tree for a file without them.

use super::*;
use crate::dispatcher::tree::{Command, Node, Scheduled, Status, Tree};
use marie_vocabulary::property::{ParamDecl, ParamSchema, Value};
use marie_vocabulary::status::FlagDecl;

/// The operations of these tests and the flags each raises.
fn catalog() -> StaticCatalog {
    let op = |name: &str, id: u32, flags: &[&str]| {
        OpInfo::new(name, id, "1.0.0").flags(flags.iter().map(|f| FlagDecl::new(*f, "")).collect())
    };
    StaticCatalog::new([
        op("ultrasonic", 1516, &[]),
        op("wall-sensor", 1512, &["wall-found"]),
        op("wall-follower", 1514, &[]),
        op("docking-detector", 1518, &["dock-found"]),
        op("trajectory-controller", 1511, &["parked"]),
        op("reverse", 1601, &[]),
        op("turner", 1602, &[]),
        op("bumper", 1603, &["obstacle"]),
    ])
}

/// Six lines: the mission and three flags; what a test adds starts at line 7.
const HEAD: &str = "[mission]\nname = \"t\"\n[flags]\nready = 0\nwall-found = 1\nobstacle = 2\n";

type Found = Vec<(usize, usize, String)>;

fn found(d: &Diagnostics) -> Found {
    d.iter()
        .map(|d| (d.line, d.column, d.message.clone()))
        .collect()
}

/// Stage 1 must reject `HEAD` + `body`: what it says.
#[track_caller]
fn parse_err(body: &str) -> Found {
    match ParsedMission::parse(&format!("{HEAD}{body}"), None) {
        Ok(_) => panic!("stage 1 should reject:\n{body}"),
        Err(d) => found(&d),
    }
}

/// Stage 1 must pass `HEAD` + `body` and stage 2 reject it: what stage 2 says.
#[track_caller]
fn validate_err(body: &str) -> Found {
    let parsed = ParsedMission::parse(&format!("{HEAD}{body}"), None)
        .unwrap_or_else(|d| panic!("stage 1 failed:\n{d}"));
    match parsed.validate(&catalog()) {
        Ok(_) => panic!("stage 2 should reject:\n{body}"),
        Err(d) => found(&d),
    }
}

#[track_caller]
fn mission(src: &str) -> Mission {
    ParsedMission::parse(src, None)
        .and_then(|p| p.validate(&catalog()))
        .unwrap_or_else(|d| panic!("{d}"))
}

fn at(line: usize, column: usize, message: &str) -> (usize, usize, String) {
    (line, column, message.to_string())
}

const KINDS: &str = "\"sequence\", \"fallback\", \"parallel\" or \"reactive\"";

// ---------------------------------------------------------------------------------------------
// Stage 1: structure

#[test]
fn unknown_keys_of_groups_and_retries_are_reported_with_the_accepted_ones() {
    let d = parse_err(
        "[[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"a\"]\nkids = 1\n\
         retry = { attempts = 2, backof_s = 1 }\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n",
    );
    assert_eq!(
        d,
        [
            at(11, 1, "unknown key `kids` in `[[group]]` (expected one of: name, kind, children, when, retry, timeout_s, on_failure, while, unless, success, failure)"),
            at(12, 25, "unknown key `backof_s` in `group.retry` (expected one of: attempts, backoff_s)"),
        ]
    );
    let d = parse_err("[[grop]]\n[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n");
    assert_eq!(
        d,
        [at(
            7,
            3,
            "unknown key `grop` in the mission file (expected one of: mission, flags, action, requires, pin, group)"
        )]
    );
}

#[test]
fn a_group_needs_a_name_a_known_kind_and_children() {
    let d = parse_err(
        "[[group]]\nname = \"f\"\nkind = \"fallback\"\nchildren = []\n\
         [[group]]\nname = \"s\"\nkind = \"seq\"\nchildren = [\"a\"]\n\
         [[group]]\nkind = \"parallel\"\n\
         [[group]]\nname = \"k\"\nchildren = [\"a\"]\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n",
    );
    assert_eq!(
        d,
        [
            at(10, 12, "a fallback with no child: group `f` names no action or group in `children`"),
            at(13, 8, &format!("unknown group kind \"seq\" (expected {KINDS})")),
            at(15, 1, "missing key `name` in `[[group]]` (expected a name for the group, unique among actions and groups, a string)"),
            at(15, 1, "missing key `children` in group without a name (expected the names of the actions and groups it runs, in order)"),
            at(17, 1, &format!("missing key `kind` in group `k` (expected {KINDS})")),
        ]
    );
}

#[test]
fn children_and_recoveries_name_an_action_or_a_group_with_a_suggestion_or_the_names() {
    let d = parse_err(
        "[[action]]\nname = \"follow-wall\"\non_failure = \"bakc-off\"\n[action.ops.wall-follower]\n\
         [[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"folow-wall\", \"zzz\"]\n",
    );
    assert_eq!(
        d,
        [
            at(9, 14, "unknown action or group `bakc-off` in `action.on_failure` (expected one of: follow-wall, g)"),
            at(14, 13, "unknown action or group `folow-wall` in `group.children` (did you mean `follow-wall`?)"),
            at(14, 27, "unknown action or group `zzz` in `group.children` (expected one of: follow-wall, g)"),
        ]
    );
}

#[test]
fn names_are_unique_among_actions_and_groups() {
    let d = parse_err(
        "[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n\
         [[group]]\nname = \"a\"\nkind = \"sequence\"\nchildren = [\"b\"]\n\
         [[action]]\nname = \"b\"\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"b\"\n[action.ops.reverse]\n",
    );
    assert_eq!(
        d,
        [
            at(11, 8, "duplicate name `a` (first used at 8:8 by an action; action and group names must be unique)"),
            at(18, 8, "duplicate action name `b` (first used at 15:8; action names must be unique)"),
        ]
    );
}

#[test]
fn an_item_is_the_child_of_one_group_at_most() {
    let d = parse_err(
        "[[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"a\", \"a\"]\n\
         [[group]]\nname = \"h\"\nkind = \"fallback\"\nchildren = [\"a\"]\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n",
    );
    assert_eq!(
        d,
        [
            at(10, 18, "action `a` is named twice among the children of group `g` (first at 10:13)"),
            at(14, 13, "action `a` is already a child of group `g` (named at 10:13): an action or group is the child of one group at most"),
        ]
    );
}

#[test]
fn a_group_cannot_contain_itself_directly_or_through_another() {
    let d = parse_err(
        "[[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"g\"]\n\
         [[group]]\nname = \"h\"\nkind = \"sequence\"\nchildren = [\"i\"]\n\
         [[group]]\nname = \"i\"\nkind = \"fallback\"\nchildren = [\"h\"]\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n",
    );
    assert_eq!(
        d,
        [
            at(10, 13, "group `g` names itself among its children (a group cannot contain itself)"),
            at(18, 13, "group `h` contains itself: `h` contains `i`, `i` contains `h` (a group cannot contain itself)"),
        ]
    );
}

#[test]
fn a_recovery_cannot_be_what_it_recovers_nor_contain_it() {
    let d = parse_err(
        "[[action]]\nname = \"a\"\non_failure = \"a\"\n[action.ops.ultrasonic]\n\
         [[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"b\"]\n\
         [[action]]\nname = \"b\"\non_failure = \"g\"\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"c\"\non_failure = \"d\"\n[action.ops.reverse]\n\
         [[action]]\nname = \"d\"\non_failure = \"c\"\n[action.ops.turner]\n",
    );
    assert_eq!(
        d,
        [
            at(9, 14, "action `a` names itself in `on_failure` (a recovery cannot be what it recovers)"),
            at(17, 14, "the recovery of action `b` leads back to it: `b` recovers with `g`, `g` contains `b` (a recovery cannot contain what it recovers)"),
            at(21, 14, "the recovery of action `c` leads back to it: `c` recovers with `d`, `d` recovers with `c` (a recovery cannot contain what it recovers)"),
        ]
    );
}

#[test]
fn a_retry_needs_an_attempt_and_a_backoff_of_zero_or_more_and_a_timeout_is_positive() {
    let d = parse_err(
        "[[action]]\nname = \"a\"\nretry = { attempts = 0 }\n[action.ops.ultrasonic]\n\
         [[action]]\nname = \"b\"\nretry = { attempts = -1, backoff_s = -2.0 }\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"c\"\nretry = { backoff_s = 1 }\n[action.ops.reverse]\n\
         [[action]]\nname = \"d\"\nretry = 3\ntimeout_s = 0\n[action.ops.turner]\n\
         [[group]]\nname = \"g\"\nkind = \"sequence\"\nchildren = [\"a\"]\nretry = { attempts = 0 }\n",
    );
    assert_eq!(
        d,
        [
            at(9, 22, "a retry of 0 attempts never runs the action (`attempts` counts every attempt, the first included: expected at least 1)"),
            at(13, 22, "`action.retry.attempts` must be an integer of at least 1, found -1"),
            at(13, 38, "`action.retry.backoff_s` must be a non-negative, finite number of seconds, found -2.0"),
            at(17, 9, "missing key `attempts` in `action.retry` (expected the attempts in all, the first included: an integer of at least 1)"),
            at(21, 9, "expected a table for `action.retry` (e.g. retry = { attempts = 3, backoff_s = 2.0 }), found integer"),
            at(22, 13, "`action.timeout_s` must be a positive, finite number of seconds, found 0"),
            at(28, 22, "a retry of 0 attempts never runs the group (`attempts` counts every attempt, the first included: expected at least 1)"),
        ]
    );
}

#[test]
fn parallel_thresholds_lie_between_one_and_the_number_of_children_and_only_parallels_have_them() {
    let d = parse_err(
        "[[group]]\nname = \"p\"\nkind = \"parallel\"\nchildren = [\"a\", \"b\"]\nsuccess = 0\nfailure = 3\n\
         [[group]]\nname = \"s\"\nkind = \"sequence\"\nchildren = [\"c\"]\nsuccess = 1\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n\
         [[action]]\nname = \"b\"\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"c\"\n[action.ops.reverse]\n",
    );
    assert_eq!(
        d,
        [
            at(11, 11, "`success` = 0 of parallel `p` is out of range (expected 1 to 2: how many of its 2 children must succeed)"),
            at(12, 11, "`failure` = 3 of parallel `p` is out of range (expected 1 to 2: how many of its 2 children failing make it fail)"),
            at(17, 1, "`success` applies to a parallel group only (group `s` is a sequence)"),
        ]
    );
}

#[test]
fn a_reactive_group_needs_while_or_unless() {
    let d = parse_err(
        "[[group]]\nname = \"r\"\nkind = \"reactive\"\nchildren = [\"a\"]\n\
         [[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n",
    );
    assert_eq!(
        d,
        [at(9, 8, "reactive group `r` has neither `while` nor `unless` (a reactive group re-checks them while its children run: give at least one)")]
    );
}

#[test]
fn while_and_unless_name_declared_flags_and_never_the_same_one() {
    let d = parse_err(
        "[[action]]\nname = \"a\"\nwhile = [\"redy\"]\nunless = [\"obstacle\", \"ready\"]\n[action.ops.ultrasonic]\n\
         [[group]]\nname = \"g\"\nkind = \"reactive\"\nchildren = [\"a\"]\nwhile = [\"ready\"]\nunless = [\"ready\"]\n",
    );
    assert_eq!(
        d,
        [
            at(9, 10, "unknown flag `redy` in `action.while` (expected one of: obstacle, ready, wall-found)"),
            at(17, 11, "flag `ready` is in both `while` and `unless` of group `g`: it could never run"),
        ]
    );
}

#[test]
fn a_tree_too_deep_or_too_large_is_refused() {
    // 40 groups, each the only child of the one before: 41 levels with the action
    let mut body = String::new();
    for k in 0..40 {
        let child = if k == 39 {
            "a".to_string()
        } else {
            format!("g{}", k + 1)
        };
        body +=
            &format!("[[group]]\nname = \"g{k}\"\nkind = \"sequence\"\nchildren = [\"{child}\"]\n");
    }
    body += "[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n";
    assert_eq!(
        parse_err(&body),
        [at(
            8,
            8,
            "group `g0` nests groups and recoveries 41 levels deep (at most 32)"
        )]
    );
    // each group recovers with its own child: the child's tree twice, 3·2^k − 2 nodes
    let mut body = "[[action]]\nname = \"s0\"\n[action.ops.ultrasonic]\n".to_string();
    for k in 1..=12 {
        body += &format!(
            "[[group]]\nname = \"s{k}\"\nkind = \"sequence\"\nchildren = [\"s{0}\"]\non_failure = \"s{0}\"\n",
            k - 1
        );
    }
    // s12's name: 3 lines of the action, 11 groups of 5 lines, then its table's second line
    assert_eq!(
        parse_err(&body),
        [at(
            6 + 3 + 11 * 5 + 2,
            8,
            "the mission's behaviour tree would have 12287 nodes (at most 10000); group `s12` alone makes 12286: a recovery is copied wherever it may run"
        )]
    );
}

// ---------------------------------------------------------------------------------------------
// Stage 2: against the operations

#[test]
fn children_of_a_parallel_may_not_share_an_operation() {
    let d = validate_err(
        "[[group]]\nname = \"p\"\nkind = \"parallel\"\nchildren = [\"look\", \"follow\", \"turn\"]\n\
         [[action]]\nname = \"look\"\n[action.ops.ultrasonic]\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"follow\"\n[action.ops.wall-follower]\n[action.ops.\"1512\"]\n[action.ops.ultrasonic]\n\
         [[action]]\nname = \"turn\"\non_failure = \"back\"\n[action.ops.turner]\n\
         [[action]]\nname = \"back\"\n[action.ops.wall-follower]\n",
    );
    // `turn` shares with `follow` through its recovery, which runs in its branch
    assert_eq!(
        d,
        [
            at(10, 21, "children `look` and `follow` of parallel `p` both run operations `ultrasonic`, `wall-sensor` (they would run at once, and an operation runs for one action at a time)"),
            at(10, 31, "children `follow` and `turn` of parallel `p` both run operation `wall-follower` (they would run at once, and an operation runs for one action at a time)"),
        ]
    );
}

#[test]
fn a_top_level_item_may_not_wait_for_a_flag_only_its_own_operations_raise() {
    let body = "[[action]]\nname = \"follow\"\nwhen = [\"wall-found\"]\n[action.ops.wall-sensor]\n\
                [[group]]\nname = \"g\"\nkind = \"sequence\"\nwhen = [\"obstacle\"]\nchildren = [\"bump\"]\n\
                [[action]]\nname = \"bump\"\n[action.ops.bumper]\n";
    assert_eq!(
        validate_err(body),
        [
            at(9, 9, "action `follow` waits for flag `wall-found`, which only its own operations raise (`wall-sensor`): it would wait for itself forever"),
            at(14, 9, "group `g` waits for flag `obstacle`, which only operations run inside it raise (`bumper` in `bump`): it would wait for itself forever"),
        ]
    );
    // a thesis mission (no control keys, no group) keeps its meaning: such a wait is the
    // run's failure to report ("no runnable action"), not the check's
    let thesis =
        "[[action]]\nname = \"follow\"\nwhen = [\"wall-found\"]\n[action.ops.wall-sensor]\n";
    assert!(ParsedMission::parse(&format!("{HEAD}{thesis}"), None)
        .and_then(|p| p.validate(&catalog()))
        .is_ok());
    // raised elsewhere too: fine
    let fine = body.replace(
        "[[group]]",
        "[[action]]\nname = \"look\"\n[action.ops.\"1512\"]\n[[group]]",
    ) + "[[action]]\nname = \"hit\"\n[action.ops.bumper]\n";
    assert!(ParsedMission::parse(&format!("{HEAD}{fine}"), None)
        .and_then(|p| p.validate(&catalog()))
        .is_ok());
}

#[test]
fn a_while_flag_must_be_raised_or_initial() {
    assert_eq!(
        validate_err("[[action]]\nname = \"a\"\nwhile = [\"obstacle\"]\n[action.ops.wall-sensor]\n"),
        [at(9, 10, "flag `obstacle` is never raised by any operation of this mission, nor set in `mission.initial` (needed by `action.while`; they raise: wall-found)")]
    );
}

// ---------------------------------------------------------------------------------------------
// The tree

/// Every construct: a retried, timed action with a recovery; a timed fallback between a
/// parallel (one child reactive) and a retried reactive group (one child guarded); top-level
/// actions before and after the groups.
const EVERY_CONSTRUCT: &str = r#"
[mission]
name = "recovering"
success = ["parked"]
initial = ["powered"]

[flags]
powered = 0
wall-found = 1
dock-found = 2
parked = 3
obstacle = 4

[[action]]
name = "find-wall"
when = ["powered"]
timeout_s = 40.0
retry = { attempts = 3, backoff_s = 2.0 }
on_failure = "back-off"
[action.ops.wall-sensor]

[[action]]
name = "back-off"
[action.ops.reverse]

[[group]]
name = "dock"
kind = "fallback"
when = ["wall-found"]
children = ["follow-and-detect", "search"]
timeout_s = 120

[[group]]
name = "follow-and-detect"
kind = "parallel"
children = ["follow-wall", "detect"]
success = 1
failure = 2

[[action]]
name = "follow-wall"
while = ["wall-found"]
unless = ["obstacle"]
[action.ops.wall-follower]

[[action]]
name = "detect"
[action.ops.docking-detector]

[[group]]
name = "search"
kind = "reactive"
unless = ["obstacle"]
children = ["turn"]
retry = { attempts = 2 }

[[action]]
name = "turn"
when = ["wall-found"]
[action.ops.turner]
[action.ops.bumper]

[[action]]
name = "park"
when = ["dock-found"]
[action.ops.trajectory-controller]
"#;

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

#[test]
fn every_construct_builds_the_tree_its_keys_describe() {
    let m = mission(EVERY_CONSTRUCT);
    let names: Vec<&str> = m.actions.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "find-wall",
            "back-off",
            "follow-wall",
            "detect",
            "turn",
            "park"
        ]
    );
    let (powered, wall, dock, obstacle) = (1 << 0, 1 << 1, 1 << 2, 1 << 4);
    let find_wall = Node::Retry {
        child: Box::new(Node::Recover {
            child: Box::new(Node::Timeout {
                child: Box::new(Node::Action(0)),
                limit: secs(40),
            }),
            recovery: Box::new(Node::Action(1)),
        }),
        attempts: 3,
        backoff: secs(2),
    };
    let follow_and_detect = Node::Parallel {
        children: vec![
            Node::Reactive {
                while_: wall,
                unless: obstacle,
                children: vec![Node::Action(2)],
            },
            Node::Action(3),
        ],
        success: 1,
        failure: 2,
    };
    let search = Node::Retry {
        child: Box::new(Node::Reactive {
            while_: 0,
            unless: obstacle,
            // inside a group, `when` is a guard
            children: vec![Node::Sequence(vec![Node::Condition(wall), Node::Action(4)])],
        }),
        attempts: 2,
        backoff: Duration::ZERO,
    };
    let dock_group = Node::Timeout {
        child: Box::new(Node::Fallback(vec![follow_and_detect, search])),
        limit: secs(120),
    };
    // at the top level, in file order (actions and groups interleaved), `when` is the wait
    let expected = Node::Schedule(vec![
        Scheduled {
            when: powered,
            node: find_wall,
        },
        Scheduled {
            when: wall,
            node: dock_group,
        },
        Scheduled {
            when: dock,
            node: Node::Action(5),
        },
    ]);
    assert_eq!(m.control.root, expected);
    assert!(!m.control.is_thesis());
    assert_eq!(
        m.control.labels,
        [
            "mission",
            "retry(find-wall)",
            "recover(find-wall, then back-off)",
            "timeout(find-wall)",
            "find-wall",
            "back-off",
            "timeout(dock)",
            "dock",
            "follow-and-detect",
            "reactive(follow-wall)",
            "follow-wall",
            "detect",
            "retry(search)",
            "search",
            "when(turn)",
            "condition(0x2)",
            "turn",
            "park",
        ]
    );
    let tree = Tree::new(m.control.root.clone());
    assert_eq!(tree.preorder().len(), m.control.labels.len());
    assert_eq!(
        m.control.recoveries,
        [Recovery {
            node: 2,
            of: "find-wall".into(),
            recovery: "back-off".into(),
            actions: vec![1],
        }]
    );
}

#[test]
fn a_built_tree_runs_the_recovery_between_a_failure_and_the_next_attempt() {
    let m = mission(EVERY_CONSTRUCT);
    let mut tree = Tree::new(m.control.root.clone());
    let powered = m.initial.0;
    let t = tree.tick(powered, secs(0));
    assert_eq!(t.commands, [Command::Start(0)], "find-wall");
    tree.leaf_ended(0, false);
    assert_eq!(
        tree.tick(powered, secs(1)).commands,
        [Command::Start(1)],
        "back-off"
    );
    tree.leaf_ended(1, true);
    let t = tree.tick(powered, secs(2));
    assert_eq!((t.commands, t.wake), (vec![], Some(secs(4))), "the backoff");
    assert_eq!(
        tree.tick(powered, secs(4)).commands,
        [Command::Start(0)],
        "attempt 2"
    );
    // attempt 2 outlives its timeout: halted, then recovered from again
    let t = tree.tick(powered, secs(44));
    assert_eq!(t.commands, [Command::Halt(0), Command::Start(1)]);
    assert_eq!(t.status, Status::Running);
}

#[test]
fn a_recovery_used_twice_is_in_the_tree_twice_and_a_guard_keeps_its_when() {
    let m = mission(&format!(
        "{HEAD}[[action]]\nname = \"a\"\non_failure = \"back\"\n[action.ops.ultrasonic]\n\
         [[action]]\nname = \"b\"\non_failure = \"back\"\n[action.ops.wall-sensor]\n\
         [[action]]\nname = \"back\"\nwhen = [\"wall-found\"]\n[action.ops.reverse]\n"
    ));
    let recover = |i| Node::Recover {
        child: Box::new(Node::Action(i)),
        recovery: Box::new(Node::Sequence(vec![Node::Condition(0b10), Node::Action(2)])),
    };
    assert_eq!(
        m.control.root,
        Node::Schedule(vec![
            Scheduled {
                when: 0,
                node: recover(0)
            },
            Scheduled {
                when: 0,
                node: recover(1)
            },
        ])
    );
    let of: Vec<(&str, &str, usize)> = m
        .control
        .recoveries
        .iter()
        .map(|r| (r.of.as_str(), r.recovery.as_str(), r.node))
        .collect();
    assert_eq!(of, [("a", "back", 1), ("b", "back", 6)]);
}

/// A catalog with every operation `parsed` names, each taking the parameters it supplies
/// (by their type) and raising every flag of the mission.
fn accepting(parsed: &ParsedMission) -> StaticCatalog {
    let flags: Vec<FlagDecl> = parsed
        .flags()
        .keys()
        .map(|f| FlagDecl::new(f, ""))
        .collect();
    StaticCatalog::new(parsed.ops().enumerate().map(|(i, key)| {
        let mut decls: Vec<ParamDecl> = Vec::new();
        for supplied in parsed.need(key).supplied {
            for (name, value) in supplied {
                if decls.iter().any(|d| d.name == name) {
                    continue;
                }
                decls.push(match value {
                    Value::Float(_) => ParamDecl::float(name, 0.0),
                    Value::Int(_) => ParamDecl::int(name, 0),
                    Value::Bool(_) => ParamDecl::bool(name, false),
                    _ => ParamDecl::text(name, ""),
                });
            }
        }
        OpInfo::new(key, 2000 + i as u32, "1.0.0")
            .params(ParamSchema::new(decls))
            .flags(flags.clone())
    }))
}

#[test]
fn a_mission_without_control_keys_is_the_thesis_schedule() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../missions/docking.toml");
    let parsed = ParsedMission::parse_file(&path).unwrap_or_else(|d| panic!("{d}"));
    let m = parsed
        .validate(&accepting(&parsed))
        .unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(m.actions.len(), 4);
    assert_eq!(m.control, Control::thesis(&m.actions));
    assert!(m.control.is_thesis());
    assert!(m.control.recoveries.is_empty());
    // and as JSON, a thesis control says nothing of recoveries
    let json = serde_json::to_value(&m.control).unwrap_or_default();
    assert!(json.get("recoveries").is_none(), "{json}");
}

//! What the dispatcher would do with a mission now, without running it — what
//! `marie check` shows: for every operation the choice among its live instances (asked
//! through their property interface, chosen by [`selection`](super::selection)), which
//! operation raises each condition flag the mission waits for, and how many control
//! details the mission supplies against how many it leaves at their declared defaults.
//!
//! The thesis counted control details to show what self-configuration saves the operator:
//! the fewer a mission must spell out, the more the system decides by itself.

use super::candidates::select;
use super::mission::Mission;
use crate::eo::EoClient;
use marie_vocabulary::run::Choice;
use serde::{Deserialize, Serialize};

/// The dispatcher's view of a mission before it runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Survey {
    /// The choice for each operation the mission uses, in order of first use.
    pub choices: Vec<Choice>,
    /// Each flag a condition or the success set waits for, and where it comes from.
    pub flags: Vec<FlagSource>,
    /// Control details: parameter values the mission supplies, and those it leaves at the
    /// defaults the chosen instances declare (counted per action that runs the operation).
    pub control_details: ControlDetails,
}

/// Where a flag the mission waits for comes from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FlagSource {
    /// The flag's name.
    pub flag: String,
    /// What waits for it: `success`, or `action NAME`.
    pub needed_by: Vec<String>,
    /// The operations of the mission whose chosen instance declares it can raise it.
    pub raised_by: Vec<String>,
    /// Whether `mission.initial` sets it.
    pub initial: bool,
}

impl FlagSource {
    /// Whether something sets it: an operation that raises it, or the initial word.
    pub fn is_raised(&self) -> bool {
        self.initial || !self.raised_by.is_empty()
    }
}

/// How many parameter values the mission supplies and how many come from declared defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControlDetails {
    /// Values the mission's actions supply.
    pub supplied: usize,
    /// Parameters the chosen instances declare that the mission leaves at their default.
    pub defaulted: usize,
}

impl Survey {
    /// Whether every operation has an instance to run it.
    pub fn all_chosen(&self) -> bool {
        self.choices.iter().all(|c| c.chosen().is_some())
    }
}

/// Survey `mission` against the live registry: every instance of every operation it uses
/// asked for its properties, and chosen among as the dispatcher would choose now.
pub async fn survey(mission: &Mission) -> Survey {
    let mut choices = Vec::new();
    for name in mission.operation_names() {
        choices.push(
            select(&mission.need(name), EoClient::DEFAULT_TIMEOUT)
                .await
                .1,
        );
    }
    tell(mission, choices)
}

/// The survey of `mission` for `choices` already made.
pub fn tell(mission: &Mission, choices: Vec<Choice>) -> Survey {
    Survey {
        flags: flag_sources(mission, &choices),
        control_details: control_details(mission, &choices),
        choices,
    }
}

fn flag_sources(mission: &Mission, choices: &[Choice]) -> Vec<FlagSource> {
    let mut out: Vec<FlagSource> = Vec::new();
    let mut wait = |bits: marie_vocabulary::status::StatusFlags, by: String| {
        for bit in bits.bits() {
            let Some(flag) = mission.flag_name(bit) else {
                continue;
            };
            match out.iter_mut().find(|s| s.flag == flag) {
                Some(s) => s.needed_by.push(by.clone()),
                None => out.push(FlagSource {
                    flag: flag.to_string(),
                    needed_by: vec![by.clone()],
                    raised_by: Vec::new(),
                    initial: mission.initial.has_bit(bit),
                }),
            }
        }
    };
    wait(mission.success, "success".to_string());
    for a in &mission.actions {
        wait(a.when, format!("action {}", a.name));
    }
    for source in &mut out {
        source.raised_by = choices
            .iter()
            .filter(|c| {
                c.chosen()
                    .is_some_and(|chosen| chosen.flags.contains(&source.flag))
            })
            .map(|c| c.operation.clone())
            .collect();
    }
    out
}

fn control_details(mission: &Mission, choices: &[Choice]) -> ControlDetails {
    let mut count = ControlDetails::default();
    for choice in choices {
        let Some(chosen) = choice.chosen() else {
            continue;
        };
        for op in mission.actions.iter().flat_map(|a| &a.ops) {
            if op.name == choice.operation {
                count.supplied += op.params.len();
                count.defaulted += chosen
                    .schema
                    .iter()
                    .filter(|p| !op.params.contains_key(*p))
                    .count();
            }
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dispatcher::mission::{Catalog, OpInfo, ParsedMission};
    use crate::dispatcher::selection::{choose, Offer};
    use marie_vocabulary::property::{ParamDecl, ParamSchema};
    use marie_vocabulary::status::FlagDecl;

    struct Ops(Vec<OpInfo>);

    impl Catalog for Ops {
        fn operation(&self, key: &str) -> Option<OpInfo> {
            self.0.iter().find(|o| o.name == key).cloned()
        }
        fn names(&self) -> Vec<String> {
            self.0.iter().map(|o| o.name.clone()).collect()
        }
    }

    const MISSION: &str = r#"
[mission]
name = "survey"
initial = ["ready"]
success = ["done"]

[flags]
found = 0
done = 1
ready = 2

[[action]]
name = "look"
when = ["ready"]
ends_on = ["finder"]
[action.ops.finder]
range = 2.0

[[action]]
name = "finish"
when = ["found"]
ends_on = ["finisher"]
[action.ops.finisher]
"#;

    fn ops() -> Vec<OpInfo> {
        vec![
            OpInfo::new("finder", 1, "1.0.0")
                .params(ParamSchema::new(vec![
                    ParamDecl::float("range", 1.0),
                    ParamDecl::float("speed", 0.2),
                ]))
                .flags(vec![FlagDecl::new("found", "")]),
            OpInfo::new("finisher", 2, "1.0.0")
                .params(ParamSchema::new(vec![ParamDecl::float("gain", 1.0)]))
                .flags(vec![FlagDecl::new("done", "")]),
        ]
    }

    fn surveyed() -> Survey {
        let ops = ops();
        let mission = ParsedMission::parse(MISSION, None)
            .unwrap()
            .validate(&Ops(ops.clone()))
            .unwrap();
        let choices = ops
            .iter()
            .map(|o| {
                let offer = Offer::new("0.1", "n1", o.clone());
                choose(&mission.need(&o.name), &[offer], "n1")
            })
            .collect();
        tell(&mission, choices)
    }

    #[test]
    fn each_awaited_flag_names_the_operations_that_raise_it_or_the_initial_word() {
        let s = surveyed();
        let by_flag = |f: &str| s.flags.iter().find(|x| x.flag == f).unwrap().clone();
        assert_eq!(by_flag("done").raised_by, ["finisher"]);
        assert_eq!(by_flag("done").needed_by, ["success"]);
        assert_eq!(by_flag("found").raised_by, ["finder"]);
        assert_eq!(by_flag("found").needed_by, ["action finish"]);
        let ready = by_flag("ready");
        assert!(ready.initial && ready.raised_by.is_empty() && ready.is_raised());
    }

    #[test]
    fn control_details_count_supplied_values_and_declared_defaults_left_alone() {
        // finder: range supplied, speed defaulted; finisher: gain defaulted
        assert_eq!(
            surveyed().control_details,
            ControlDetails {
                supplied: 1,
                defaulted: 2
            }
        );
    }
}

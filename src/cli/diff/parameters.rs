//! The parameter values two runs' operations ran with ([`Provenance::parameters`]), compared
//! per action, operation and parameter.
//!
//! A value the mission gave and one the operation's default gave are one parameter set at
//! the action's start: a value added to the mission shows as `0.5 (default) -> 0.7
//! (mission)`, one change, not as one value gone and another come. A re-parameterization
//! while the run went on is kept apart, with its time: it is not the run's input but what
//! someone did to it.

use super::aspects::{secs, Difference};
use marie::run::{ParamSetting, ParamSource, Provenance};
use serde_json::json;

/// A parameter of an action's operation, set at the action's start or re-set later.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Key {
    action: String,
    operation: String,
    name: String,
    reparameterized: bool,
}

impl Key {
    fn of(s: &ParamSetting) -> Key {
        Key {
            action: s.action.clone(),
            operation: s.operation.clone(),
            name: s.name.clone(),
            reparameterized: s.source == ParamSource::Reparameterized,
        }
    }

    /// `action/operation.name` (`operation.name` for a re-parameterization between actions).
    fn label(&self) -> String {
        match self.action.is_empty() {
            true => format!("{}.{}", self.operation, self.name),
            false => format!("{}/{}.{}", self.action, self.operation, self.name),
        }
    }
}

/// A value and where it came from: `0.8 (mission)`, `0.9 (reparameterized at 12.000 s)`.
fn setting_text(s: &ParamSetting) -> String {
    match s.at_ms {
        Some(at) => format!("{} ({} at {})", s.value, s.source, secs(at)),
        None => format!("{} ({})", s.value, s.source),
    }
}

/// Every parameter of `p` with its values' texts, in the order first set (an action run
/// again with other values, or re-set several times, has several).
fn values(p: &Provenance) -> Vec<(Key, Vec<String>)> {
    let mut out: Vec<(Key, Vec<String>)> = Vec::new();
    for s in &p.parameters {
        let (key, text) = (Key::of(s), setting_text(s));
        match out.iter_mut().find(|(k, _)| *k == key) {
            Some((_, texts)) => texts.push(text),
            None => out.push((key, vec![text])),
        }
    }
    out
}

/// The parameters whose values differ, and those only one run set; `None` when every
/// parameter has the same values from the same sources.
pub(crate) fn compare(a: &Provenance, b: &Provenance) -> Option<Difference> {
    let (va, vb) = (values(a), values(b));
    let mut diff = Difference::default();
    let mut json = Vec::new();
    let (mut changed, mut only_a, mut only_b) = (0, 0, 0);
    for (key, ta) in &va {
        let label = key.label();
        match vb.iter().find(|(k, _)| k == key) {
            Some((_, tb)) if tb == ta => {}
            Some((_, tb)) => {
                changed += 1;
                let (ta, tb) = (ta.join(", "), tb.join(", "));
                diff.lines.push(format!("  {label}: {ta} -> {tb}"));
                json.push(json!({"parameter": label, "a": ta, "b": tb}));
            }
            None => {
                only_a += 1;
                let ta = ta.join(", ");
                diff.lines.push(format!("  only in a: {label} = {ta}"));
                json.push(json!({"parameter": label, "a": ta, "b": null}));
            }
        }
    }
    for (key, tb) in vb.iter().filter(|(k, _)| !va.iter().any(|(ka, _)| ka == k)) {
        only_b += 1;
        let (label, tb) = (key.label(), tb.join(", "));
        diff.lines.push(format!("  only in b: {label} = {tb}"));
        json.push(json!({"parameter": label, "a": null, "b": tb}));
    }
    let summary: Vec<String> = [
        (changed, "changed"),
        (only_a, "only in a"),
        (only_b, "only in b"),
    ]
    .iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, what)| format!("{n} {what}"))
    .collect();
    if summary.is_empty() {
        return None;
    }
    diff.summary = summary.join(", ");
    diff.json = json.into();
    Some(diff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::property::Value;

    fn set(action: &str, op: &str, name: &str, value: Value, source: ParamSource) -> ParamSetting {
        ParamSetting {
            action: action.into(),
            operation: op.into(),
            name: name.into(),
            value,
            source,
            at_ms: None,
        }
    }

    fn provenance(parameters: Vec<ParamSetting>) -> Provenance {
        Provenance {
            parameters,
            ..Provenance::default()
        }
    }

    #[test]
    fn a_changed_value_is_shown_with_its_source_on_both_sides() {
        let a = provenance(vec![
            set(
                "follow-wall",
                "wall-follower",
                "distance",
                Value::Float(0.8),
                ParamSource::Mission,
            ),
            set(
                "park",
                "trajectory-controller",
                "speed",
                Value::Float(0.3),
                ParamSource::Mission,
            ),
        ]);
        let b = provenance(vec![
            set(
                "follow-wall",
                "wall-follower",
                "distance",
                Value::Float(0.9),
                ParamSource::Mission,
            ),
            set(
                "park",
                "trajectory-controller",
                "speed",
                Value::Float(0.3),
                ParamSource::Mission,
            ),
        ]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "1 changed");
        assert_eq!(
            diff.lines,
            vec!["  follow-wall/wall-follower.distance: 0.8 (mission) -> 0.9 (mission)"]
        );
        assert_eq!(diff.json[0]["b"], "0.9 (mission)");
        assert!(compare(&a, &a).is_none());
    }

    #[test]
    fn a_default_the_mission_now_gives_is_one_change_of_value_and_source() {
        let a = provenance(vec![set(
            "a",
            "op",
            "gain",
            Value::Float(0.5),
            ParamSource::Default,
        )]);
        let b = provenance(vec![set(
            "a",
            "op",
            "gain",
            Value::Float(0.7),
            ParamSource::Mission,
        )]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(
            diff.lines,
            vec!["  a/op.gain: 0.5 (default) -> 0.7 (mission)"]
        );
    }

    #[test]
    fn values_only_one_run_set_and_re_parameterizations_are_told_apart() {
        let mut later = set(
            "",
            "wall-follower",
            "distance",
            Value::Float(0.9),
            ParamSource::Reparameterized,
        );
        later.at_ms = Some(12_000);
        let a = provenance(vec![
            set(
                "a",
                "op",
                "mode",
                Value::Text("cruise".into()),
                ParamSource::Mission,
            ),
            later,
        ]);
        let b = provenance(vec![set(
            "a",
            "op",
            "x",
            Value::Int(1),
            ParamSource::Default,
        )]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "2 only in a, 1 only in b");
        assert_eq!(
            diff.lines,
            vec![
                "  only in a: a/op.mode = \"cruise\" (mission)",
                "  only in a: wall-follower.distance = 0.9 (reparameterized at 12.000 s)",
                "  only in b: a/op.x = 1 (default)",
            ]
        );
    }
}

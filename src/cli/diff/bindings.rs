//! Which instances two runs bound their operations to, and how they rebound them: per
//! operation the versions and nodes it ran on (from the actions' records and the selection's
//! choices), and the rebinds with their causes.
//!
//! Addresses are left out of the comparison: a restarted instance has a new one, and the
//! question is whether the run used another version or node, or lost an instance.

use super::aspects::{Difference, Side};
use marie::report::RunReport;
use marie::run::RebindRecord;
use serde_json::json;

/// Per operation, the instances it was bound to as `VERSION on NODE`, each once, in the
/// order first bound.
fn bound(r: &RunReport) -> Vec<(String, Vec<String>)> {
    let chosen = r.selection.iter().filter_map(|c| {
        c.chosen()
            .map(|i| (c.operation.as_str(), format!("{} on {}", i.version, i.node)))
    });
    let ran = r
        .actions
        .iter()
        .flat_map(|a| &a.operations)
        .map(|o| (o.name.as_str(), format!("{} on {}", o.version, o.node)));
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    for (op, instance) in chosen.chain(ran) {
        match out.iter_mut().find(|(name, _)| name == op) {
            Some((_, instances)) if instances.contains(&instance) => {}
            Some((_, instances)) => instances.push(instance),
            None => out.push((op.to_string(), vec![instance])),
        }
    }
    out
}

/// What a rebind is to the comparison: the operation, why, from which node to which.
fn rebind_key(r: &RebindRecord) -> String {
    format!("{} {} {} {}", r.operation, r.cause, r.from_node, r.to_node)
}

/// A rebind as a line: `wall-follower: died: its actor is gone; 0.18 -> 0.28 on embedded`.
fn rebind_text(r: &RebindRecord) -> String {
    let at = |address: &str, node: &str| match node.is_empty() {
        true => address.to_string(),
        false => format!("{address} on {node}"),
    };
    let moved = match r.from_node == r.to_node {
        true => format!("{} -> {}", r.from, at(&r.to, &r.to_node)),
        false => format!("{} -> {}", at(&r.from, &r.from_node), at(&r.to, &r.to_node)),
    };
    format!("{}: {}; {moved}", r.operation, r.cause)
}

/// The operations bound to other versions or nodes, those only one run bound, and the
/// rebinds when they differ; `None` when both runs bound and rebound alike.
pub(crate) fn compare(a: &RunReport, b: &RunReport) -> Option<Difference> {
    let (ba, bb) = (bound(a), bound(b));
    let mut diff = Difference::default();
    let mut summary = Vec::new();
    let mut ops = serde_json::Map::new();
    let text = |i: &[String]| i.join(", then ");
    for (op, ia) in &ba {
        match bb.iter().find(|(name, _)| name == op) {
            Some((_, ib)) if ib == ia => {}
            Some((_, ib)) => {
                diff.lines
                    .push(format!("  {op}: {} -> {}", text(ia), text(ib)));
                summary.push(op.clone());
                ops.insert(op.clone(), json!({"a": ia, "b": ib}));
            }
            None => {
                diff.lines.push(format!("  only in a: {op}: {}", text(ia)));
                summary.push(format!("{op} only in a"));
                ops.insert(op.clone(), json!({"a": ia, "b": null}));
            }
        }
    }
    for (op, ib) in bb.iter().filter(|(op, _)| !ba.iter().any(|(o, _)| o == op)) {
        diff.lines.push(format!("  only in b: {op}: {}", text(ib)));
        summary.push(format!("{op} only in b"));
        ops.insert(op.clone(), json!({"a": null, "b": ib}));
    }
    let keys = |r: &RunReport| r.rebinds.iter().map(rebind_key).collect::<Vec<_>>();
    let mut json = json!({});
    if a.rebinds_total != b.rebinds_total || keys(a) != keys(b) {
        summary.push(format!(
            "rebinds {} -> {}",
            a.rebinds_total, b.rebinds_total
        ));
        diff.lines.push(format!(
            "  rebinds: {} -> {}",
            a.rebinds_total, b.rebinds_total
        ));
        for (side, r) in [(Side::A, a), (Side::B, b)] {
            if r.rebinds.is_empty() {
                diff.lines.push(format!("    {side}: none"));
            }
            for rebind in &r.rebinds {
                diff.lines
                    .push(format!("    {side}: {}", rebind_text(rebind)));
            }
        }
        json["rebinds"] = json!({
            "a": {"total": a.rebinds_total, "rebinds": a.rebinds},
            "b": {"total": b.rebinds_total, "rebinds": b.rebinds},
        });
    }
    if summary.is_empty() {
        return None;
    }
    if !ops.is_empty() {
        json["operations"] = ops.into();
    }
    diff.summary = summary.join(", ");
    diff.json = json;
    Some(diff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::report::{ActionRecord, OpRecord};
    use marie::run::{LossCause, OpEnd, Outcome};

    fn op(name: &str, version: &str, address: &str) -> OpRecord {
        OpRecord {
            name: name.into(),
            id: 1514,
            version: version.into(),
            node: "embedded".into(),
            address: address.into(),
            ended: OpEnd::Finished,
            flags: Vec::new(),
        }
    }

    fn report(ops: Vec<OpRecord>) -> RunReport {
        let mut r = RunReport::new("docking", Outcome::Succeeded, "");
        r.actions.push(ActionRecord {
            name: "follow-wall".into(),
            start_ms: 0,
            end_ms: 1,
            flags: Vec::new(),
            status: 0,
            operations: ops,
        });
        r
    }

    #[test]
    fn another_version_of_an_operation_is_a_change_of_its_binding() {
        let a = report(vec![op("wall-follower", "1.0.0", "0.18")]);
        let b = report(vec![op("wall-follower", "2.0.0", "0.19")]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "wall-follower");
        assert_eq!(
            diff.lines,
            vec!["  wall-follower: 1.0.0 on embedded -> 2.0.0 on embedded"]
        );
        assert_eq!(
            diff.json["operations"]["wall-follower"]["b"][0],
            "2.0.0 on embedded"
        );
    }

    #[test]
    fn a_rebind_is_a_difference_but_a_new_address_alone_is_not() {
        let a = report(vec![op("wall-follower", "1.0.0", "0.18")]);
        let mut b = report(vec![op("wall-follower", "1.0.0", "0.28")]);
        assert_eq!(compare(&a, &b), None, "the same version on the same node");
        b.record_rebind(RebindRecord {
            operation: "wall-follower".into(),
            cause: LossCause::Gone,
            from: "0.18".into(),
            to: "0.28".into(),
            from_node: "embedded".into(),
            to_node: "embedded".into(),
            downtime_ms: 0,
            epoch: 2,
        });
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "rebinds 0 -> 1");
        assert_eq!(
            diff.lines,
            vec![
                "  rebinds: 0 -> 1",
                "    a: none",
                "    b: wall-follower: died: its actor is gone; 0.18 -> 0.28 on embedded",
            ]
        );
        assert_eq!(compare(&b, &b), None);
    }

    #[test]
    fn an_operation_only_one_run_bound_is_named_with_its_side() {
        let a = report(vec![op("wall-follower", "1.0.0", "0.18")]);
        let b = report(vec![
            op("wall-follower", "1.0.0", "0.18"),
            op("path-planner", "1.0.0", "0.16"),
        ]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(
            diff.lines,
            vec!["  only in b: path-planner: 1.0.0 on embedded"]
        );
    }
}

//! Stage 2: a [`ParsedMission`] checked against the operations a [`Catalog`] offers.

use super::parsed::{GroupKind, Item, ParsedOp, ParsedParam};
use super::{Action, Catalog, Mission, OpInfo, OpRun, ParsedMission};
use marie_vocabulary::diagnostic::toml::{name_list, quote};
use marie_vocabulary::diagnostic::{Diagnostic, Diagnostics};
use marie_vocabulary::property::{ParamMap, RejectReason};
use marie_vocabulary::status::StatusFlags;
use std::collections::{BTreeMap, BTreeSet};

/// Stage 2 entry point.
pub(crate) fn validate<C: Catalog + ?Sized>(
    pm: &ParsedMission,
    catalog: &C,
) -> Result<Mission, Diagnostics> {
    let mut v = Validator {
        file: &pm.file,
        catalog,
        diags: Vec::new(),
        resolved: BTreeMap::new(),
        available: None,
        all_resolved: true,
        raised: BTreeSet::new(),
        op_flags: BTreeMap::new(),
    };
    let mut actions = Vec::new();
    for a in &pm.actions {
        let mut ops = Vec::new();
        // canonical operation name -> key it was first written as, in this action
        let mut seen: BTreeMap<String, &str> = BTreeMap::new();
        for op in &a.ops {
            let Some(info) = v.resolve(op) else { continue };
            match seen.get(&info.name) {
                Some(first) => {
                    let msg = format!(
                        "operation {} appears twice in action {} (as {} and {}; an operation runs once per action)",
                        quote(&info.name),
                        quote(&a.name),
                        quote(first),
                        quote(&op.key)
                    );
                    v.diags.push(Diagnostic::at(v.file, op.at, msg));
                }
                None => {
                    seen.insert(info.name.clone(), &op.key);
                }
            }
            v.raised.extend(info.flags.iter().map(|f| f.name.clone()));
            v.op_flags
                .entry(info.name.clone())
                .or_insert_with(|| info.flags.iter().map(|f| f.name.clone()).collect());
            let params = v.params(op, &info);
            ops.push(OpRun {
                key: op.key.clone(),
                name: info.name.clone(),
                id: info.id,
                params,
            });
        }
        actions.push(Action {
            name: a.name.clone(),
            when: bits(a.when.iter().map(|r| r.bit)),
            ops,
            ends_on: a.ends_on.clone(),
            end_mode: a.end_mode,
            deadline: a.deadline,
        });
    }
    v.check_raisable(pm);
    v.check_parallels(pm, &actions);
    v.check_waits(pm, &actions);
    let requires = named_ops(&mut v, &actions, &pm.requires, "[requires]");
    let pins = named_ops(&mut v, &actions, &pm.pins, "[pin]");
    let mission = Mission {
        name: pm.name.clone(),
        description: pm.description.clone(),
        path: pm.path.clone(),
        flags: pm.flags.clone(),
        initial: bits(pm.initial.iter().map(|r| r.bit)),
        success: bits(pm.success.iter().map(|r| r.bit)),
        deadline: pm.deadline,
        rebind_deadline: pm.rebind_deadline.unwrap_or(super::DEFAULT_REBIND_DEADLINE),
        control: super::control::build(pm, &actions),
        actions,
        world: pm.world.clone(),
        requires,
        pins,
        checked: Default::default(),
    };
    Diagnostics(v.diags)
        .into_result(mission)
        .map(|mut mission| {
            // what a check against the running instances chose, for the dispatcher to bind
            mission.checked = catalog.checked(&mission);
            mission
        })
}

fn bits(bits: impl Iterator<Item = u8>) -> StatusFlags {
    bits.filter_map(StatusFlags::bit)
        .fold(StatusFlags::EMPTY, |acc, b| acc | b)
}

/// The version requirements of `table` (`[requires]`, `[pin]`) by operation name; an entry
/// naming an operation no action runs is an error.
fn named_ops<C: Catalog + ?Sized>(
    v: &mut Validator<'_, C>,
    actions: &[Action],
    entries: &[(String, semver::VersionReq, super::Pos)],
    table: &str,
) -> BTreeMap<String, semver::VersionReq> {
    let mut out = BTreeMap::new();
    for (key, req, at) in entries {
        let op = actions
            .iter()
            .flat_map(|a| a.ops.iter())
            .find(|o| &o.key == key || &o.name == key);
        match op {
            Some(op) => {
                out.insert(op.name.clone(), req.clone());
            }
            None => v.diags.push(Diagnostic::at(
                v.file,
                *at,
                format!("`{table}` names operation `{key}`, which no action runs"),
            )),
        }
    }
    out
}

struct Validator<'a, C: ?Sized> {
    file: &'a str,
    catalog: &'a C,
    diags: Vec<Diagnostic>,
    /// Catalog answers by key, so each key is asked once.
    resolved: BTreeMap<String, Option<OpInfo>>,
    /// `catalog.names()`, sorted, asked only when a key is unknown.
    available: Option<Vec<String>>,
    /// False once an operation is unknown: its flags are unknown too.
    all_resolved: bool,
    /// Names of the flags the mission's operations declare.
    raised: BTreeSet<String>,
    /// The flags each operation of the mission declares, by canonical name.
    op_flags: BTreeMap<String, BTreeSet<String>>,
}

impl<C: Catalog + ?Sized> Validator<'_, C> {
    fn resolve(&mut self, op: &ParsedOp) -> Option<OpInfo> {
        let catalog = self.catalog;
        let info = self
            .resolved
            .entry(op.key.clone())
            .or_insert_with(|| catalog.operation(&op.key))
            .clone();
        if info.is_none() {
            self.all_resolved = false;
            let names = self.available.get_or_insert_with(|| {
                let mut names = catalog.names();
                names.sort();
                names.dedup();
                names
            });
            let msg = if names.is_empty() {
                format!(
                    "unknown operation {} (no operations are available)",
                    quote(&op.key)
                )
            } else {
                format!(
                    "unknown operation {} (available: {})",
                    quote(&op.key),
                    name_list(names.iter())
                )
            };
            self.diags.push(Diagnostic::at(self.file, op.at, msg));
        }
        info
    }

    /// The supplied parameters of `op`, checked and canonicalized; problems are reported.
    fn params(&mut self, op: &ParsedOp, info: &OpInfo) -> ParamMap {
        let mut out = ParamMap::new();
        for p in &op.params {
            if let Some(v) = self.param(p, info) {
                out.insert(p.name.clone(), v);
            }
        }
        out
    }

    fn param(
        &mut self,
        p: &ParsedParam,
        info: &OpInfo,
    ) -> Option<marie_vocabulary::property::Value> {
        // a name an older version used, which this one's migrations rename: checked as the
        // parameter it became (and sent under that name, see `Migrations::apply`)
        let renamed = || {
            let r = info.migrations.renames.iter().find(|r| r.from == p.name)?;
            info.schema.get(&r.to)
        };
        let Some(decl) = info.schema.get(&p.name).or_else(renamed) else {
            let hint = if info.schema.is_empty() {
                format!("operation {} has no parameters", quote(&info.name))
            } else {
                format!(
                    "expected one of: {}",
                    name_list(info.schema.params.iter().map(|d| d.name.as_str()))
                )
            };
            let msg = format!(
                "unknown parameter {} of operation {} ({hint})",
                quote(&p.name),
                quote(&info.name)
            );
            self.diags.push(Diagnostic::at(self.file, p.at, msg));
            return None;
        };
        if decl.read_only {
            let msg = format!(
                "parameter {} of operation {} is read-only: a mission may not set it",
                quote(&p.name),
                quote(&info.name)
            );
            self.diags.push(Diagnostic::at(self.file, p.at, msg));
            return None;
        }
        match decl.check(&p.name, &p.value) {
            Ok(v) => Some(v),
            Err(r) => {
                let at = p
                    .value_at
                    .get(&r.name)
                    .or_else(|| p.value_at.get(&p.name))
                    .copied()
                    .unwrap_or(p.at);
                let reason = match &r.reason {
                    RejectReason::UnknownName => "unknown field".to_string(),
                    other => other.to_string(),
                };
                let msg = if r.name == p.name {
                    format!(
                        "invalid value for parameter {} of operation {}: {reason}",
                        quote(&p.name),
                        quote(&info.name)
                    )
                } else {
                    format!(
                        "invalid value for parameter {} of operation {}: {}: {reason}",
                        quote(&p.name),
                        quote(&info.name),
                        quote(&r.name)
                    )
                };
                self.diags.push(Diagnostic::at(self.file, at, msg));
                None
            }
        }
    }

    /// Every flag a condition or the success set needs must be set initially or raised by
    /// some operation of the mission. Skipped when an operation is unknown: what it raises is
    /// unknown too, and it has been reported already.
    fn check_raisable(&mut self, pm: &ParsedMission) {
        if !self.all_resolved {
            return;
        }
        let initial: BTreeSet<&str> = pm.initial.iter().map(|r| r.name.as_str()).collect();
        let needed = pm
            .success
            .iter()
            .chain(
                pm.actions
                    .iter()
                    .flat_map(|a| a.when.iter().chain(&a.control.while_)),
            )
            .chain(
                pm.groups
                    .iter()
                    .flat_map(|g| g.when.iter().chain(&g.control.while_)),
            );
        let raised: Vec<&str> = self
            .raised
            .iter()
            .filter(|n| pm.flags.contains_key(n.as_str()))
            .map(String::as_str)
            .collect();
        for r in needed {
            if initial.contains(r.name.as_str()) || self.raised.contains(&r.name) {
                continue;
            }
            let hint = if raised.is_empty() {
                "they raise none of the mission's flags".to_string()
            } else {
                format!("they raise: {}", name_list(&raised))
            };
            let msg = format!(
                "flag {} is never raised by any operation of this mission, nor set in `mission.initial` (needed by `{}`; {hint})",
                quote(&r.name),
                r.field
            );
            self.diags.push(Diagnostic::at(self.file, r.at, msg));
        }
    }

    /// The children of a parallel group run at once: no two of them may run one operation
    /// (each runs for one action at a time).
    fn check_parallels(&mut self, pm: &ParsedMission, actions: &[Action]) {
        for g in &pm.groups {
            if g.kind != GroupKind::Parallel {
                continue;
            }
            let ops: Vec<BTreeSet<&str>> = g
                .children
                .iter()
                .map(|c| {
                    pm.reach(c.item)
                        .into_iter()
                        .filter_map(|a| actions.get(a))
                        .flat_map(|a| a.ops.iter().map(|o| o.name.as_str()))
                        .collect()
                })
                .collect();
            for (j, later) in g.children.iter().enumerate() {
                for (i, earlier) in g.children[..j].iter().enumerate() {
                    let shared: Vec<&str> = ops[i].intersection(&ops[j]).copied().collect();
                    if shared.is_empty() {
                        continue;
                    }
                    let what = if shared.len() == 1 {
                        format!("operation {}", quote(shared[0]))
                    } else {
                        let all: Vec<String> = shared.iter().map(|o| quote(o)).collect();
                        format!("operations {}", all.join(", "))
                    };
                    let msg = format!(
                        "children {} and {} of parallel {} both run {what} (they would run at once, and an operation runs for one action at a time)",
                        quote(pm.item_name(earlier.item)),
                        quote(pm.item_name(later.item)),
                        quote(&g.name)
                    );
                    self.diags.push(Diagnostic::at(self.file, later.at, msg));
                }
            }
        }
    }

    /// A top-level item may not wait (`when`) for a flag that only the operations of its
    /// own tree raise: they run only once it started, so it would wait forever. Skipped
    /// when an operation is unknown (what it raises is unknown too), and for a mission
    /// without control keys: the thesis' mission keeps its meaning, such a wait a failure
    /// the run reports ("no runnable action").
    fn check_waits(&mut self, pm: &ParsedMission, actions: &[Action]) {
        if !self.all_resolved || !pm.has_control() {
            return;
        }
        let initial: BTreeSet<&str> = pm.initial.iter().map(|r| r.name.as_str()).collect();
        for item in pm.roots() {
            let own = pm.reach(item);
            for f in pm.item_when(item) {
                if initial.contains(f.name.as_str()) {
                    continue;
                }
                // (action, operation) of every operation that raises it
                let raisers: Vec<(usize, &str)> = actions
                    .iter()
                    .enumerate()
                    .flat_map(|(i, a)| a.ops.iter().map(move |o| (i, o.name.as_str())))
                    .filter(|(_, o)| self.op_flags.get(*o).is_some_and(|fl| fl.contains(&f.name)))
                    .collect();
                if raisers.is_empty() || !raisers.iter().all(|(a, _)| own.contains(a)) {
                    continue;
                }
                let mut by: Vec<String> = raisers
                    .iter()
                    .map(|(a, o)| match item {
                        Item::Action(_) => quote(o),
                        Item::Group(_) => format!("{} in {}", quote(o), quote(&actions[*a].name)),
                    })
                    .collect();
                by.dedup();
                let whose = match item {
                    Item::Action(_) => "its own operations",
                    Item::Group(_) => "operations run inside it",
                };
                let msg = format!(
                    "{} waits for flag {}, which only {whose} raise ({}): it would wait for itself forever",
                    pm.describe(item),
                    quote(&f.name),
                    by.join(", ")
                );
                self.diags.push(Diagnostic::at(self.file, f.at, msg));
            }
        }
    }
}

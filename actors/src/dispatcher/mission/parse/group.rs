//! `[[group]]`: actions and groups run as a sequence, a fallback, a parallel (with its
//! thresholds) or a reactive sequence — read, then resolved against the mission's flags and
//! names.

use super::super::parsed::{GroupKind, ParsedGroup};
use super::control_keys::{self, Owner, RawControl};
use super::names::Refs;
use marie_vocabulary::diagnostic::toml::{quote, Reader, Span, Tbl, Val};
use toml::de::DeValue;
use toml::Spanned;

/// The keys a `[[group]]` may have.
const GROUP_KEYS: &[&str] = &[
    "name",
    "kind",
    "children",
    "when",
    "retry",
    "timeout_s",
    "on_failure",
    "while",
    "unless",
    "success",
    "failure",
];

/// One `[[group]]` table, fields typed but not cross-checked.
pub(super) struct RawGroup {
    /// The table (for its place in the file, and missing keys).
    pub(super) at: Span,
    pub(super) name: Option<Spanned<String>>,
    /// `None` when missing or unknown (reported).
    kind: Option<Spanned<GroupKind>>,
    children: Vec<Spanned<String>>,
    when: Vec<Spanned<String>>,
    control: RawControl,
    success: Option<usize>,
    failure: Option<usize>,
}

/// The `[[group]]`s, the value of the file's `group` key.
pub(super) fn read_all(ctx: &mut Reader<'_>, v: &Val<'_>) -> Vec<RawGroup> {
    let Some(items) = ctx.array(v, "an array of tables `[[group]]` for `group`") else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for item in items {
        if let Some(t) = ctx.table_or(item, "`[[group]]`", "a table `[[group]]` for each group") {
            out.push(read(ctx, &t));
        }
    }
    out
}

/// One `[[group]]`: its keys, then what relates them — a reactive group has conditions,
/// thresholds belong to a parallel and count its children.
fn read(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> RawGroup {
    ctx.unknown_keys(t, GROUP_KEYS);
    let name = ctx
        .required(
            t,
            "name",
            "a name for the group, unique among actions and groups, a string",
        )
        .and_then(|v| ctx.non_empty_string(v, "group.name"));
    let label = name
        .as_ref()
        .map_or_else(|| "without a name".to_string(), |n| quote(n.get_ref()));
    // once its name is read, messages name the group by it
    let group = t.named(format!("group {label}"));
    let kind = kind(ctx, &group);
    let children = children(ctx, &group, kind.as_ref(), &label);
    let when = t
        .get("when")
        .and_then(|v| ctx.string_list(v, Owner::Group.fields().when))
        .unwrap_or_default();
    let control = control_keys::read(ctx, t, Owner::Group);
    reactive_has_conditions(ctx, kind.as_ref(), &control, &label);
    let parallel = Parallel {
        kind: kind.as_ref().map(|k| *k.get_ref()),
        children: children.len(),
        label: &label,
    };
    let success = parallel.threshold(ctx, t, "success", "must succeed");
    let failure = parallel.threshold(ctx, t, "failure", "failing make it fail");
    RawGroup {
        at: t.span.clone(),
        name,
        kind,
        children,
        when,
        control,
        success,
        failure,
    }
}

/// `kind`, one of [`GroupKind::NAMES`].
fn kind(ctx: &mut Reader<'_>, group: &Tbl<'_, '_>) -> Option<Spanned<GroupKind>> {
    let v = ctx.required(group, "kind", GroupKind::NAMES)?;
    match v.get_ref() {
        DeValue::String(s) => match GroupKind::parse(s) {
            Some(k) => Some(Spanned::new(v.span(), k)),
            None => {
                ctx.err(
                    &v.span(),
                    format!(
                        "unknown group kind \"{}\" (expected {})",
                        s.escape_debug(),
                        GroupKind::NAMES
                    ),
                );
                None
            }
        },
        _ => ctx.expected(
            v,
            format_args!("a string for `group.kind` ({})", GroupKind::NAMES),
        ),
    }
}

/// `children`: the names of the items it runs, at least one.
fn children(
    ctx: &mut Reader<'_>,
    group: &Tbl<'_, '_>,
    kind: Option<&Spanned<GroupKind>>,
    label: &str,
) -> Vec<Spanned<String>> {
    let Some(v) = ctx.required(
        group,
        "children",
        "the names of the actions and groups it runs, in order",
    ) else {
        return Vec::new();
    };
    let children = ctx.string_list(v, "group.children");
    if children.as_ref().is_some_and(Vec::is_empty) {
        let kind_word = kind.map_or("group", |k| k.get_ref().word());
        ctx.err(
            &v.span(),
            format!(
                "a {kind_word} with no child: group {label} names no action or group in `children`"
            ),
        );
    }
    children.unwrap_or_default()
}

/// A reactive group re-checks `while` and `unless`: it needs one of them.
fn reactive_has_conditions(
    ctx: &mut Reader<'_>,
    kind: Option<&Spanned<GroupKind>>,
    control: &RawControl,
    label: &str,
) {
    let Some(k) = kind else { return };
    if *k.get_ref() == GroupKind::Reactive && control.while_.is_empty() && control.unless.is_empty()
    {
        ctx.err(
            &k.span(),
            format!(
                "reactive group {label} has neither `while` nor `unless` (a reactive group re-checks them while its children run: give at least one)"
            ),
        );
    }
}

/// What a parallel's thresholds (`success`, `failure`) are checked against.
struct Parallel<'l> {
    /// The group's kind, when known.
    kind: Option<GroupKind>,
    /// How many children it names.
    children: usize,
    /// The group in messages.
    label: &'l str,
}

impl Parallel<'_> {
    /// Threshold `key` (how many children `what`): on a parallel only (or a group whose
    /// kind is unknown), an integer from 1 to the number of children.
    fn threshold(
        &self,
        ctx: &mut Reader<'_>,
        t: &Tbl<'_, '_>,
        key: &str,
        what: &str,
    ) -> Option<usize> {
        let (k, v) = t.t.get_key_value(key)?;
        let label = self.label;
        match self.kind {
            Some(GroupKind::Parallel) | None => {}
            Some(other) => {
                ctx.err(
                    &k.span(),
                    format!(
                        "`{key}` applies to a parallel group only (group {label} is a {})",
                        other.word()
                    ),
                );
                return None;
            }
        }
        let x = ctx.int_value(v, &format!("group.{key}"))?;
        let n = self.children;
        if n == 0 {
            return None; // "no child" is reported already
        }
        if let Some(x) = usize::try_from(x).ok().filter(|x| (1..=n).contains(x)) {
            return Some(x);
        }
        let shown = ctx.written(v);
        let expected = if n == 1 {
            "1".to_string()
        } else {
            format!("1 to {n}")
        };
        ctx.err(
            &v.span(),
            format!(
                "`{key}` = {shown} of parallel {label} is out of range (expected {expected}: how many of its {n} {} {what})",
                if n == 1 { "child" } else { "children" }
            ),
        );
        None
    }
}

impl RawGroup {
    /// The group with its flags, control keys and children resolved.
    pub(super) fn resolve(self, ctx: &mut Reader<'_>, refs: &Refs<'_>) -> ParsedGroup {
        let at = self.name.as_ref().map_or(self.at.clone(), Spanned::span);
        let at = ctx.pos(&at);
        let name = self.name.map(Spanned::into_inner);
        let when = refs.flags.refs(ctx, &self.when, Owner::Group.fields().when);
        let control = self
            .control
            .resolve(ctx, refs, Owner::Group, name.as_deref());
        let children = self
            .children
            .iter()
            .filter_map(|c| refs.item(ctx, c, "group.children"))
            .collect::<Vec<_>>();
        let n = self.children.len();
        ParsedGroup {
            name: name.unwrap_or_default(),
            at,
            kind: self.kind.map_or(GroupKind::Sequence, Spanned::into_inner),
            children,
            when,
            control,
            success: self.success.unwrap_or(n),
            failure: self.failure.unwrap_or(1),
        }
    }
}

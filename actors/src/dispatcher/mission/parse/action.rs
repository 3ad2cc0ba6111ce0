//! `[[action]]`: the operations to run together, the flags it waits for, the operations whose
//! end ends it, its deadline and control keys — read, then resolved against the mission's
//! flags and names.

use super::super::parsed::{ParsedAction, ParsedOp};
use super::super::EndMode;
use super::control_keys::{self, Owner, RawControl};
use super::names::Refs;
use super::ops;
use super::seconds::seconds;
use marie_vocabulary::diagnostic::toml::{name_list, quote, Reader, Span, Tbl, Val};
use std::time::Duration;
use toml::de::DeValue;
use toml::Spanned;

/// Deadline of an action that gives no `deadline_s`.
const DEFAULT_ACTION_DEADLINE: Duration = Duration::from_secs(30);

/// The keys an `[[action]]` may have.
const ACTION_KEYS: &[&str] = &[
    "name",
    "when",
    "ends_on",
    "end_mode",
    "deadline_s",
    "ops",
    "retry",
    "timeout_s",
    "on_failure",
    "while",
    "unless",
];

/// What a mission without actions is told.
const NO_ACTIONS: &str = "the mission has no actions (expected at least one `[[action]]`)";

/// One `[[action]]` table, fields typed but not cross-checked.
pub(super) struct RawAction {
    /// The table (for its place in the file).
    pub(super) at: Span,
    pub(super) name: Option<Spanned<String>>,
    when: Vec<Spanned<String>>,
    ends_on: Option<Spanned<Vec<Spanned<String>>>>,
    end_mode: EndMode,
    deadline: Duration,
    ops: Vec<ParsedOp>,
    control: RawControl,
}

/// The `[[action]]`s, the value of the file's `action` key; a mission without one is
/// reported at its `[mission]` table, `header`.
pub(super) fn read_all(ctx: &mut Reader<'_>, v: Option<&Val<'_>>, header: &Span) -> Vec<RawAction> {
    let Some(v) = v else {
        ctx.err(header, NO_ACTIONS);
        return Vec::new();
    };
    let Some(items) = ctx.array(v, "an array of tables `[[action]]` for `action`") else {
        return Vec::new();
    };
    if items.is_empty() {
        ctx.err(&v.span(), NO_ACTIONS);
    }
    let mut out = Vec::new();
    for item in items {
        if let Some(t) = ctx.table_or(item, "`[[action]]`", "a table `[[action]]` for each action")
        {
            out.push(read(ctx, &t));
        }
    }
    out
}

/// One `[[action]]`.
fn read(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> RawAction {
    ctx.unknown_keys(t, ACTION_KEYS);
    let control = control_keys::read(ctx, t, Owner::Action);
    let name = ctx
        .required(t, "name", "a unique name for the action, a string")
        .and_then(|v| ctx.non_empty_string(v, "action.name"));
    let label = name
        .as_ref()
        .map_or_else(|| "without a name".to_string(), |n| quote(n.get_ref()));
    RawAction {
        at: t.span.clone(),
        name,
        when: t
            .get("when")
            .and_then(|v| ctx.string_list(v, "action.when"))
            .unwrap_or_default(),
        ends_on: t.get("ends_on").and_then(|v| {
            ctx.string_list(v, "action.ends_on")
                .map(|l| Spanned::new(v.span(), l))
        }),
        end_mode: t.get("end_mode").map_or(EndMode::Any, |v| end_mode(ctx, v)),
        deadline: t
            .get("deadline_s")
            .and_then(|v| seconds(ctx, v, "action.deadline_s"))
            .unwrap_or(DEFAULT_ACTION_DEADLINE),
        ops: operations(ctx, t, &label),
        control,
    }
}

/// `end_mode`: "any" or "all".
fn end_mode(ctx: &mut Reader<'_>, v: &Val<'_>) -> EndMode {
    match v.get_ref() {
        DeValue::String(s) if s == "any" => EndMode::Any,
        DeValue::String(s) if s == "all" => EndMode::All,
        other => {
            let found = match other {
                DeValue::String(s) => format!("\"{}\"", s.escape_debug()),
                _ => other.type_str().to_string(),
            };
            ctx.err(
                &v.span(),
                format!("expected \"any\" or \"all\" for `action.end_mode`, found {found}"),
            );
            EndMode::Any
        }
    }
}

/// `[action.ops]`: at least one operation (the action named `label` in messages).
fn operations(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>, label: &str) -> Vec<ParsedOp> {
    let no_ops = format!(
        "action {label} has no operations (expected at least one table `[action.ops.<operation>]`)"
    );
    let Some(v) = t.get("ops") else {
        ctx.err(&t.span, no_ops);
        return Vec::new();
    };
    let Some(ops) = ctx.table_or(v, "`action.ops`", "a table of operations for `action.ops`")
    else {
        return Vec::new();
    };
    if ops.t.is_empty() {
        ctx.err(&v.span(), no_ops);
        return Vec::new();
    }
    ops::read_all(ctx, &ops)
}

impl RawAction {
    /// The action with its flags, control keys and `ends_on` resolved.
    pub(super) fn resolve(self, ctx: &mut Reader<'_>, refs: &Refs<'_>) -> ParsedAction {
        let at = self.name.as_ref().map_or(self.at.clone(), Spanned::span);
        let at = ctx.pos(&at);
        let name = self.name.map(Spanned::into_inner);
        let control = self
            .control
            .resolve(ctx, refs, Owner::Action, name.as_deref());
        let when = refs.flags.refs(ctx, &self.when, "action.when");
        let ends_on = ends_on(ctx, self.ends_on, &self.ops);
        ParsedAction {
            name: name.unwrap_or_default(),
            at,
            when,
            ops: self.ops,
            ends_on,
            end_mode: self.end_mode,
            deadline: self.deadline,
            control,
        }
    }
}

/// The operations that end the action: those `ends_on` names, each once, or, without it,
/// all of `ops`.
fn ends_on(
    ctx: &mut Reader<'_>,
    named: Option<Spanned<Vec<Spanned<String>>>>,
    ops: &[ParsedOp],
) -> Vec<String> {
    let keys: Vec<String> = ops.iter().map(|o| o.key.clone()).collect();
    let Some(named) = named else {
        return keys;
    };
    if named.get_ref().is_empty() {
        ctx.err(
            &named.span(),
            "`action.ends_on` must name at least one operation of the action (or be left out: then all of them end it)",
        );
    }
    let mut out: Vec<String> = Vec::new();
    for k in named.into_inner() {
        if keys.is_empty() {
            // "has no operations" is reported already.
        } else if !keys.contains(k.get_ref()) {
            let msg = format!(
                "unknown operation {} in `action.ends_on` (expected one of the action's operations: {})",
                quote(k.get_ref()),
                name_list(&keys)
            );
            ctx.err(&k.span(), msg);
        } else if !out.contains(k.get_ref()) {
            out.push(k.into_inner());
        }
    }
    out
}

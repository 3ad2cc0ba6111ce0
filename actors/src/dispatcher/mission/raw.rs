//! Stage 1: from TOML text to a [`ParsedMission`].
//!
//! The text is parsed by toml's span-preserving parser ([`DeTable`]: every key and value is a
//! [`Spanned`]), then walked by hand into the raw structures below. A derived `Deserialize`
//! stops at the first problem; walking the table lets one pass report *every* unknown key,
//! wrong type and missing field, each at its own position. The raw structures are then checked
//! for what needs no catalog: flag bits, flag names, action names, `ends_on`, deadlines.

use super::{EndMode, ParsedMission};
use crate::diagnostic::toml::{quote, Reader, Tbl};
use crate::diagnostic::{Diagnostics, Pos};
use crate::property::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::path::Path;
use std::time::Duration;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

type Span = Range<usize>;

/// The longest deadline a mission may set: a day. A wait longer than that could not be run in
/// reasonable time at `--speed 1`, so `marie check` refuses it.
pub(crate) const MAX_SECONDS: f64 = 86_400.0;

/// Deadline of an action that gives no `deadline_s`.
pub(crate) const DEFAULT_ACTION_DEADLINE: Duration = Duration::from_secs(30);

const TOP_KEYS: &[&str] = &["mission", "flags", "action", "requires"];
const MISSION_KEYS: &[&str] = &[
    "name",
    "description",
    "success",
    "initial",
    "deadline_s",
    "rebind_deadline_s",
    "world",
];
const ACTION_KEYS: &[&str] = &["name", "when", "ends_on", "end_mode", "deadline_s", "ops"];

/// A flag named in `initial`, `success` or `when`, resolved to its bit.
#[derive(Clone, Debug)]
pub(crate) struct FlagRef {
    pub(crate) name: String,
    pub(crate) bit: u8,
    pub(crate) at: Pos,
    /// The field it was named in, e.g. `action.when`.
    pub(crate) field: &'static str,
}

/// One supplied parameter, converted but not yet checked against a schema.
#[derive(Clone, Debug)]
pub(crate) struct ParsedParam {
    pub(crate) name: String,
    /// Position of the parameter's key.
    pub(crate) at: Pos,
    pub(crate) value: Value,
    /// Position of the value and of every nested value, by path (`pose.x`, `gains[1]`).
    pub(crate) value_at: BTreeMap<String, Pos>,
}

/// One `[action.ops.<key>]` table.
#[derive(Clone, Debug)]
pub(crate) struct ParsedOp {
    pub(crate) key: String,
    pub(crate) at: Pos,
    pub(crate) params: Vec<ParsedParam>,
}

/// One `[[action]]`, structurally sound.
#[derive(Clone, Debug)]
pub(crate) struct ParsedAction {
    pub(crate) name: String,
    pub(crate) when: Vec<FlagRef>,
    pub(crate) ops: Vec<ParsedOp>,
    pub(crate) ends_on: Vec<String>,
    pub(crate) end_mode: EndMode,
    pub(crate) deadline: Duration,
}

/// The `[mission]` table.
#[derive(Default)]
struct RawHeader {
    at: Span,
    name: Option<Spanned<String>>,
    description: Option<Spanned<String>>,
    success: Vec<Spanned<String>>,
    initial: Vec<Spanned<String>>,
    deadline: Option<Duration>,
    rebind_deadline: Option<Duration>,
    world: Option<Spanned<String>>,
}

/// One `[[action]]` table, fields typed but not cross-checked.
struct RawAction {
    name: Option<Spanned<String>>,
    when: Vec<Spanned<String>>,
    ends_on: Option<Spanned<Vec<Spanned<String>>>>,
    end_mode: EndMode,
    deadline: Duration,
    ops: Vec<ParsedOp>,
}

/// Where problems go while walking the document: the shared TOML reader.
type Ctx<'s> = Reader<'s>;

/// Text from the file, quoted for a message: `` `name` ``, with control characters escaped.
pub(crate) fn q(text: &str) -> String {
    quote(text)
}

/// A list of names for "expected one of" hints.
pub(crate) fn list<S: AsRef<str>>(names: impl IntoIterator<Item = S>) -> String {
    names
        .into_iter()
        .map(|n| n.as_ref().escape_debug().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Stage 1 entry point.
pub(crate) fn parse(src: &str, path: Option<&Path>) -> Result<ParsedMission, Diagnostics> {
    let file = super::display_path(path);
    let mut ctx = Reader::new(src, file);
    let Some(doc) = ctx.parse() else {
        let mut syntax = Diagnostics(ctx.into_diagnostics());
        syntax.sort();
        return Err(syntax);
    };
    let doc = doc.get_ref();
    unknown_keys(&mut ctx, doc, TOP_KEYS, "the mission file");

    let header = match doc.get("mission") {
        None => {
            ctx.err(
                &(0..0),
                "missing table `[mission]` (expected at least `name = \"...\"`)",
            );
            RawHeader::default()
        }
        Some(v) => match v.get_ref() {
            DeValue::Table(t) => raw_header(&mut ctx, t, v.span()),
            other => {
                ctx.err(
                    &v.span(),
                    format!("expected a table `[mission]`, found {}", other.type_str()),
                );
                RawHeader {
                    at: v.span(),
                    ..RawHeader::default()
                }
            }
        },
    };
    let flags = match doc.get("flags") {
        None => Vec::new(),
        Some(v) => match v.get_ref() {
            DeValue::Table(t) => raw_flags(&mut ctx, t),
            other => {
                ctx.err(
                    &v.span(),
                    format!(
                        "expected a table `[flags]` of flag names and bit numbers, found {}",
                        other.type_str()
                    ),
                );
                Vec::new()
            }
        },
    };
    let actions = match doc.get("action") {
        None => {
            ctx.err(
                &header.at,
                "the mission has no actions (expected at least one `[[action]]`)",
            );
            Vec::new()
        }
        Some(v) => raw_actions(&mut ctx, v),
    };
    let requires = match doc.get("requires") {
        None => Vec::new(),
        Some(v) => match v.get_ref() {
            DeValue::Table(t) => raw_requires(&mut ctx, t),
            other => {
                ctx.err(
                    &v.span(),
                    format!(
                        "expected a table `[requires]` of operations and version requirements \
                         (e.g. wall-follower = \"^2\"), found {}",
                        other.type_str()
                    ),
                );
                Vec::new()
            }
        },
    };
    let mut mission = check(&mut ctx, path, header, flags, actions);
    mission.requires = requires;
    Diagnostics(ctx.into_diagnostics()).into_result(mission)
}

/// `[requires]`: operation = "semver requirement", each at its position.
fn raw_requires(ctx: &mut Ctx<'_>, table: &DeTable<'_>) -> Vec<(String, semver::VersionReq, Pos)> {
    let mut out = Vec::new();
    for (key, v) in in_file_order(table) {
        let Some(text) = string(ctx, v, key.get_ref()) else {
            continue;
        };
        match semver::VersionReq::parse(text.get_ref()) {
            Ok(req) => out.push((key.get_ref().to_string(), req, ctx.pos(&key.span()))),
            Err(e) => ctx.err(
                &v.span(),
                format!(
                    "{} is not a version requirement for {}: {e} (e.g. \"^2\", \">=1.2, <3\")",
                    q(text.get_ref()),
                    q(key.get_ref())
                ),
            ),
        }
    }
    out
}

/// Report every key of `table` not in `allowed`.
fn unknown_keys(ctx: &mut Ctx<'_>, table: &DeTable<'_>, allowed: &[&str], place: &str) {
    let tbl = Tbl {
        t: table,
        span: 0..0,
        place: place.to_string(),
    };
    ctx.unknown_keys(&tbl, allowed);
}

/// The entries of a table in file order (toml's map orders keys by name).
fn in_file_order<'a, 'i>(
    table: &'a DeTable<'i>,
) -> Vec<(
    &'a Spanned<std::borrow::Cow<'i, str>>,
    &'a Spanned<DeValue<'i>>,
)> {
    let mut entries: Vec<_> = table.iter().collect();
    entries.sort_by_key(|(k, _)| k.span().start);
    entries
}

fn string(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>, field: &str) -> Option<Spanned<String>> {
    match v.get_ref() {
        DeValue::String(s) => Some(Spanned::new(v.span(), s.to_string())),
        other => {
            ctx.err(
                &v.span(),
                format!(
                    "expected a string for `{field}`, found {}",
                    other.type_str()
                ),
            );
            None
        }
    }
}

fn non_empty_string(
    ctx: &mut Ctx<'_>,
    v: &Spanned<DeValue<'_>>,
    field: &str,
) -> Option<Spanned<String>> {
    let s = string(ctx, v, field)?;
    if s.get_ref().trim().is_empty() {
        ctx.err(&s.span(), format!("`{field}` must not be empty"));
        return None;
    }
    Some(s)
}

fn string_list(
    ctx: &mut Ctx<'_>,
    v: &Spanned<DeValue<'_>>,
    field: &str,
) -> Option<Vec<Spanned<String>>> {
    let DeValue::Array(items) = v.get_ref() else {
        ctx.err(
            &v.span(),
            format!(
                "expected an array of strings for `{field}`, found {}",
                v.get_ref().type_str()
            ),
        );
        return None;
    };
    let mut out = Vec::new();
    for item in items.iter() {
        match item.get_ref() {
            DeValue::String(s) => out.push(Spanned::new(item.span(), s.to_string())),
            other => ctx.err(
                &item.span(),
                format!("expected a string in `{field}`, found {}", other.type_str()),
            ),
        }
    }
    Some(out)
}

fn integer(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>) -> Option<i64> {
    let DeValue::Integer(i) = v.get_ref() else {
        return None;
    };
    let parsed = i64::from_str_radix(i.as_str(), i.radix()).ok();
    if parsed.is_none() {
        let shown = ctx.src().get(v.span()).unwrap_or_default().to_string();
        ctx.err(
            &v.span(),
            format!("integer {shown} is out of range (expected a 64-bit signed integer)"),
        );
    }
    parsed
}

fn float(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>) -> Option<f64> {
    let DeValue::Float(f) = v.get_ref() else {
        return None;
    };
    match f.as_str().parse::<f64>() {
        Ok(x) if x.is_finite() || f.as_str().contains("inf") || x.is_nan() => Some(x),
        _ => {
            let shown = ctx.src().get(v.span()).unwrap_or_default().to_string();
            ctx.err(
                &v.span(),
                format!("float {shown} is out of range (expected a 64-bit float)"),
            );
            None
        }
    }
}

fn seconds(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>, field: &str) -> Option<Duration> {
    let x = match v.get_ref() {
        DeValue::Integer(_) => integer(ctx, v)? as f64,
        DeValue::Float(_) => float(ctx, v)?,
        other => {
            ctx.err(
                &v.span(),
                format!(
                    "expected a number of seconds for `{field}`, found {}",
                    other.type_str()
                ),
            );
            return None;
        }
    };
    let shown = ctx.src().get(v.span()).unwrap_or_default().to_string();
    if !(x.is_finite() && x > 0.0) {
        ctx.err(
            &v.span(),
            format!("`{field}` must be a positive, finite number of seconds, found {shown}"),
        );
        return None;
    }
    if x > MAX_SECONDS {
        ctx.err(
            &v.span(),
            format!("`{field}` = {shown} is more than a mission may wait ({MAX_SECONDS} s, a day)"),
        );
        return None;
    }
    match Duration::try_from_secs_f64(x) {
        Ok(d) if !d.is_zero() => Some(d),
        Ok(_) => {
            ctx.err(
                &v.span(),
                format!("`{field}` = {shown} is too small (expected at least 1 ns)"),
            );
            None
        }
        Err(_) => {
            ctx.err(
                &v.span(),
                format!("`{field}` = {shown} is too large for a duration"),
            );
            None
        }
    }
}

fn raw_header(ctx: &mut Ctx<'_>, t: &DeTable<'_>, at: Span) -> RawHeader {
    unknown_keys(ctx, t, MISSION_KEYS, "`[mission]`");
    let mut h = RawHeader {
        at,
        ..RawHeader::default()
    };
    match t.get("name") {
        None => ctx.err(
            &h.at,
            "missing key `name` in `[mission]` (expected the mission's name, a string)",
        ),
        Some(v) => h.name = non_empty_string(ctx, v, "mission.name"),
    }
    if let Some(v) = t.get("description") {
        h.description = string(ctx, v, "mission.description");
    }
    if let Some(v) = t.get("success") {
        h.success = string_list(ctx, v, "mission.success").unwrap_or_default();
    }
    if let Some(v) = t.get("initial") {
        h.initial = string_list(ctx, v, "mission.initial").unwrap_or_default();
    }
    if let Some(v) = t.get("deadline_s") {
        h.deadline = seconds(ctx, v, "mission.deadline_s");
    }
    if let Some(v) = t.get("rebind_deadline_s") {
        h.rebind_deadline = seconds(ctx, v, "mission.rebind_deadline_s");
    }
    if let Some(v) = t.get("world") {
        h.world = non_empty_string(ctx, v, "mission.world");
    }
    h
}

/// A `[flags]` entry: its name, and its bit when that is a valid bit number.
type RawFlag = (Spanned<String>, Option<Spanned<u8>>);

/// The `[flags]` entries, in file order. Entries with an invalid bit are kept (without a bit)
/// so that naming them elsewhere is not reported a second time as an unknown flag.
fn raw_flags(ctx: &mut Ctx<'_>, t: &DeTable<'_>) -> Vec<RawFlag> {
    let mut out = Vec::new();
    for (key, v) in in_file_order(t) {
        let name = key.get_ref().to_string();
        if name.trim().is_empty() {
            ctx.err(&key.span(), "a flag name must not be empty");
            continue;
        }
        let name = Spanned::new(key.span(), name);
        let bit = match v.get_ref() {
            DeValue::Integer(_) => integer(ctx, v),
            other => {
                ctx.err(
                    &v.span(),
                    format!(
                        "expected a bit number 0..=31 for flag {}, found {}",
                        q(name.get_ref()),
                        other.type_str()
                    ),
                );
                None
            }
        };
        let Some(bit) = bit else {
            out.push((name, None));
            continue;
        };
        match u8::try_from(bit).ok().filter(|b| *b < 32) {
            Some(b) => out.push((name, Some(Spanned::new(v.span(), b)))),
            None => {
                ctx.err(
                    &v.span(),
                    format!(
                        "bit {bit} of flag {} is out of range (expected 0..=31: the status word has 32 bits)",
                        q(name.get_ref())
                    ),
                );
                out.push((name, None));
            }
        }
    }
    out
}

fn raw_actions(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>) -> Vec<RawAction> {
    let DeValue::Array(items) = v.get_ref() else {
        ctx.err(
            &v.span(),
            format!(
                "expected an array of tables `[[action]]` for `action`, found {}",
                v.get_ref().type_str()
            ),
        );
        return Vec::new();
    };
    if items.is_empty() {
        ctx.err(
            &v.span(),
            "the mission has no actions (expected at least one `[[action]]`)",
        );
    }
    let mut out = Vec::new();
    for item in items.iter() {
        match item.get_ref() {
            DeValue::Table(t) => out.push(raw_action(ctx, t, item.span())),
            other => ctx.err(
                &item.span(),
                format!(
                    "expected a table `[[action]]` for each action, found {}",
                    other.type_str()
                ),
            ),
        }
    }
    out
}

fn raw_action(ctx: &mut Ctx<'_>, t: &DeTable<'_>, at: Span) -> RawAction {
    unknown_keys(ctx, t, ACTION_KEYS, "`[[action]]`");
    let name = match t.get("name") {
        None => {
            ctx.err(
                &at,
                "missing key `name` in `[[action]]` (expected a unique name for the action, a string)",
            );
            None
        }
        Some(v) => non_empty_string(ctx, v, "action.name"),
    };
    let label = name
        .as_ref()
        .map_or_else(|| "without a name".to_string(), |n| q(n.get_ref()));
    let when = t
        .get("when")
        .and_then(|v| string_list(ctx, v, "action.when"))
        .unwrap_or_default();
    let ends_on = t
        .get("ends_on")
        .and_then(|v| string_list(ctx, v, "action.ends_on").map(|l| Spanned::new(v.span(), l)));
    let end_mode = match t.get("end_mode") {
        None => EndMode::Any,
        Some(v) => match v.get_ref() {
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
        },
    };
    let deadline = t
        .get("deadline_s")
        .and_then(|v| seconds(ctx, v, "action.deadline_s"))
        .unwrap_or(DEFAULT_ACTION_DEADLINE);
    let no_ops = format!(
        "action {label} has no operations (expected at least one table `[action.ops.<operation>]`)"
    );
    let ops = match t.get("ops") {
        None => {
            ctx.err(&at, no_ops);
            Vec::new()
        }
        Some(v) => match v.get_ref() {
            DeValue::Table(ops) if ops.is_empty() => {
                ctx.err(&v.span(), no_ops);
                Vec::new()
            }
            DeValue::Table(ops) => in_file_order(ops)
                .into_iter()
                .map(|(key, v)| raw_op(ctx, key, v))
                .collect(),
            other => {
                ctx.err(
                    &v.span(),
                    format!(
                        "expected a table of operations for `action.ops`, found {}",
                        other.type_str()
                    ),
                );
                Vec::new()
            }
        },
    };
    RawAction {
        name,
        when,
        ends_on,
        end_mode,
        deadline,
        ops,
    }
}

fn raw_op(
    ctx: &mut Ctx<'_>,
    key: &Spanned<std::borrow::Cow<'_, str>>,
    v: &Spanned<DeValue<'_>>,
) -> ParsedOp {
    // The operation is kept even when malformed (its problems are reported), so that
    // `ends_on` naming it does not cause a second, misleading diagnostic.
    let mut op = ParsedOp {
        key: key.get_ref().to_string(),
        at: ctx.pos(&key.span()),
        params: Vec::new(),
    };
    if op.key.trim().is_empty() {
        ctx.err(&key.span(), "an operation name must not be empty");
        return op;
    }
    let DeValue::Table(t) = v.get_ref() else {
        ctx.err(
            &v.span(),
            format!(
                "expected a table of parameters for operation {} (`[action.ops.{}]`), found {}",
                q(&op.key),
                op.key.escape_debug(),
                v.get_ref().type_str()
            ),
        );
        return op;
    };
    for (pkey, pv) in in_file_order(t) {
        let name = pkey.get_ref().to_string();
        let mut value_at = BTreeMap::new();
        if let Some(value) = value(ctx, pv, &name, &op.key, &mut value_at) {
            op.params.push(ParsedParam {
                at: ctx.pos(&pkey.span()),
                name,
                value,
                value_at,
            });
        }
    }
    op
}

/// Convert a parameter value, recording the position of it and of every nested value by path.
/// Reports (and returns `None` for) values no parameter type can hold.
fn value(
    ctx: &mut Ctx<'_>,
    v: &Spanned<DeValue<'_>>,
    path: &str,
    op: &str,
    at: &mut BTreeMap<String, Pos>,
) -> Option<Value> {
    at.insert(path.to_string(), ctx.pos(&v.span()));
    let bad = |ctx: &mut Ctx<'_>, what: String| {
        ctx.err(
            &v.span(),
            format!("parameter {} of operation {}: {what}", q(path), q(op)),
        );
        None
    };
    match v.get_ref() {
        DeValue::String(s) => Some(Value::Text(s.to_string())),
        DeValue::Boolean(b) => Some(Value::Bool(*b)),
        DeValue::Integer(_) => integer(ctx, v).map(Value::Int),
        DeValue::Float(_) => float(ctx, v).map(Value::Float),
        DeValue::Datetime(d) => bad(
            ctx,
            format!(
                "the datetime {d} has no parameter type (expected a bool, integer, float, string, array or table)"
            ),
        ),
        DeValue::Array(items) => {
            let mut out = Vec::new();
            let mut ok = true;
            for (i, item) in items.iter().enumerate() {
                match value(ctx, item, &format!("{path}[{i}]"), op, at) {
                    Some(x) => out.push(x),
                    None => ok = false,
                }
            }
            ok.then_some(Value::Array(out))
        }
        DeValue::Table(t) => {
            let mut out = BTreeMap::new();
            let mut ok = true;
            for (k, item) in in_file_order(t) {
                match value(ctx, item, &format!("{path}.{}", k.get_ref()), op, at) {
                    Some(x) => {
                        out.insert(k.get_ref().to_string(), x);
                    }
                    None => ok = false,
                }
            }
            ok.then_some(Value::Struct(out))
        }
    }
}

/// Resolve flag names to bits, reporting names not declared in `[flags]`. Names declared
/// with an invalid bit (`declared` but not in `flags`) were reported already.
fn flag_refs(
    ctx: &mut Ctx<'_>,
    names: &[Spanned<String>],
    flags: &BTreeMap<String, u8>,
    declared: &BTreeSet<String>,
    field: &'static str,
) -> Vec<FlagRef> {
    let mut out = Vec::new();
    for n in names {
        match flags.get(n.get_ref()) {
            Some(bit) => out.push(FlagRef {
                name: n.get_ref().clone(),
                bit: *bit,
                at: ctx.pos(&n.span()),
                field,
            }),
            None if declared.contains(n.get_ref()) => {}
            None if declared.is_empty() => ctx.err(
                &n.span(),
                format!(
                    "unknown flag {} in `{field}` (no flags are declared: add it to `[flags]`)",
                    q(n.get_ref())
                ),
            ),
            None => ctx.err(
                &n.span(),
                format!(
                    "unknown flag {} in `{field}` (expected one of: {})",
                    q(n.get_ref()),
                    list(declared)
                ),
            ),
        }
    }
    out
}

/// The checks of stage 1 that relate fields to each other.
fn check(
    ctx: &mut Ctx<'_>,
    path: Option<&Path>,
    header: RawHeader,
    raw_flags: Vec<RawFlag>,
    raw_actions: Vec<RawAction>,
) -> ParsedMission {
    let mut flags = BTreeMap::new();
    let mut owner: BTreeMap<u8, String> = BTreeMap::new();
    let declared: BTreeSet<String> = raw_flags.iter().map(|(n, _)| n.get_ref().clone()).collect();
    for (name, bit) in raw_flags {
        let Some(bit) = bit else { continue };
        let b = *bit.get_ref();
        if let Some(first) = owner.get(&b) {
            let msg = format!(
                "bit {b} of flag {} is already used by flag {} (each flag needs its own bit)",
                q(name.get_ref()),
                q(first)
            );
            ctx.err(&bit.span(), msg);
            continue;
        }
        owner.insert(b, name.get_ref().clone());
        flags.insert(name.into_inner(), b);
    }
    let initial = flag_refs(ctx, &header.initial, &flags, &declared, "mission.initial");
    let success = flag_refs(ctx, &header.success, &flags, &declared, "mission.success");

    let mut actions = Vec::new();
    let mut first_use: BTreeMap<String, Pos> = BTreeMap::new();
    for raw in raw_actions {
        let name = raw.name.map(|n| {
            let at = ctx.pos(&n.span());
            match first_use.get(n.get_ref()) {
                Some(first) => {
                    let msg = format!(
                        "duplicate action name {} (first used at {first}; action names must be unique)",
                        q(n.get_ref())
                    );
                    ctx.err(&n.span(), msg);
                }
                None => {
                    first_use.insert(n.get_ref().clone(), at);
                }
            }
            n.into_inner()
        });
        let when = flag_refs(ctx, &raw.when, &flags, &declared, "action.when");
        let keys: Vec<String> = raw.ops.iter().map(|o| o.key.clone()).collect();
        let ends_on = match raw.ends_on {
            None => keys.clone(),
            Some(list_) => {
                if list_.get_ref().is_empty() {
                    ctx.err(
                        &list_.span(),
                        "`action.ends_on` must name at least one operation of the action (or be left out: then all of them end it)",
                    );
                }
                let mut out: Vec<String> = Vec::new();
                for k in list_.into_inner() {
                    if keys.is_empty() {
                        // "has no operations" is reported already.
                    } else if !keys.contains(k.get_ref()) {
                        let msg = format!(
                            "unknown operation {} in `action.ends_on` (expected one of the action's operations: {})",
                            q(k.get_ref()),
                            list(&keys)
                        );
                        ctx.err(&k.span(), msg);
                    } else if !out.contains(k.get_ref()) {
                        out.push(k.into_inner());
                    }
                }
                out
            }
        };
        actions.push(ParsedAction {
            name: name.unwrap_or_default(),
            when,
            ops: raw.ops,
            ends_on,
            end_mode: raw.end_mode,
            deadline: raw.deadline,
        });
    }
    ParsedMission {
        file: super::display_path(path),
        path: path.map(Path::to_path_buf),
        name: header.name.map(Spanned::into_inner).unwrap_or_default(),
        description: header
            .description
            .map(Spanned::into_inner)
            .unwrap_or_default(),
        flags,
        initial,
        success,
        deadline: header.deadline,
        rebind_deadline: header.rebind_deadline,
        world_at: header.world.as_ref().map(|w| ctx.pos(&w.span())),
        world: header
            .world
            .map(|w| crate::diagnostic::beside(path, w.get_ref())),
        actions,
        requires: Vec::new(),
    }
}

//! Stage 1: from TOML text to a [`ParsedMission`].
//!
//! The text is parsed by toml's span-preserving parser ([`DeTable`]: every key and value is a
//! [`Spanned`]), then walked by hand into the raw structures below. A derived `Deserialize`
//! stops at the first problem; walking the table lets one pass report *every* unknown key,
//! wrong type and missing field, each at its own position. The raw structures are then checked
//! for what needs no catalog: flag bits, flag names, action names, `ends_on`, deadlines.

use super::{EndMode, ParsedMission};
use marie_vocabulary::diagnostic::toml::{quote, Reader, Tbl};
use marie_vocabulary::diagnostic::{Diagnostic, Diagnostics, Pos};
use marie_vocabulary::property::Value;
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

const TOP_KEYS: &[&str] = &["mission", "flags", "action", "requires", "group"];
const MISSION_KEYS: &[&str] = &[
    "name",
    "description",
    "success",
    "initial",
    "deadline_s",
    "rebind_deadline_s",
    "world",
];
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
const RETRY_KEYS: &[&str] = &["attempts", "backoff_s"];

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
    /// Where its name is written.
    pub(crate) at: Pos,
    pub(crate) when: Vec<FlagRef>,
    pub(crate) ops: Vec<ParsedOp>,
    pub(crate) ends_on: Vec<String>,
    pub(crate) end_mode: EndMode,
    pub(crate) deadline: Duration,
    pub(crate) control: ParsedControl,
}

/// An action or a group of a mission, by its index among the mission's actions or groups.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Item {
    /// `actions[i]`.
    Action(usize),
    /// `groups[i]`.
    Group(usize),
}

/// A name in `children` or `on_failure`, resolved to the item it names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ItemRef {
    pub(crate) item: Item,
    /// Where the name is written.
    pub(crate) at: Pos,
}

/// `retry = { attempts = 3, backoff_s = 2.0 }`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Retry {
    /// Attempts in all, the first included (at least 1).
    pub(crate) attempts: u32,
    /// Time between a failure and the next attempt.
    pub(crate) backoff: Duration,
}

/// The control keys of an `[[action]]` or a `[[group]]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct ParsedControl {
    pub(crate) retry: Option<Retry>,
    pub(crate) timeout: Option<Duration>,
    pub(crate) on_failure: Option<ItemRef>,
    /// `while`: flags that must all stay set while it runs.
    pub(crate) while_: Vec<FlagRef>,
    /// `unless`: flags none of which may become set while it runs.
    pub(crate) unless: Vec<FlagRef>,
}

impl ParsedControl {
    /// True when it has reactive conditions (`while` or `unless`).
    pub(crate) fn reactive(&self) -> bool {
        !(self.while_.is_empty() && self.unless.is_empty())
    }

    /// True when no control key is given.
    pub(crate) fn is_empty(&self) -> bool {
        self.retry.is_none()
            && self.timeout.is_none()
            && self.on_failure.is_none()
            && self.while_.is_empty()
            && self.unless.is_empty()
    }
}

/// What a `[[group]]` does with its children (`kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupKind {
    /// In order; fails at the first failure.
    Sequence,
    /// In order until one succeeds.
    Fallback,
    /// All at once, with thresholds.
    Parallel,
    /// A sequence whose `while`/`unless` are re-checked while a child runs.
    Reactive,
}

impl GroupKind {
    const NAMES: &'static str = "\"sequence\", \"fallback\", \"parallel\" or \"reactive\"";

    fn parse(word: &str) -> Option<GroupKind> {
        match word {
            "sequence" => Some(GroupKind::Sequence),
            "fallback" => Some(GroupKind::Fallback),
            "parallel" => Some(GroupKind::Parallel),
            "reactive" => Some(GroupKind::Reactive),
            _ => None,
        }
    }

    /// The kind as the file writes it.
    pub fn word(self) -> &'static str {
        match self {
            GroupKind::Sequence => "sequence",
            GroupKind::Fallback => "fallback",
            GroupKind::Parallel => "parallel",
            GroupKind::Reactive => "reactive",
        }
    }
}

/// One `[[group]]`, structurally sound.
#[derive(Clone, Debug)]
pub(crate) struct ParsedGroup {
    pub(crate) name: String,
    /// Where its name is written.
    pub(crate) at: Pos,
    pub(crate) kind: GroupKind,
    pub(crate) children: Vec<ItemRef>,
    pub(crate) when: Vec<FlagRef>,
    pub(crate) control: ParsedControl,
    /// Parallel: how many children must succeed (default: all).
    pub(crate) success: usize,
    /// Parallel: how many failures make it fail (default 1).
    pub(crate) failure: usize,
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
    /// The table (for its place in the file).
    at: Span,
    name: Option<Spanned<String>>,
    when: Vec<Spanned<String>>,
    ends_on: Option<Spanned<Vec<Spanned<String>>>>,
    end_mode: EndMode,
    deadline: Duration,
    ops: Vec<ParsedOp>,
    control: RawControl,
}

/// The control keys of an `[[action]]` or a `[[group]]`, typed but not cross-checked.
#[derive(Default)]
struct RawControl {
    retry: Option<Retry>,
    timeout: Option<Duration>,
    on_failure: Option<Spanned<String>>,
    while_: Vec<Spanned<String>>,
    unless: Vec<Spanned<String>>,
}

/// One `[[group]]` table, fields typed but not cross-checked.
struct RawGroup {
    /// The table (for its place in the file, and missing keys).
    at: Span,
    name: Option<Spanned<String>>,
    /// `None` when missing or unknown (reported).
    kind: Option<Spanned<GroupKind>>,
    children: Vec<Spanned<String>>,
    when: Vec<Spanned<String>>,
    control: RawControl,
    success: Option<usize>,
    failure: Option<usize>,
}

/// Whose keys are read: an action's or a group's (for field names in messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Owner {
    Action,
    Group,
}

/// The names messages give the control keys of an action or a group (`action.while`).
struct Fields {
    when: &'static str,
    while_: &'static str,
    unless: &'static str,
    on_failure: &'static str,
    timeout: &'static str,
    retry: &'static str,
    attempts: &'static str,
    backoff: &'static str,
}

impl Owner {
    fn word(self) -> &'static str {
        match self {
            Owner::Action => "action",
            Owner::Group => "group",
        }
    }

    fn fields(self) -> &'static Fields {
        match self {
            Owner::Action => &Fields {
                when: "action.when",
                while_: "action.while",
                unless: "action.unless",
                on_failure: "action.on_failure",
                timeout: "action.timeout_s",
                retry: "action.retry",
                attempts: "action.retry.attempts",
                backoff: "action.retry.backoff_s",
            },
            Owner::Group => &Fields {
                when: "group.when",
                while_: "group.while",
                unless: "group.unless",
                on_failure: "group.on_failure",
                timeout: "group.timeout_s",
                retry: "group.retry",
                attempts: "group.retry.attempts",
                backoff: "group.retry.backoff_s",
            },
        }
    }
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
    let groups = match doc.get("group") {
        None => Vec::new(),
        Some(v) => raw_groups(&mut ctx, v),
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
    let mut mission = check(&mut ctx, path, header, flags, actions, groups);
    mission.requires = requires;
    if !ctx.has_errors() {
        // how actions and groups name each other: only once every name is known
        super::structure::check(&mut ctx, &mission);
    }
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
    seconds_from(ctx, v, field, false)
}

/// A number of seconds, at most a day: positive, or, with `zero`, positive or zero.
fn seconds_from(
    ctx: &mut Ctx<'_>,
    v: &Spanned<DeValue<'_>>,
    field: &str,
    zero: bool,
) -> Option<Duration> {
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
    let in_range = if zero { x >= 0.0 } else { x > 0.0 };
    if !(x.is_finite() && in_range) {
        let what = if zero { "non-negative" } else { "positive" };
        ctx.err(
            &v.span(),
            format!("`{field}` must be a {what}, finite number of seconds, found {shown}"),
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
        Ok(d) if zero || !d.is_zero() => Some(d),
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
    let control = raw_control(ctx, t, Owner::Action);
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
        at,
        name,
        when,
        ends_on,
        end_mode,
        deadline,
        ops,
        control,
    }
}

/// The control keys of an action or a group: `retry`, `timeout_s`, `on_failure`, `while`,
/// `unless`.
fn raw_control(ctx: &mut Ctx<'_>, t: &DeTable<'_>, owner: Owner) -> RawControl {
    let mut c = RawControl::default();
    if let Some(v) = t.get("retry") {
        c.retry = raw_retry(ctx, v, owner);
    }
    if let Some(v) = t.get("timeout_s") {
        c.timeout = seconds(ctx, v, owner.fields().timeout);
    }
    if let Some(v) = t.get("on_failure") {
        c.on_failure = non_empty_string(ctx, v, owner.fields().on_failure);
    }
    if let Some(v) = t.get("while") {
        c.while_ = string_list(ctx, v, owner.fields().while_).unwrap_or_default();
    }
    if let Some(v) = t.get("unless") {
        c.unless = string_list(ctx, v, owner.fields().unless).unwrap_or_default();
    }
    c
}

/// `retry = { attempts = 3, backoff_s = 2.0 }`.
fn raw_retry(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>, owner: Owner) -> Option<Retry> {
    let field = owner.fields().retry;
    let DeValue::Table(t) = v.get_ref() else {
        ctx.err(
            &v.span(),
            format!(
                "expected a table for `{field}` (e.g. retry = {{ attempts = 3, backoff_s = 2.0 }}), found {}",
                v.get_ref().type_str()
            ),
        );
        return None;
    };
    unknown_keys(ctx, t, RETRY_KEYS, &format!("`{field}`"));
    let backoff = match t.get("backoff_s") {
        None => Some(Duration::ZERO),
        Some(b) => seconds_from(ctx, b, owner.fields().backoff, true),
    };
    let Some(a) = t.get("attempts") else {
        ctx.err(
            &v.span(),
            format!(
                "missing key `attempts` in `{field}` (expected the attempts in all, the first included: an integer of at least 1)"
            ),
        );
        return None;
    };
    let attempts_field = owner.fields().attempts;
    let DeValue::Integer(_) = a.get_ref() else {
        ctx.err(
            &a.span(),
            format!(
                "expected an integer for `{attempts_field}`, found {}",
                a.get_ref().type_str()
            ),
        );
        return None;
    };
    let n = integer(ctx, a)?;
    let shown = ctx.src().get(a.span()).unwrap_or_default().to_string();
    let attempts = match u32::try_from(n) {
        Ok(0) => {
            ctx.err(
                &a.span(),
                format!(
                    "a retry of 0 attempts never runs the {} (`attempts` counts every attempt, the first included: expected at least 1)",
                    owner.word()
                ),
            );
            return None;
        }
        Ok(n) => n,
        Err(_) if n < 0 => {
            ctx.err(
                &a.span(),
                format!("`{attempts_field}` must be an integer of at least 1, found {shown}"),
            );
            return None;
        }
        Err(_) => {
            ctx.err(
                &a.span(),
                format!(
                    "`{attempts_field}` = {shown} is too large (expected at most {})",
                    u32::MAX
                ),
            );
            return None;
        }
    };
    Some(Retry {
        attempts,
        backoff: backoff?,
    })
}

fn raw_groups(ctx: &mut Ctx<'_>, v: &Spanned<DeValue<'_>>) -> Vec<RawGroup> {
    let DeValue::Array(items) = v.get_ref() else {
        ctx.err(
            &v.span(),
            format!(
                "expected an array of tables `[[group]]` for `group`, found {}",
                v.get_ref().type_str()
            ),
        );
        return Vec::new();
    };
    let mut out = Vec::new();
    for item in items.iter() {
        match item.get_ref() {
            DeValue::Table(t) => out.push(raw_group(ctx, t, item.span())),
            other => ctx.err(
                &item.span(),
                format!(
                    "expected a table `[[group]]` for each group, found {}",
                    other.type_str()
                ),
            ),
        }
    }
    out
}

fn raw_group(ctx: &mut Ctx<'_>, t: &DeTable<'_>, at: Span) -> RawGroup {
    let owner = Owner::Group;
    unknown_keys(ctx, t, GROUP_KEYS, "`[[group]]`");
    let name = match t.get("name") {
        None => {
            ctx.err(
                &at,
                "missing key `name` in `[[group]]` (expected a name for the group, unique among actions and groups, a string)",
            );
            None
        }
        Some(v) => non_empty_string(ctx, v, "group.name"),
    };
    let label = name
        .as_ref()
        .map_or_else(|| "without a name".to_string(), |n| q(n.get_ref()));
    let kind = match t.get("kind") {
        None => {
            ctx.err(
                &at,
                format!(
                    "missing key `kind` in group {label} (expected {})",
                    GroupKind::NAMES
                ),
            );
            None
        }
        Some(v) => match v.get_ref() {
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
            other => {
                ctx.err(
                    &v.span(),
                    format!(
                        "expected a string for `group.kind` ({}), found {}",
                        GroupKind::NAMES,
                        other.type_str()
                    ),
                );
                None
            }
        },
    };
    let kind_word = kind.as_ref().map_or("group", |k| k.get_ref().word());
    let children = match t.get("children") {
        None => {
            ctx.err(
                &at,
                format!(
                    "missing key `children` in group {label} (expected the names of the actions and groups it runs, in order)"
                ),
            );
            Vec::new()
        }
        Some(v) => {
            let children = string_list(ctx, v, "group.children");
            if children.as_ref().is_some_and(Vec::is_empty) {
                ctx.err(
                    &v.span(),
                    format!(
                        "a {kind_word} with no child: group {label} names no action or group in `children`"
                    ),
                );
            }
            children.unwrap_or_default()
        }
    };
    let when = t
        .get("when")
        .and_then(|v| string_list(ctx, v, owner.fields().when))
        .unwrap_or_default();
    let control = raw_control(ctx, t, owner);
    if let Some(k) = &kind {
        if *k.get_ref() == GroupKind::Reactive
            && control.while_.is_empty()
            && control.unless.is_empty()
        {
            ctx.err(
                &k.span(),
                format!(
                    "reactive group {label} has neither `while` nor `unless` (a reactive group re-checks them while its children run: give at least one)"
                ),
            );
        }
    }
    let mut threshold = |key: &str, what: &str| -> Option<usize> {
        let (k, v) = t.get_key_value(key)?;
        match kind.as_ref().map(|k| *k.get_ref()) {
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
        let DeValue::Integer(_) = v.get_ref() else {
            ctx.err(
                &v.span(),
                format!(
                    "expected an integer for `group.{key}`, found {}",
                    v.get_ref().type_str()
                ),
            );
            return None;
        };
        let x = integer(ctx, v)?;
        let n = children.len();
        if n == 0 {
            return None; // "no child" is reported already
        }
        match usize::try_from(x).ok().filter(|x| (1..=n).contains(x)) {
            Some(x) => Some(x),
            None => {
                let shown = ctx.src().get(v.span()).unwrap_or_default().to_string();
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
    };
    let success = threshold("success", "must succeed");
    let failure = threshold("failure", "failing make it fail");
    RawGroup {
        at,
        name,
        kind,
        children,
        when,
        control,
        success,
        failure,
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
    raw_groups: Vec<RawGroup>,
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

    // actions and groups share one name space; in file order, so that a duplicate is
    // reported where it is written again
    let mut items: Vec<(usize, Item)> = raw_actions
        .iter()
        .enumerate()
        .map(|(i, a)| (a.at.start, Item::Action(i)))
        .chain(
            raw_groups
                .iter()
                .enumerate()
                .map(|(i, g)| (g.at.start, Item::Group(i))),
        )
        .collect();
    items.sort();
    let items: Vec<Item> = items.into_iter().map(|(_, item)| item).collect();
    let mut names: BTreeMap<String, Item> = BTreeMap::new();
    let mut first_use: BTreeMap<String, Pos> = BTreeMap::new();
    for item in &items {
        let name = match item {
            Item::Action(i) => raw_actions[*i].name.as_ref(),
            Item::Group(i) => raw_groups[*i].name.as_ref(),
        };
        let Some(n) = name else { continue };
        match (first_use.get(n.get_ref()), names.get(n.get_ref())) {
            (Some(first), Some(Item::Action(_))) if matches!(item, Item::Action(_)) => {
                let msg = format!(
                    "duplicate action name {} (first used at {first}; action names must be unique)",
                    q(n.get_ref())
                );
                ctx.err(&n.span(), msg);
            }
            (Some(first), Some(by)) => {
                let msg = format!(
                    "duplicate name {} (first used at {first} by {}; action and group names must be unique)",
                    q(n.get_ref()),
                    match by {
                        Item::Action(_) => "an action",
                        Item::Group(_) => "a group",
                    }
                );
                ctx.err(&n.span(), msg);
            }
            _ => {
                first_use.insert(n.get_ref().clone(), ctx.pos(&n.span()));
                names.insert(n.get_ref().clone(), *item);
            }
        }
    }
    let refs = Refs {
        flags: &flags,
        declared: &declared,
        names: &names,
    };

    let mut actions = Vec::new();
    for raw in raw_actions {
        let at = raw.name.as_ref().map_or(raw.at.clone(), Spanned::span);
        let at = ctx.pos(&at);
        let name = raw.name.map(Spanned::into_inner);
        let control = refs.control(ctx, raw.control, Owner::Action, name.as_deref());
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
            at,
            when,
            ops: raw.ops,
            ends_on,
            end_mode: raw.end_mode,
            deadline: raw.deadline,
            control,
        });
    }
    let mut groups = Vec::new();
    for raw in raw_groups {
        let at = raw.name.as_ref().map_or(raw.at.clone(), Spanned::span);
        let at = ctx.pos(&at);
        let name = raw.name.map(Spanned::into_inner);
        let when = flag_refs(ctx, &raw.when, &flags, &declared, "group.when");
        let control = refs.control(ctx, raw.control, Owner::Group, name.as_deref());
        let children = raw
            .children
            .iter()
            .filter_map(|c| refs.item(ctx, c, "group.children"))
            .collect::<Vec<_>>();
        let n = raw.children.len();
        groups.push(ParsedGroup {
            name: name.unwrap_or_default(),
            at,
            kind: raw.kind.map_or(GroupKind::Sequence, Spanned::into_inner),
            children,
            when,
            control,
            success: raw.success.unwrap_or(n),
            failure: raw.failure.unwrap_or(1),
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
            .map(|w| marie_vocabulary::diagnostic::beside(path, w.get_ref())),
        actions,
        groups,
        items,
        requires: Vec::new(),
    }
}

/// What names in the control keys are resolved against.
struct Refs<'a> {
    flags: &'a BTreeMap<String, u8>,
    declared: &'a BTreeSet<String>,
    names: &'a BTreeMap<String, Item>,
}

impl Refs<'_> {
    /// The control keys of an action or a group, their names resolved.
    fn control(
        &self,
        ctx: &mut Ctx<'_>,
        raw: RawControl,
        owner: Owner,
        name: Option<&str>,
    ) -> ParsedControl {
        let while_ = flag_refs(
            ctx,
            &raw.while_,
            self.flags,
            self.declared,
            owner.fields().while_,
        );
        let unless = flag_refs(
            ctx,
            &raw.unless,
            self.flags,
            self.declared,
            owner.fields().unless,
        );
        for u in &unless {
            if while_.iter().any(|w| w.name == u.name) {
                let label = name.map_or_else(|| "without a name".to_string(), q);
                ctx.push(Diagnostic::at(
                    ctx.file(),
                    u.at,
                    format!(
                        "flag {} is in both `while` and `unless` of {} {label}: it could never run",
                        q(&u.name),
                        owner.word()
                    ),
                ));
            }
        }
        ParsedControl {
            retry: raw.retry,
            timeout: raw.timeout,
            on_failure: raw
                .on_failure
                .and_then(|r| self.item(ctx, &r, owner.fields().on_failure)),
            while_,
            unless,
        }
    }

    /// The action or group `name` names, or a diagnostic with the closest name or the
    /// names there are.
    fn item(&self, ctx: &mut Ctx<'_>, name: &Spanned<String>, field: &str) -> Option<ItemRef> {
        if let Some(item) = self.names.get(name.get_ref()) {
            return Some(ItemRef {
                item: *item,
                at: ctx.pos(&name.span()),
            });
        }
        let hint = match super::structure::closest(name.get_ref(), self.names.keys()) {
            Some(near) => format!("did you mean {}?", q(near)),
            None if self.names.is_empty() => "the mission names none".to_string(),
            None => format!("expected one of: {}", list(self.names.keys())),
        };
        ctx.err(
            &name.span(),
            format!(
                "unknown action or group {} in `{field}` ({hint})",
                q(name.get_ref())
            ),
        );
        None
    }
}

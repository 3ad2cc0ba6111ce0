//! The `[mission]` table — name, description, flags to start with and to succeed on,
//! deadlines, world — and `[requires]`, the versions of operations the mission accepts.

use super::seconds::seconds;
use marie_vocabulary::diagnostic::toml::{quote, Reader, Span, Tbl, Val};
use marie_vocabulary::diagnostic::Pos;
use std::time::Duration;
use toml::Spanned;

/// The keys `[mission]` may have.
const MISSION_KEYS: &[&str] = &[
    "name",
    "description",
    "success",
    "initial",
    "deadline_s",
    "rebind_deadline_s",
    "world",
];

/// The `[mission]` table, fields typed but not cross-checked.
#[derive(Default)]
pub(super) struct RawHeader {
    /// The table (where a mission without actions is reported).
    pub(super) at: Span,
    pub(super) name: Option<Spanned<String>>,
    pub(super) description: Option<Spanned<String>>,
    pub(super) success: Vec<Spanned<String>>,
    pub(super) initial: Vec<Spanned<String>>,
    pub(super) deadline: Option<Duration>,
    pub(super) rebind_deadline: Option<Duration>,
    pub(super) world: Option<Spanned<String>>,
}

/// A `[requires]` entry: the operation, the versions it accepts, where it is written.
pub(super) type Requirement = (String, semver::VersionReq, Pos);

/// `[mission]`, the value of the file's `mission` key (a diagnostic when there is none).
pub(super) fn read(ctx: &mut Reader<'_>, v: Option<&Val<'_>>) -> RawHeader {
    let Some(v) = v else {
        ctx.err(
            &(0..0),
            "missing table `[mission]` (expected at least `name = \"...\"`)",
        );
        return RawHeader::default();
    };
    match ctx.table_or(v, "`[mission]`", "a table `[mission]`") {
        Some(t) => fields(ctx, &t),
        None => RawHeader {
            at: v.span(),
            ..RawHeader::default()
        },
    }
}

/// The keys of `[mission]`.
fn fields(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> RawHeader {
    ctx.unknown_keys(t, MISSION_KEYS);
    let name = ctx
        .required(t, "name", "the mission's name, a string")
        .and_then(|v| ctx.non_empty_string(v, "mission.name"));
    RawHeader {
        at: t.span.clone(),
        name,
        description: t
            .get("description")
            .and_then(|v| ctx.spanned_string(v, "mission.description")),
        success: t
            .get("success")
            .and_then(|v| ctx.string_list(v, "mission.success"))
            .unwrap_or_default(),
        initial: t
            .get("initial")
            .and_then(|v| ctx.string_list(v, "mission.initial"))
            .unwrap_or_default(),
        deadline: t
            .get("deadline_s")
            .and_then(|v| seconds(ctx, v, "mission.deadline_s")),
        rebind_deadline: t
            .get("rebind_deadline_s")
            .and_then(|v| seconds(ctx, v, "mission.rebind_deadline_s")),
        world: t
            .get("world")
            .and_then(|v| ctx.non_empty_string(v, "mission.world")),
    }
}

/// `[pin]`: operation = "version" (exactly that version) or "requirement" (with an
/// operator: `"~1.0"`, `">=1, <1.1"`), each at its position — the versions the operation
/// runs on for the whole mission: its binding never moves to a newer version, and a
/// stand-in after a loss must match too.
pub(super) fn pins(ctx: &mut Reader<'_>, v: &Val<'_>) -> Vec<Requirement> {
    let expects = "a table `[pin]` of operations and the version each runs on \
                   (e.g. wall-follower = \"1.0.0\")";
    requirements(ctx, v, "`[pin]`", expects, |text, op| {
        // a bare version pins exactly it; semver would read it as `^1.0.0`
        let exact = match semver::Version::parse(text.trim()) {
            Ok(version) => format!("={version}"),
            Err(_) => text.to_string(),
        };
        semver::VersionReq::parse(&exact).map_err(|e| {
            format!(
                "{} is neither a version nor a version requirement to pin {} to: {e} \
                 (e.g. \"1.0.0\", \"~1.0\")",
                quote(text),
                quote(op)
            )
        })
    })
}

/// `[requires]`: operation = "semver requirement", each at its position.
pub(super) fn requires(ctx: &mut Reader<'_>, v: &Val<'_>) -> Vec<Requirement> {
    let expects = "a table `[requires]` of operations and version requirements \
                   (e.g. wall-follower = \"^2\")";
    requirements(ctx, v, "`[requires]`", expects, |text, op| {
        semver::VersionReq::parse(text).map_err(|e| {
            format!(
                "{} is not a version requirement for {}: {e} (e.g. \"^2\", \">=1.2, <3\")",
                quote(text),
                quote(op)
            )
        })
    })
}

/// A table `table` of operation = requirement, each read by `read(text, operation)` (its
/// error is the diagnostic, at the value), each kept at its key's position.
fn requirements(
    ctx: &mut Reader<'_>,
    v: &Val<'_>,
    table: &str,
    expects: &str,
    read: impl Fn(&str, &str) -> Result<semver::VersionReq, String>,
) -> Vec<Requirement> {
    let Some(t) = ctx.table_or(v, table, expects) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (key, v) in t.in_file_order() {
        let Some(text) = ctx.string_value(v, key.get_ref()) else {
            continue;
        };
        match read(&text, key.get_ref()) {
            Ok(req) => out.push((key.get_ref().to_string(), req, ctx.pos(&key.span()))),
            Err(words) => ctx.err(&v.span(), words),
        }
    }
    out
}

//! The control keys an `[[action]]` and a `[[group]]` share — `retry`, `timeout_s`,
//! `on_failure`, `while`, `unless` — read, and then resolved against the mission's names.

use super::super::parsed::{ParsedControl, Retry};
use super::names::Refs;
use super::seconds::{seconds, seconds_from};
use marie_vocabulary::diagnostic::toml::{quote, Reader, Tbl, Val};
use marie_vocabulary::diagnostic::Diagnostic;
use std::time::Duration;
use toml::Spanned;

/// The keys a `retry` table may have.
const RETRY_KEYS: &[&str] = &["attempts", "backoff_s"];

/// Whose keys are read: an action's or a group's (for field names in messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Owner {
    Action,
    Group,
}

/// The names messages give the control keys of an action or a group (`action.while`).
pub(super) struct Fields {
    pub(super) when: &'static str,
    pub(super) while_: &'static str,
    pub(super) unless: &'static str,
    pub(super) on_failure: &'static str,
    pub(super) timeout: &'static str,
    pub(super) retry: &'static str,
    pub(super) attempts: &'static str,
    pub(super) backoff: &'static str,
}

impl Owner {
    /// The owner as messages name it.
    pub(super) fn word(self) -> &'static str {
        match self {
            Owner::Action => "action",
            Owner::Group => "group",
        }
    }

    /// The names of its fields in messages.
    pub(super) fn fields(self) -> &'static Fields {
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

/// The control keys of an `[[action]]` or a `[[group]]`, typed but not cross-checked.
#[derive(Default)]
pub(super) struct RawControl {
    pub(super) retry: Option<Retry>,
    pub(super) timeout: Option<Duration>,
    pub(super) on_failure: Option<Spanned<String>>,
    pub(super) while_: Vec<Spanned<String>>,
    pub(super) unless: Vec<Spanned<String>>,
}

/// The control keys of an action or a group: `retry`, `timeout_s`, `on_failure`, `while`,
/// `unless`.
pub(super) fn read(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>, owner: Owner) -> RawControl {
    let fields = owner.fields();
    RawControl {
        retry: t.get("retry").and_then(|v| retry(ctx, v, owner)),
        timeout: t
            .get("timeout_s")
            .and_then(|v| seconds(ctx, v, fields.timeout)),
        on_failure: t
            .get("on_failure")
            .and_then(|v| ctx.non_empty_string(v, fields.on_failure)),
        while_: t
            .get("while")
            .and_then(|v| ctx.string_list(v, fields.while_))
            .unwrap_or_default(),
        unless: t
            .get("unless")
            .and_then(|v| ctx.string_list(v, fields.unless))
            .unwrap_or_default(),
    }
}

/// `retry = { attempts = 3, backoff_s = 2.0 }`.
fn retry(ctx: &mut Reader<'_>, v: &Val<'_>, owner: Owner) -> Option<Retry> {
    let field = owner.fields().retry;
    let t = ctx.table_or(
        v,
        &format!("`{field}`"),
        format!("a table for `{field}` (e.g. retry = {{ attempts = 3, backoff_s = 2.0 }})"),
    )?;
    ctx.unknown_keys(&t, RETRY_KEYS);
    let backoff = match t.get("backoff_s") {
        None => Some(Duration::ZERO),
        Some(b) => seconds_from(ctx, b, owner.fields().backoff, true),
    };
    let a = ctx.required(
        &t,
        "attempts",
        "the attempts in all, the first included: an integer of at least 1",
    )?;
    let attempts = attempts(ctx, a, owner)?;
    Some(Retry {
        attempts,
        backoff: backoff?,
    })
}

/// `retry.attempts`: an integer of at least 1 that fits 32 bits.
fn attempts(ctx: &mut Reader<'_>, a: &Val<'_>, owner: Owner) -> Option<u32> {
    let field = owner.fields().attempts;
    let n = ctx.int_value(a, field)?;
    let shown = ctx.written(a);
    let message = match u32::try_from(n) {
        Ok(0) => format!(
            "a retry of 0 attempts never runs the {} (`attempts` counts every attempt, the first included: expected at least 1)",
            owner.word()
        ),
        Ok(n) => return Some(n),
        Err(_) if n < 0 => {
            format!("`{field}` must be an integer of at least 1, found {shown}")
        }
        Err(_) => format!(
            "`{field}` = {shown} is too large (expected at most {})",
            u32::MAX
        ),
    };
    ctx.err(&a.span(), message);
    None
}

impl RawControl {
    /// The control keys of an action or a group (`name`, when it has one), their names
    /// resolved.
    pub(super) fn resolve(
        self,
        ctx: &mut Reader<'_>,
        refs: &Refs<'_>,
        owner: Owner,
        name: Option<&str>,
    ) -> ParsedControl {
        let fields = owner.fields();
        let while_ = refs.flags.refs(ctx, &self.while_, fields.while_);
        let unless = refs.flags.refs(ctx, &self.unless, fields.unless);
        for u in &unless {
            if while_.iter().any(|w| w.name == u.name) {
                let label = name.map_or_else(|| "without a name".to_string(), quote);
                ctx.push(Diagnostic::at(
                    ctx.file(),
                    u.at,
                    format!(
                        "flag {} is in both `while` and `unless` of {} {label}: it could never run",
                        quote(&u.name),
                        owner.word()
                    ),
                ));
            }
        }
        ParsedControl {
            retry: self.retry,
            timeout: self.timeout,
            on_failure: self
                .on_failure
                .and_then(|r| refs.item(ctx, &r, fields.on_failure)),
            while_,
            unless,
        }
    }
}

//! Durations in seconds — deadlines, timeouts, backoffs: a number, positive (or zero where a
//! pause may be none), finite, and at most a day.

use marie_vocabulary::diagnostic::toml::{Reader, Val};
use std::time::Duration;
use toml::de::DeValue;

/// The longest deadline a mission may set: a day. A wait longer than that could not be run in
/// reasonable time at `--speed 1`, so `marie check` refuses it.
const MAX_SECONDS: f64 = 86_400.0;

/// A positive number of seconds, at most a day.
pub(super) fn seconds(ctx: &mut Reader<'_>, v: &Val<'_>, field: &str) -> Option<Duration> {
    seconds_from(ctx, v, field, false)
}

/// A number of seconds, at most a day: positive, or, with `zero`, positive or zero.
pub(super) fn seconds_from(
    ctx: &mut Reader<'_>,
    v: &Val<'_>,
    field: &str,
    zero: bool,
) -> Option<Duration> {
    let x = number(ctx, v, field)?;
    let shown = ctx.written(v);
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
    duration(ctx, v, field, x, zero)
}

/// The value as a number, integer or float (as written: `inf` and `nan` are judged by the
/// caller).
fn number(ctx: &mut Reader<'_>, v: &Val<'_>, field: &str) -> Option<f64> {
    match v.get_ref() {
        DeValue::Integer(_) => ctx.int_value(v, field).map(|n| n as f64),
        DeValue::Float(_) => ctx.float_value(v, field),
        _ => ctx.expected(v, format_args!("a number of seconds for `{field}`")),
    }
}

/// `x` seconds (finite, in range) as a duration: not zero unless `zero`.
fn duration(
    ctx: &mut Reader<'_>,
    v: &Val<'_>,
    field: &str,
    x: f64,
    zero: bool,
) -> Option<Duration> {
    let shown = ctx.written(v);
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

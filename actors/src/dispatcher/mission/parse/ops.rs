//! `[action.ops.<operation>]`: the operations an action runs and the parameters it sends
//! each, converted to [`Value`]s with the position of every value kept for stage 2's messages.

use super::super::parsed::{ParsedOp, ParsedParam};
use marie_vocabulary::diagnostic::toml::{quote, Reader, Tbl, Val};
use marie_vocabulary::diagnostic::Pos;
use marie_vocabulary::property::Value;
use std::borrow::Cow;
use std::collections::BTreeMap;
use toml::de::DeValue;
use toml::Spanned;

/// The operations of `ops`, the action's `[action.ops]` table, in file order.
pub(super) fn read_all(ctx: &mut Reader<'_>, ops: &Tbl<'_, '_>) -> Vec<ParsedOp> {
    ops.in_file_order()
        .into_iter()
        .map(|(key, v)| read(ctx, key, v))
        .collect()
}

/// One `[action.ops.<key>]` table. The operation is kept even when malformed (its problems
/// are reported), so that `ends_on` naming it does not cause a second, misleading
/// diagnostic.
fn read(ctx: &mut Reader<'_>, key: &Spanned<Cow<'_, str>>, v: &Val<'_>) -> ParsedOp {
    let mut op = ParsedOp {
        key: key.get_ref().to_string(),
        at: ctx.pos(&key.span()),
        params: Vec::new(),
    };
    if op.key.trim().is_empty() {
        ctx.err(&key.span(), "an operation name must not be empty");
        return op;
    }
    let place = format!("`[action.ops.{}]`", op.key.escape_debug());
    let expected = format!(
        "a table of parameters for operation {} ({place})",
        quote(&op.key)
    );
    let Some(t) = ctx.table_or(v, &place, &expected) else {
        return op;
    };
    for (pkey, pv) in t.in_file_order() {
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
    ctx: &mut Reader<'_>,
    v: &Val<'_>,
    path: &str,
    op: &str,
    at: &mut BTreeMap<String, Pos>,
) -> Option<Value> {
    at.insert(path.to_string(), ctx.pos(&v.span()));
    match v.get_ref() {
        DeValue::String(s) => Some(Value::Text(s.to_string())),
        DeValue::Boolean(b) => Some(Value::Bool(*b)),
        DeValue::Integer(_) => ctx.int_value(v, path).map(Value::Int),
        DeValue::Float(_) => ctx.float_value(v, path).map(Value::Float),
        DeValue::Datetime(d) => {
            ctx.err(
                &v.span(),
                format!(
                    "parameter {} of operation {}: the datetime {d} has no parameter type (expected a bool, integer, float, string, array or table)",
                    quote(path),
                    quote(op)
                ),
            );
            None
        }
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
            let t = Tbl {
                t,
                span: v.span(),
                place: quote(path),
            };
            for (k, item) in t.in_file_order() {
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

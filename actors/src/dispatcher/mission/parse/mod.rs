//! Stage 1: from TOML text to a [`ParsedMission`], a file per table.
//!
//! The text is parsed by toml's span-preserving parser and walked by hand with the shared
//! [`Reader`]: a derived `Deserialize` stops at the first problem; walking the table lets one
//! pass report *every* unknown key, wrong type and missing field, each at its own position.
//! Each table is read into a raw structure, its fields typed but not cross-checked
//! ([`header`], [`flags`], [`action`] and its [`ops`], [`group`], the [`control_keys`] both
//! share); then [`resolve`] relates them — flag bits and names, action and group names,
//! `ends_on` — and, once every name is known, [`structure`](super::structure) checks how
//! actions and groups name each other.

mod action;
mod closest;
mod control_keys;
mod flags;
mod group;
mod header;
mod names;
mod ops;
mod resolve;
mod seconds;

use super::ParsedMission;
use marie_vocabulary::diagnostic::toml::{Reader, Tbl};
use marie_vocabulary::diagnostic::Diagnostics;
use resolve::Tables;
use std::path::Path;

/// The top-level tables a mission file may have.
const TOP_KEYS: &[&str] = &["mission", "flags", "action", "requires", "pin", "group"];

/// Stage 1 entry point: every table read, then related, then the structure checked.
pub(crate) fn parse(src: &str, path: Option<&Path>) -> Result<ParsedMission, Diagnostics> {
    let mut ctx = Reader::new(src, super::display_path(path));
    let Some(doc) = ctx.parse() else {
        let mut syntax = Diagnostics(ctx.into_diagnostics());
        syntax.sort();
        return Err(syntax);
    };
    let top = ctx.top(&doc, "the mission file");
    ctx.unknown_keys(&top, TOP_KEYS);
    let tables = read_tables(&mut ctx, &top);
    let mission = resolve::mission(&mut ctx, path, tables);
    if !ctx.has_errors() {
        // how actions and groups name each other: only once every name is known
        super::structure::check(&mut ctx, &mission);
    }
    Diagnostics(ctx.into_diagnostics()).into_result(mission)
}

/// Read the top-level tables, in the order their problems have always been found in.
fn read_tables(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> Tables {
    let header = header::read(ctx, top.get("mission"));
    let flags = top
        .get("flags")
        .map(|v| flags::read(ctx, v))
        .unwrap_or_default();
    let actions = action::read_all(ctx, top.get("action"), &header.at);
    let groups = top
        .get("group")
        .map(|v| group::read_all(ctx, v))
        .unwrap_or_default();
    let requires = top
        .get("requires")
        .map(|v| header::requires(ctx, v))
        .unwrap_or_default();
    let pins = top
        .get("pin")
        .map(|v| header::pins(ctx, v))
        .unwrap_or_default();
    Tables {
        header,
        flags,
        actions,
        groups,
        requires,
        pins,
    }
}

//! The checks of stage 1 that relate the tables to each other: flag bits and the flags named,
//! the one name space of actions and groups, and every name an action or a group writes.

use super::super::parsed::Item;
use super::super::ParsedMission;
use super::action::RawAction;
use super::flags::{Flags, RawFlag};
use super::group::RawGroup;
use super::header::{RawHeader, Requirement};
use super::names::Refs;
use marie_vocabulary::diagnostic::toml::{quote, Reader};
use marie_vocabulary::diagnostic::{beside, Pos};
use std::collections::BTreeMap;
use std::path::Path;
use toml::Spanned;

/// Every table of the file, read on its own.
pub(super) struct Tables {
    pub(super) header: RawHeader,
    pub(super) flags: Vec<RawFlag>,
    pub(super) actions: Vec<RawAction>,
    pub(super) groups: Vec<RawGroup>,
    pub(super) requires: Vec<Requirement>,
    pub(super) pins: Vec<Requirement>,
}

/// The mission the tables make, every name in it resolved.
pub(super) fn mission(ctx: &mut Reader<'_>, path: Option<&Path>, tables: Tables) -> ParsedMission {
    let Tables {
        header,
        flags,
        actions,
        groups,
        requires,
        pins,
    } = tables;
    let flags = Flags::resolve(ctx, flags);
    let initial = flags.refs(ctx, &header.initial, "mission.initial");
    let success = flags.refs(ctx, &header.success, "mission.success");
    let items = in_file_order(&actions, &groups);
    let names = names(ctx, &items, &actions, &groups);
    let refs = Refs {
        flags: &flags,
        names: &names,
    };
    let actions = actions.into_iter().map(|a| a.resolve(ctx, &refs)).collect();
    let groups = groups.into_iter().map(|g| g.resolve(ctx, &refs)).collect();
    ParsedMission {
        file: super::super::display_path(path),
        path: path.map(Path::to_path_buf),
        name: header.name.map(Spanned::into_inner).unwrap_or_default(),
        description: header
            .description
            .map(Spanned::into_inner)
            .unwrap_or_default(),
        flags: flags.bits,
        initial,
        success,
        deadline: header.deadline,
        rebind_deadline: header.rebind_deadline,
        world_at: header.world.as_ref().map(|w| ctx.pos(&w.span())),
        world: header.world.map(|w| beside(path, w.get_ref())),
        actions,
        groups,
        items,
        requires,
        pins,
    }
}

/// Every action and group, in file order: actions and groups share one name space, and a
/// duplicate is reported where it is written again.
fn in_file_order(actions: &[RawAction], groups: &[RawGroup]) -> Vec<Item> {
    let mut items: Vec<(usize, Item)> = actions
        .iter()
        .enumerate()
        .map(|(i, a)| (a.at.start, Item::Action(i)))
        .chain(
            groups
                .iter()
                .enumerate()
                .map(|(i, g)| (g.at.start, Item::Group(i))),
        )
        .collect();
    items.sort();
    items.into_iter().map(|(_, item)| item).collect()
}

/// Each name and the item it names — the first to use it; a name used again is reported.
fn names(
    ctx: &mut Reader<'_>,
    items: &[Item],
    actions: &[RawAction],
    groups: &[RawGroup],
) -> BTreeMap<String, Item> {
    let mut names: BTreeMap<String, Item> = BTreeMap::new();
    let mut first_use: BTreeMap<String, Pos> = BTreeMap::new();
    for item in items {
        let name = match item {
            Item::Action(i) => actions[*i].name.as_ref(),
            Item::Group(i) => groups[*i].name.as_ref(),
        };
        let Some(n) = name else { continue };
        match (first_use.get(n.get_ref()), names.get(n.get_ref())) {
            (Some(first), Some(Item::Action(_))) if matches!(item, Item::Action(_)) => {
                let msg = format!(
                    "duplicate action name {} (first used at {first}; action names must be unique)",
                    quote(n.get_ref())
                );
                ctx.err(&n.span(), msg);
            }
            (Some(first), Some(by)) => {
                let msg = format!(
                    "duplicate name {} (first used at {first} by {}; action and group names must be unique)",
                    quote(n.get_ref()),
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
    names
}

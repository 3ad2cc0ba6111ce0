//! What the names a mission writes are resolved against: its flags, and the one name space of
//! its actions and groups — a name that misses is reported with the closest name, or the
//! names there are.

use super::super::parsed::{Item, ItemRef};
use super::closest::closest;
use super::flags::Flags;
use marie_vocabulary::diagnostic::toml::{name_list, quote, Reader};
use std::collections::BTreeMap;
use toml::Spanned;

/// What names in `when`, the control keys and `children` are resolved against.
pub(super) struct Refs<'a> {
    /// The flags `[flags]` declares.
    pub(super) flags: &'a Flags,
    /// Every action and group, by name.
    pub(super) names: &'a BTreeMap<String, Item>,
}

impl Refs<'_> {
    /// The action or group `name` names, or a diagnostic with the closest name or the
    /// names there are.
    pub(super) fn item(
        &self,
        ctx: &mut Reader<'_>,
        name: &Spanned<String>,
        field: &str,
    ) -> Option<ItemRef> {
        if let Some(item) = self.names.get(name.get_ref()) {
            return Some(ItemRef {
                item: *item,
                at: ctx.pos(&name.span()),
            });
        }
        let hint = match closest(name.get_ref(), self.names.keys()) {
            Some(near) => format!("did you mean {}?", quote(near)),
            None if self.names.is_empty() => "the mission names none".to_string(),
            None => format!("expected one of: {}", name_list(self.names.keys())),
        };
        ctx.err(
            &name.span(),
            format!(
                "unknown action or group {} in `{field}` ({hint})",
                quote(name.get_ref())
            ),
        );
        None
    }
}

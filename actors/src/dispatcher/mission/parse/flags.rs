//! `[flags]` — the names of the status word's bits — and the flags named elsewhere
//! (`initial`, `success`, `when`, `while`, `unless`), resolved to their bits.

use super::super::parsed::FlagRef;
use marie_vocabulary::diagnostic::toml::{name_list, quote, Reader, Val};
use std::collections::{BTreeMap, BTreeSet};
use toml::de::DeValue;
use toml::Spanned;

/// A `[flags]` entry: its name, and its bit when that is a valid bit number.
pub(super) type RawFlag = (Spanned<String>, Option<Spanned<u8>>);

/// The `[flags]` entries, in file order. Entries with an invalid bit are kept (without a bit)
/// so that naming them elsewhere is not reported a second time as an unknown flag.
pub(super) fn read(ctx: &mut Reader<'_>, v: &Val<'_>) -> Vec<RawFlag> {
    let Some(t) = ctx.table_or(
        v,
        "`[flags]`",
        "a table `[flags]` of flag names and bit numbers",
    ) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (key, v) in t.in_file_order() {
        let name = key.get_ref().to_string();
        if name.trim().is_empty() {
            ctx.err(&key.span(), "a flag name must not be empty");
            continue;
        }
        let name = Spanned::new(key.span(), name);
        let bit = bit(ctx, &name, v);
        out.push((name, bit));
    }
    out
}

/// The bit of flag `name`: an integer of 0..=31.
fn bit(ctx: &mut Reader<'_>, name: &Spanned<String>, v: &Val<'_>) -> Option<Spanned<u8>> {
    if !matches!(v.get_ref(), DeValue::Integer(_)) {
        return ctx.expected(
            v,
            format_args!("a bit number 0..=31 for flag {}", quote(name.get_ref())),
        );
    }
    let bit = ctx.int_value(v, name.get_ref())?;
    match u8::try_from(bit).ok().filter(|b| *b < 32) {
        Some(b) => Some(Spanned::new(v.span(), b)),
        None => {
            ctx.err(
                &v.span(),
                format!(
                    "bit {bit} of flag {} is out of range (expected 0..=31: the status word has 32 bits)",
                    quote(name.get_ref())
                ),
            );
            None
        }
    }
}

/// The flags of a mission: each name's bit, and every name declared (a name declared with an
/// invalid bit, reported already, has no bit but is no unknown flag either).
pub(super) struct Flags {
    pub(super) bits: BTreeMap<String, u8>,
    declared: BTreeSet<String>,
}

impl Flags {
    /// The flags `[flags]` declares; a bit given twice is reported where it is given again.
    pub(super) fn resolve(ctx: &mut Reader<'_>, raw: Vec<RawFlag>) -> Flags {
        let declared = raw.iter().map(|(n, _)| n.get_ref().clone()).collect();
        let mut bits = BTreeMap::new();
        let mut owner: BTreeMap<u8, String> = BTreeMap::new();
        for (name, bit) in raw {
            let Some(bit) = bit else { continue };
            let b = *bit.get_ref();
            if let Some(first) = owner.get(&b) {
                let msg = format!(
                    "bit {b} of flag {} is already used by flag {} (each flag needs its own bit)",
                    quote(name.get_ref()),
                    quote(first)
                );
                ctx.err(&bit.span(), msg);
                continue;
            }
            owner.insert(b, name.get_ref().clone());
            bits.insert(name.into_inner(), b);
        }
        Flags { bits, declared }
    }

    /// Flag names resolved to bits, reporting names not declared in `[flags]`.
    pub(super) fn refs(
        &self,
        ctx: &mut Reader<'_>,
        names: &[Spanned<String>],
        field: &'static str,
    ) -> Vec<FlagRef> {
        let mut out = Vec::new();
        for n in names {
            match self.bits.get(n.get_ref()) {
                Some(bit) => out.push(FlagRef {
                    name: n.get_ref().clone(),
                    bit: *bit,
                    at: ctx.pos(&n.span()),
                    field,
                }),
                None if self.declared.contains(n.get_ref()) => {}
                None if self.declared.is_empty() => ctx.err(
                    &n.span(),
                    format!(
                        "unknown flag {} in `{field}` (no flags are declared: add it to `[flags]`)",
                        quote(n.get_ref())
                    ),
                ),
                None => ctx.err(
                    &n.span(),
                    format!(
                        "unknown flag {} in `{field}` (expected one of: {})",
                        quote(n.get_ref()),
                        name_list(&self.declared)
                    ),
                ),
            }
        }
        out
    }
}

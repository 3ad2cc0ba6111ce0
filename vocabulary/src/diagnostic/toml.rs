//! The span-keeping TOML reader shared by every file loader (missions, worlds, node configs).
//!
//! The text is parsed by toml's span-preserving parser ([`DeTable`]: every key and value is a
//! [`Spanned`]) and walked by hand. A derived `Deserialize` stops at the first problem; walking
//! the table lets one pass report *every* unknown key, wrong type, missing field and
//! out-of-range number, each at its own position — which is what a person fixing a file by
//! hand needs. A [`Reader`] collects the problems; its helpers return `None` (or a default)
//! after recording one, so a loader simply carries on and reports the rest.

use super::{Diagnostic, Diagnostics, LineIndex, Pos};
use std::ops::{Range, RangeInclusive};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// A byte range of the source.
pub type Span = Range<usize>;

/// A value with its span.
pub type Val<'i> = Spanned<DeValue<'i>>;

/// Where problems go while a document is walked.
pub struct Reader<'s> {
    src: &'s str,
    lines: LineIndex<'s>,
    file: String,
    diags: Vec<Diagnostic>,
}

impl std::fmt::Debug for Reader<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reader")
            .field("file", &self.file)
            .field("lines", &self.lines)
            .finish_non_exhaustive()
    }
}

/// A table being read: its entries, where it starts, and how messages name it
/// (e.g. `[cart]`, `[[operation]] #2`).
pub struct Tbl<'a, 'i> {
    /// The entries.
    pub t: &'a DeTable<'i>,
    /// Where the table starts (missing keys are reported here).
    pub span: Span,
    /// How messages name the table.
    pub place: String,
}

impl std::fmt::Debug for Tbl<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tbl")
            .field("place", &self.place)
            .field("span", &self.span)
            .field("keys", &self.t.len())
            .finish()
    }
}

impl<'a, 'i> Tbl<'a, 'i> {
    /// The value of `key`, if present.
    pub fn get(&self, key: &str) -> Option<&'a Val<'i>> {
        self.t.get(key)
    }

    /// The same table named otherwise in messages — e.g. by the name it gives itself, once
    /// that is read (`` group `g` `` rather than `[[group]]`).
    pub fn named(&self, place: impl Into<String>) -> Tbl<'a, 'i> {
        Tbl {
            t: self.t,
            span: self.span.clone(),
            place: place.into(),
        }
    }

    /// The entries in file order (toml's map orders keys by name).
    pub fn in_file_order(&self) -> Vec<(&'a Spanned<std::borrow::Cow<'i, str>>, &'a Val<'i>)> {
        let mut entries: Vec<_> = self.t.iter().collect();
        entries.sort_by_key(|(k, _)| k.span().start);
        entries
    }
}

/// What a number must satisfy; the message says the rule in words.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rule {
    /// Any finite number.
    Any,
    /// x > 0.
    Positive,
    /// x ≥ 0.
    NonNegative,
    /// lo < x ≤ hi.
    AboveUpTo(f64, f64),
    /// lo < x < hi.
    Between(f64, f64),
    /// lo ≤ x ≤ hi.
    Within(f64, f64),
}

impl Rule {
    /// `Ok` when `x` satisfies the rule, otherwise the rule and the number that broke it.
    pub fn check(self, x: f64) -> Result<(), OutOfRule> {
        let ok = match self {
            Rule::Any => x.is_finite(),
            Rule::Positive => x > 0.0,
            Rule::NonNegative => x >= 0.0,
            Rule::AboveUpTo(lo, hi) => x > lo && x <= hi,
            Rule::Between(lo, hi) => x > lo && x < hi,
            Rule::Within(lo, hi) => x >= lo && x <= hi,
        };
        if ok {
            Ok(())
        } else {
            Err(OutOfRule {
                rule: self,
                found: x,
            })
        }
    }

    /// What the rule expects, in words: `greater than 0`, `in [0, 10]`.
    pub fn expected(self) -> String {
        match self {
            Rule::Any => "a finite number".to_string(),
            Rule::Positive => "greater than 0".to_string(),
            Rule::NonNegative => "at least 0".to_string(),
            Rule::AboveUpTo(lo, hi) => format!("in ({lo}, {hi}]"),
            Rule::Between(lo, hi) => format!("in ({lo}, {hi})"),
            Rule::Within(lo, hi) => format!("in [{lo}, {hi}]"),
        }
    }
}

/// A number that breaks its [`Rule`]: which rule, and the number, so a caller can tell a
/// bound from a non-finite number without reading text. The rule already names every kind
/// of failure, so this carries it rather than repeating its variants. Displayed as what
/// was expected (`greater than 0`), the words a message puts after "must be", since the
/// number is best shown as the file wrote it ([`literal`]).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("{}", .rule.expected())]
pub struct OutOfRule {
    /// The rule broken.
    pub rule: Rule,
    /// The number that broke it.
    pub found: f64,
}

/// Text from the file, quoted for a message: `` `name` ``, with control characters escaped.
pub fn quote(text: &str) -> String {
    format!("`{}`", text.escape_debug())
}

/// Names from the file for an "expected one of" hint: `a, b, c`, each with control
/// characters escaped (as [`quote`] does), without quotes — a hint lists many.
pub fn name_list<S: AsRef<str>>(names: impl IntoIterator<Item = S>) -> String {
    names
        .into_iter()
        .map(|n| n.as_ref().escape_debug().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

impl<'s> Reader<'s> {
    /// A reader of `src`, naming `file` in its diagnostics.
    pub fn new(src: &'s str, file: impl Into<String>) -> Self {
        Reader {
            src,
            lines: LineIndex::new(src),
            file: file.into(),
            diags: Vec::new(),
        }
    }

    /// The text being read.
    pub fn src(&self) -> &'s str {
        self.src
    }

    /// The file name diagnostics show.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The position of the start of `span`.
    pub fn pos(&self, span: &Span) -> Pos {
        self.lines.span(span)
    }

    /// Record a problem at the start of `span`.
    pub fn err(&mut self, span: &Span, message: impl Into<String>) {
        let d = Diagnostic::at(&self.file, self.pos(span), message);
        self.diags.push(d);
    }

    /// Record that `v` is of the wrong type: `expected {what}, found {its type}` — the one
    /// wording of every getter's (and every format's) type mismatch. `None`, for the caller
    /// to return (or `.unwrap_or(default)`).
    pub fn expected<T>(&mut self, v: &Val<'_>, what: impl std::fmt::Display) -> Option<T> {
        let found = v.get_ref().type_str();
        self.err(&v.span(), format!("expected {what}, found {found}"));
        None
    }

    /// Record a diagnostic found elsewhere (e.g. in a file this one names).
    pub fn push(&mut self, d: Diagnostic) {
        self.diags.push(d);
    }

    /// True when a problem has been recorded.
    pub fn has_errors(&self) -> bool {
        !self.diags.is_empty()
    }

    /// The problems recorded so far, consuming the reader.
    pub fn into_diagnostics(self) -> Vec<Diagnostic> {
        self.diags
    }

    /// Parse the document; every syntax error is recorded at its position and `None`
    /// returned.
    pub fn parse(&mut self) -> Option<Spanned<DeTable<'s>>> {
        let (doc, errors) = DeTable::parse_recoverable(self.src);
        if errors.is_empty() {
            return Some(doc);
        }
        for e in errors {
            let span = e.span().unwrap_or(0..0);
            self.err(&span, format!("syntax error: {}", e.message().trim_end()));
        }
        None
    }

    /// The document's top table, named `place` in messages.
    pub fn top<'a, 'i>(&self, doc: &'a Spanned<DeTable<'i>>, place: &str) -> Tbl<'a, 'i> {
        Tbl {
            t: doc.get_ref(),
            span: 0..0,
            place: place.to_string(),
        }
    }

    /// `Ok(value)` when nothing was recorded and there is a value; otherwise the sorted
    /// diagnostics (with `fallback` at 1:1 should a value be missing without a recorded
    /// reason).
    pub fn finish<T>(self, value: Option<T>, fallback: &str) -> Result<T, Diagnostics> {
        match value {
            Some(v) if self.diags.is_empty() => Ok(v),
            _ => {
                let mut diags = Diagnostics(self.diags);
                if diags.is_empty() {
                    diags.0.push(Diagnostic::new(&self.file, 1, 1, fallback));
                }
                diags.sort();
                Err(diags)
            }
        }
    }

    /// The value as a table, or a diagnostic.
    pub fn table<'a, 'i>(&mut self, v: &'a Val<'i>, place: &str) -> Option<Tbl<'a, 'i>> {
        self.table_or(v, place, format!("a table for {place}"))
    }

    /// The value as a table named `place` in messages; otherwise a diagnostic that says what
    /// was expected in the caller's words — `expected {expected}, found {type}` — for a
    /// format whose tables deserve more than "a table" (``a table `[flags]` of flag names
    /// and bit numbers``).
    pub fn table_or<'a, 'i>(
        &mut self,
        v: &'a Val<'i>,
        place: &str,
        expected: impl std::fmt::Display,
    ) -> Option<Tbl<'a, 'i>> {
        match v.get_ref() {
            DeValue::Table(t) => Some(Tbl {
                t,
                span: v.span(),
                place: place.to_string(),
            }),
            _ => self.expected(v, expected),
        }
    }

    /// The items of an array; otherwise a diagnostic, `expected {expected}, found {type}`.
    pub fn array<'a, 'i>(
        &mut self,
        v: &'a Val<'i>,
        expected: impl std::fmt::Display,
    ) -> Option<&'a [Val<'i>]> {
        match v.get_ref() {
            DeValue::Array(items) => Some(items),
            _ => self.expected(v, expected),
        }
    }

    /// The value of `key` in `tbl`; when it is missing, a diagnostic at the table that says
    /// what belongs there: ``missing key `{key}` in {place} (expected {expected})``.
    pub fn required<'a, 'i>(
        &mut self,
        tbl: &Tbl<'a, 'i>,
        key: &str,
        expected: &str,
    ) -> Option<&'a Val<'i>> {
        let v = tbl.get(key);
        if v.is_none() {
            self.err(
                &tbl.span,
                format!("missing key `{key}` in {} (expected {expected})", tbl.place),
            );
        }
        v
    }

    /// Record every key of `tbl` not in `allowed`, in file order.
    pub fn unknown_keys(&mut self, tbl: &Tbl<'_, '_>, allowed: &[&str]) {
        for (key, _) in tbl.in_file_order() {
            if !allowed.contains(&key.get_ref().as_ref()) {
                self.err(
                    &key.span(),
                    format!(
                        "unknown key {} in {} (expected one of: {})",
                        quote(key.get_ref()),
                        tbl.place,
                        allowed.join(", ")
                    ),
                );
            }
        }
    }

    /// A finite number (integer or float), or a diagnostic.
    pub fn number(&mut self, v: &Val<'_>, field: &str) -> Option<f64> {
        let x = match v.get_ref() {
            DeValue::Integer(i) => match i64::from_str_radix(i.as_str(), i.radix()) {
                Ok(n) => n as f64,
                Err(_) => {
                    self.err(&v.span(), format!("`{field}`: integer out of range"));
                    return None;
                }
            },
            DeValue::Float(f) => f.as_str().parse::<f64>().unwrap_or(f64::NAN),
            _ => return self.expected(v, format_args!("a number for `{field}`")),
        };
        if !x.is_finite() {
            self.err(&v.span(), format!("`{field}` must be a finite number"));
            return None;
        }
        Some(x)
    }

    /// Number `key` of `tbl`: `default` when absent (a diagnostic when there is no default),
    /// the value when it satisfies `rule`, otherwise a diagnostic and `None`.
    pub fn num(
        &mut self,
        tbl: &Tbl<'_, '_>,
        key: &str,
        default: Option<f64>,
        rule: Rule,
    ) -> Option<f64> {
        let Some(v) = tbl.get(key) else {
            if default.is_none() {
                self.err(&tbl.span, format!("missing `{key}` in {}", tbl.place));
            }
            return default;
        };
        let x = self.number(v, key)?;
        match rule.check(x) {
            Ok(()) => Some(x),
            Err(want) => {
                self.err(
                    &v.span(),
                    format!("`{key}` must be {want}, found {}", literal(v)),
                );
                None
            }
        }
    }

    /// Integer `key` of `tbl` within `range`: `default` when absent (a diagnostic when there is
    /// no default); a float, a string or a number out of range is a diagnostic and `None`.
    pub fn integer(
        &mut self,
        tbl: &Tbl<'_, '_>,
        key: &str,
        default: Option<i64>,
        range: RangeInclusive<i64>,
    ) -> Option<i64> {
        let Some(v) = tbl.get(key) else {
            if default.is_none() {
                self.err(&tbl.span, format!("missing `{key}` in {}", tbl.place));
            }
            return default;
        };
        let n = match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix()).ok(),
            _ => return self.expected(v, format_args!("an integer for `{key}`")),
        };
        match n {
            Some(n) if range.contains(&n) => Some(n),
            _ => {
                self.err(
                    &v.span(),
                    format!(
                        "`{key}` must be an integer in [{}, {}], found {}",
                        range.start(),
                        range.end(),
                        literal(v)
                    ),
                );
                None
            }
        }
    }

    /// String `key` of `tbl`, if present; a non-string is a diagnostic.
    pub fn string(&mut self, tbl: &Tbl<'_, '_>, key: &str) -> Option<String> {
        let v = tbl.get(key)?;
        self.string_value(v, key)
    }

    /// `key` of `tbl` if it is a string, with its span; `None`, without a diagnostic, when
    /// it is absent or of another type (for a key that takes a string or something else).
    pub fn string_if_one(&self, tbl: &Tbl<'_, '_>, key: &str) -> Option<(String, Span)> {
        let v = tbl.get(key)?;
        match v.get_ref() {
            DeValue::String(s) => Some((s.to_string(), v.span())),
            _ => None,
        }
    }

    /// The value as a string, or a diagnostic naming `field`.
    pub fn string_value(&mut self, v: &Val<'_>, field: &str) -> Option<String> {
        match v.get_ref() {
            DeValue::String(s) => Some(s.to_string()),
            _ => self.expected(v, format_args!("a string for `{field}`")),
        }
    }

    /// The value as a string with its span (for a name that later messages point back
    /// to), or a diagnostic naming `field`.
    pub fn spanned_string(&mut self, v: &Val<'_>, field: &str) -> Option<Spanned<String>> {
        self.string_value(v, field)
            .map(|s| Spanned::new(v.span(), s))
    }

    /// The value as a string that is not blank, with its span; another type or a blank
    /// string is a diagnostic naming `field`.
    pub fn non_empty_string(&mut self, v: &Val<'_>, field: &str) -> Option<Spanned<String>> {
        let s = self.spanned_string(v, field)?;
        if s.get_ref().trim().is_empty() {
            self.err(&v.span(), format!("`{field}` must not be empty"));
            return None;
        }
        Some(s)
    }

    /// The value as an array of strings, each with its span; `None` when it is not an
    /// array (a diagnostic); an item that is not a string is a diagnostic —
    /// ``expected a string in `{field}` `` — and left out.
    pub fn string_list(&mut self, v: &Val<'_>, field: &str) -> Option<Vec<Spanned<String>>> {
        let items = self.array(v, format!("an array of strings for `{field}`"))?;
        let strings = items
            .iter()
            .filter_map(|item| match item.get_ref() {
                DeValue::String(s) => Some(Spanned::new(item.span(), s.to_string())),
                _ => self.expected(item, format_args!("a string in `{field}`")),
            })
            .collect();
        Some(strings)
    }

    /// The value as a 64-bit integer; another type, or an integer too large for 64 bits
    /// (shown as the file wrote it), is a diagnostic.
    pub fn int_value(&mut self, v: &Val<'_>, field: &str) -> Option<i64> {
        let DeValue::Integer(i) = v.get_ref() else {
            return self.expected(v, format_args!("an integer for `{field}`"));
        };
        let parsed = i64::from_str_radix(i.as_str(), i.radix()).ok();
        if parsed.is_none() {
            let shown = self.written(v);
            self.err(
                &v.span(),
                format!("integer {shown} is out of range (expected a 64-bit signed integer)"),
            );
        }
        parsed
    }

    /// The value as a 64-bit float, as written: `inf` and `nan` are kept (a caller that
    /// needs a finite number says so in its own words); another type, or a literal beyond
    /// a 64-bit float (`1e400`, shown as the file wrote it), is a diagnostic.
    pub fn float_value(&mut self, v: &Val<'_>, field: &str) -> Option<f64> {
        let DeValue::Float(f) = v.get_ref() else {
            return self.expected(v, format_args!("a float for `{field}`"));
        };
        match f.as_str().parse::<f64>() {
            Ok(x) if x.is_finite() || f.as_str().contains("inf") || x.is_nan() => Some(x),
            _ => {
                let shown = self.written(v);
                self.err(
                    &v.span(),
                    format!("float {shown} is out of range (expected a 64-bit float)"),
                );
                None
            }
        }
    }

    /// The value's text as the file wrote it.
    pub fn written(&self, v: &Val<'_>) -> String {
        self.src.get(v.span()).unwrap_or_default().to_string()
    }

    /// Array of strings `key` of `tbl`, each with its span; `None` if absent or not an array
    /// (a diagnostic); an item that is not a string is a diagnostic and left out.
    pub fn string_array(&mut self, tbl: &Tbl<'_, '_>, key: &str) -> Option<Vec<(String, Span)>> {
        let v = tbl.get(key)?;
        let items = self.array(v, format!("an array of strings for `{key}`"))?;
        Some(
            items
                .iter()
                .filter_map(|item| Some((self.string_value(item, key)?, item.span())))
                .collect(),
        )
    }

    /// A non-empty string `key` of `tbl`; missing or blank is a diagnostic.
    pub fn required_string(&mut self, tbl: &Tbl<'_, '_>, key: &str) -> Option<String> {
        let Some(v) = tbl.get(key) else {
            self.err(&tbl.span, format!("missing `{key}` in {}", tbl.place));
            return None;
        };
        self.non_empty_string(v, key).map(Spanned::into_inner)
    }

    /// Boolean `key` of `tbl`, `default` when absent or not a boolean (then a diagnostic).
    pub fn boolean(&mut self, tbl: &Tbl<'_, '_>, key: &str, default: bool) -> bool {
        let Some(v) = tbl.get(key) else {
            return default;
        };
        match v.get_ref() {
            DeValue::Boolean(b) => *b,
            _ => self
                .expected(v, format_args!("true or false for `{key}`"))
                .unwrap_or(default),
        }
    }

    /// The tables of a `[[name]]` array, or diagnostics (`None` for an entry that is not a
    /// table, so callers keep their numbering).
    pub fn table_array<'a, 'i>(&mut self, v: &'a Val<'i>, name: &str) -> Vec<Option<Tbl<'a, 'i>>> {
        let Some(items) = self.array(v, format!("`[[{name}]]` tables")) else {
            return Vec::new();
        };
        items
            .iter()
            .enumerate()
            .map(|(i, item)| self.table(item, &format!("[[{name}]] #{}", i + 1)))
            .collect()
    }
}

/// The literal text of a scalar as the file wrote it, for messages (`1e300`, not its
/// 301-digit expansion).
pub fn literal(v: &Val<'_>) -> String {
    match v.get_ref() {
        DeValue::Integer(i) => i.as_str().to_string(),
        DeValue::Float(f) => f.as_str().to_string(),
        DeValue::String(s) => quote(s),
        DeValue::Boolean(b) => b.to_string(),
        other => other.type_str().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(src: &str, f: impl FnOnce(&mut Reader<'_>, &Tbl<'_, '_>)) -> String {
        let mut r = Reader::new(src, "f.toml");
        let doc = r.parse().expect("valid toml");
        let top = r.top(&doc, "the file");
        f(&mut r, &top);
        match r.finish(Some(()), "invalid") {
            Ok(()) => String::new(),
            Err(d) => d.to_string(),
        }
    }

    #[test]
    fn every_problem_is_reported_at_its_own_position() {
        let out = read("a = \"x\"\nb = 3.5\nzz = 1\nc = 1e400\n", |r, t| {
            r.unknown_keys(t, &["a", "b", "c"]);
            assert_eq!(r.num(t, "a", None, Rule::Any), None);
            assert_eq!(r.integer(t, "b", Some(1), 0..=9), None);
            assert_eq!(r.num(t, "c", None, Rule::Any), None);
            assert_eq!(r.num(t, "d", Some(2.0), Rule::Any), Some(2.0));
            assert_eq!(r.num(t, "e", None, Rule::Any), None);
        });
        assert_eq!(
            out,
            "f.toml:1:1: missing `e` in the file\n\
             f.toml:1:5: expected a number for `a`, found string\n\
             f.toml:2:5: expected an integer for `b`, found float\n\
             f.toml:3:1: unknown key `zz` in the file (expected one of: a, b, c)\n\
             f.toml:4:5: `c` must be a finite number"
        );
    }

    #[test]
    fn integers_and_rules_name_their_range() {
        let out = read("n = 12\nx = 0\n", |r, t| {
            assert_eq!(r.integer(t, "n", None, 1..=10), None);
            assert_eq!(r.num(t, "x", None, Rule::Positive), None);
        });
        assert_eq!(
            out,
            "f.toml:1:5: `n` must be an integer in [1, 10], found 12\n\
             f.toml:2:5: `x` must be greater than 0, found 0"
        );
    }

    #[test]
    fn a_broken_rule_is_matched_by_the_rule_and_says_what_was_expected() {
        assert_eq!(Rule::Positive.check(1.0), Ok(()));
        let err = Rule::Within(0.0, 10.0).check(12.5).unwrap_err();
        assert!(
            matches!(err, OutOfRule { rule: Rule::Within(lo, hi), found }
                if lo == 0.0 && hi == 10.0 && found == 12.5),
            "{err:?}"
        );
        assert_eq!(err.to_string(), "in [0, 10]");
        let err = Rule::Any.check(f64::NAN).unwrap_err();
        assert!(matches!(err.rule, Rule::Any) && err.found.is_nan());
        assert_eq!(err.to_string(), "a finite number");
        assert_eq!(
            Rule::AboveUpTo(0.0, 1.0)
                .check(0.0)
                .unwrap_err()
                .to_string(),
            "in (0, 1]"
        );
        assert_eq!(
            Rule::Between(0.0, 1.0).check(1.0).unwrap_err().to_string(),
            "in (0, 1)"
        );
        assert_eq!(
            Rule::NonNegative.check(-1.0).unwrap_err().to_string(),
            "at least 0"
        );
    }

    #[test]
    fn value_getters_say_what_was_expected_in_the_callers_words() {
        let src = "t = 1\na = \"x\"\ns = [\"p\", 2, \"q\"]\ne = \" \"\n\
                   big = 99999999999999999999\nf = 1e400\ni = inf\nn = 7\nx = 2.5\n";
        let out = read(src, |r, t| {
            let v = |k: &str| t.get(k).expect(k);
            assert!(r
                .table_or(v("t"), "`t`", "a table `[t]` of things")
                .is_none());
            assert!(r.array(v("a"), "an array of names").is_none());
            assert!(r.required(t, "zz", "a name, a string").is_none());
            assert!(r
                .required(&t.named("the thing `t`"), "yy", "more")
                .is_none());
            let list = r.string_list(v("s"), "things.s").expect("an array");
            assert_eq!(
                list.iter()
                    .map(|s| s.get_ref().as_str())
                    .collect::<Vec<_>>(),
                ["p", "q"]
            );
            assert_eq!(
                list[1].span(),
                src.find("\"q\"").map(|at| at..at + 3).unwrap()
            );
            assert_eq!(
                r.spanned_string(v("a"), "a").map(|s| s.into_inner()),
                Some("x".into())
            );
            assert!(r.non_empty_string(v("e"), "things.e").is_none());
            assert_eq!(r.int_value(v("n"), "n"), Some(7));
            assert_eq!(r.int_value(v("big"), "big"), None);
            assert_eq!(r.int_value(v("x"), "x"), None);
            assert_eq!(r.float_value(v("x"), "x"), Some(2.5));
            assert_eq!(r.float_value(v("i"), "i"), Some(f64::INFINITY));
            assert_eq!(r.float_value(v("f"), "f"), None);
            assert_eq!(r.float_value(v("n"), "n"), None);
            assert_eq!(r.written(v("big")), "99999999999999999999");
        });
        assert_eq!(
            out,
            "f.toml:1:1: missing key `zz` in the file (expected a name, a string)\n\
             f.toml:1:1: missing key `yy` in the thing `t` (expected more)\n\
             f.toml:1:5: expected a table `[t]` of things, found integer\n\
             f.toml:2:5: expected an array of names, found string\n\
             f.toml:3:11: expected a string in `things.s`, found integer\n\
             f.toml:4:5: `things.e` must not be empty\n\
             f.toml:5:7: integer 99999999999999999999 is out of range (expected a 64-bit signed integer)\n\
             f.toml:6:5: float 1e400 is out of range (expected a 64-bit float)\n\
             f.toml:8:5: expected a float for `n`, found integer\n\
             f.toml:9:5: expected an integer for `x`, found float"
        );
    }

    #[test]
    fn a_name_list_escapes_what_a_terminal_would_act_on() {
        assert_eq!(name_list(["a", "b\u{7}c"]), "a, b\\u{7}c");
        assert_eq!(name_list(Vec::<String>::new()), "");
    }

    #[test]
    fn syntax_errors_are_positioned_and_stop_the_walk() {
        let mut r = Reader::new("a = \n", "f.toml");
        assert!(r.parse().is_none());
        let d = r.finish::<()>(None, "invalid").unwrap_err();
        assert!(d.to_string().starts_with("f.toml:1:"), "{d}");
    }
}

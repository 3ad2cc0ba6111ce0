//! The hint for a name that names nothing: the name it is likely a typo of.

/// The name among `names` closest to `name` (by edit distance), when close enough to be a
/// typo of it.
pub(super) fn closest<'n>(
    name: &str,
    names: impl IntoIterator<Item = &'n String>,
) -> Option<&'n str> {
    let within = (name.chars().count() / 3).max(1);
    names
        .into_iter()
        .map(|n| (distance(name, n), n))
        .filter(|(d, _)| *d <= within)
        .min_by_key(|(d, _)| *d)
        .map(|(_, n)| n.as_str())
}

/// Levenshtein distance, in characters.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let up = row[j + 1];
            row[j + 1] = (up + 1).min(row[j] + 1).min(diag + usize::from(ca != *cb));
            diag = up;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typo_finds_its_name_and_a_stranger_finds_none() {
        let names = ["find-wall".to_string(), "park".to_string()];
        assert_eq!(closest("find-wal", &names), Some("find-wall"));
        assert_eq!(closest("parc", &names), Some("park"));
        assert_eq!(closest("dock", &names), None);
        assert_eq!(distance("kitten", "sitting"), 3);
    }
}

//! The files two runs read, compared: paired by role (the mission with the mission, the world
//! with the world, …), the same when their SHA-256 is, else a unified diff of their texts.
//!
//! Why by role and not by path: a mission copied elsewhere and edited is the question
//! `marie diff` is asked most (what did I change between these two runs?), and its path is
//! what changed least usefully.

use super::aspects::{Difference, Side};
use marie::run::{FileRead, FileRole, Provenance};
use serde_json::json;
use similar::{ChangeTag, TextDiff};
use std::time::Duration;

/// The roles in the order a run reads its files.
const ROLES: [FileRole; 4] = [
    FileRole::Mission,
    FileRole::World,
    FileRole::Node,
    FileRole::Cluster,
];

/// How long the diff of one pair of texts may search for the shortest edit: past it, a
/// coarser (still correct) diff is given. Reports' texts are small; this only bounds a
/// pathological one.
const DIFF_DEADLINE: Duration = Duration::from_secs(2);

/// The files of `a` and `b`, paired by role (the n-th of a role with the n-th), or `None`
/// when every pair has the same SHA-256.
pub(crate) fn compare(a: &Provenance, b: &Provenance) -> Option<Difference> {
    let mut diff = Difference::default();
    let mut summary = Vec::new();
    let mut json = serde_json::Map::new();
    for role in ROLES {
        let of = |p: &'_ Provenance| -> Vec<FileRead> {
            p.files.iter().filter(|f| f.role == role).cloned().collect()
        };
        let (fa, fb) = (of(a), of(b));
        for i in 0..fa.len().max(fb.len()) {
            // the first of a role is named by it, later ones by their place (`world 2`)
            let label = match i {
                0 => role.name().to_string(),
                n => format!("{role} {}", n + 1),
            };
            match (fa.get(i), fb.get(i)) {
                (Some(x), Some(y)) if x.sha256 == y.sha256 => {}
                (Some(x), Some(y)) => {
                    let text = unified(x, y);
                    let (plus, minus) = counts(&x.text, &y.text);
                    summary.push(format!("{label} +{plus} -{minus}"));
                    diff.lines
                        .push(format!("  {label}: {} -> {}", x.path, y.path));
                    if text.is_empty() {
                        // the same text under another digest: nothing to show but the digests
                        diff.lines
                            .push(format!("    sha256 {} -> {}", x.sha256, y.sha256));
                    }
                    diff.lines.extend(text.lines().map(str::to_string));
                    json.insert(
                        label,
                        json!({"a": x.path, "b": y.path, "sha256": {"a": x.sha256, "b": y.sha256},
                               "diff": text}),
                    );
                }
                (only_a, only_b) => {
                    let (side, file) = match (only_a, only_b) {
                        (Some(f), _) => (Side::A, f),
                        (_, Some(f)) => (Side::B, f),
                        // i < the longer list's length: one of them holds it
                        (None, None) => continue,
                    };
                    summary.push(format!("{label} only in {side}"));
                    diff.lines
                        .push(format!("  {label}: only in {side} ({})", file.path));
                    json.insert(label, json!({side.name(): file.path}));
                }
            }
        }
    }
    if summary.is_empty() {
        return None;
    }
    diff.summary = summary.join(", ");
    diff.json = json.into();
    Some(diff)
}

/// The unified diff of the texts of `a` and `b` (`--- a/PATH`, `+++ b/PATH`, hunks with 3
/// lines of context); empty when the texts are the same.
pub(crate) fn unified(a: &FileRead, b: &FileRead) -> String {
    if a.text == b.text {
        return String::new();
    }
    let diff = TextDiff::configure()
        .timeout(DIFF_DEADLINE)
        .diff_lines(&a.text, &b.text);
    let (ha, hb) = (
        format!("a/{}", a.path.trim_start_matches('/')),
        format!("b/{}", b.path.trim_start_matches('/')),
    );
    diff.unified_diff()
        .context_radius(3)
        .header(&ha, &hb)
        .to_string()
}

/// How many lines `b` adds to `a`'s text, and how many it removes.
fn counts(a: &str, b: &str) -> (usize, usize) {
    let diff = TextDiff::configure()
        .timeout(DIFF_DEADLINE)
        .diff_lines(a, b);
    diff.iter_all_changes()
        .fold((0, 0), |(plus, minus), c| match c.tag() {
            ChangeTag::Insert => (plus + 1, minus),
            ChangeTag::Delete => (plus, minus + 1),
            ChangeTag::Equal => (plus, minus),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::run::Digest;

    fn file(role: FileRole, path: &str, text: &str) -> FileRead {
        FileRead {
            role,
            path: path.into(),
            // a digest that tells the texts apart is enough here
            sha256: Digest(format!("{:x}", text.len() * 31 + text.lines().count())),
            text: text.into(),
        }
    }

    fn provenance(files: Vec<FileRead>) -> Provenance {
        Provenance {
            files,
            ..Provenance::default()
        }
    }

    const MISSION: &str = "[mission]\nname = \"m\"\n\n[[action]]\nname = \"a\"\n\n\
                           [action.ops.wall-follower]\ndistance = 0.8\n\n[flags]\nx = 0\ny = 1\n";

    #[test]
    fn an_edited_line_is_a_hunk_with_three_lines_of_context_under_a_and_b_headers() {
        let a = file(FileRole::Mission, "missions/m.toml", MISSION);
        let b = file(
            FileRole::Mission,
            "/tmp/x/m.toml",
            &MISSION.replace("0.8", "0.9"),
        );
        let text = unified(&a, &b);
        assert!(
            text.starts_with("--- a/missions/m.toml\n+++ b/tmp/x/m.toml\n"),
            "{text}"
        );
        assert!(text.contains("@@ -5,7 +5,7 @@\n"), "{text}");
        assert!(
            text.contains("\n-distance = 0.8\n+distance = 0.9\n"),
            "{text}"
        );
        // three lines of context each side, no more
        assert!(
            text.contains(" [action.ops.wall-follower]\n-distance"),
            "{text}"
        );
        assert!(!text.contains("name = \"m\""), "{text}");
        assert_eq!(counts(&a.text, &b.text), (1, 1));
    }

    #[test]
    fn files_pair_by_role_and_the_same_digest_is_the_same_file_wherever_it_was() {
        let world = file(FileRole::World, "worlds/lab.toml", "walls = []\n");
        let moved = FileRead {
            path: "/elsewhere/lab.toml".into(),
            ..world.clone()
        };
        let a = provenance(vec![file(FileRole::Mission, "m.toml", MISSION), world]);
        let b = provenance(vec![file(FileRole::Mission, "m.toml", MISSION), moved]);
        assert!(compare(&a, &b).is_none());
        assert!(compare(&a, &a).is_none());
    }

    #[test]
    fn a_file_of_a_role_only_one_run_read_is_named_with_its_side() {
        let a = provenance(vec![file(FileRole::Mission, "m.toml", MISSION)]);
        let b = provenance(vec![
            file(FileRole::Mission, "m.toml", MISSION),
            file(FileRole::Node, "nodes/v1-only.toml", "[node]\n"),
        ]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "node only in b");
        assert_eq!(diff.lines, vec!["  node: only in b (nodes/v1-only.toml)"]);
        assert_eq!(diff.json["node"]["b"], "nodes/v1-only.toml");
    }

    #[test]
    fn a_changed_file_is_summed_up_by_its_lines_added_and_removed() {
        let a = provenance(vec![file(FileRole::Mission, "m.toml", MISSION)]);
        let b = provenance(vec![file(
            FileRole::Mission,
            "m.toml",
            &format!("{MISSION}z = 2\n"),
        )]);
        let diff = compare(&a, &b).expect("differs");
        assert_eq!(diff.summary, "mission +1 -0");
        assert_eq!(diff.lines[0], "  mission: m.toml -> m.toml");
        assert!(diff.lines.iter().any(|l| l == "+z = 2"), "{:?}", diff.lines);
        assert!(diff.json["mission"]["diff"]
            .as_str()
            .is_some_and(|d| d.contains("+z = 2")));
    }

    #[test]
    fn texts_without_a_final_newline_still_diff() {
        let a = file(FileRole::World, "w.toml", "a\nb");
        let b = file(FileRole::World, "w.toml", "a\nc");
        let text = unified(&a, &b);
        assert!(text.contains("-b"), "{text}");
        assert!(text.contains("+c"), "{text}");
        assert!(unified(&a, &a).is_empty());
    }
}

//! The workspace's layers, as cargo's dependency graph holds them: which marie crate each
//! crate may build on. Cargo already refuses a cycle between crates; this table pins the
//! direction, so that an arrow the design does not have (the monitor on the datamanagers,
//! the vocabulary on anything) is a failing test and a decision, not a quiet edit of a
//! Cargo.toml. Inside the framework's crates, the top-level modules import one another
//! without a cycle (the vocabulary's `run` below `events` below `report`), and so do the
//! files of the cluster's transport (`cluster/src/net`). And the
//! framework's crates name no robot: no pose, no collision — what a
//! robot says of a run is a section they carry untyped.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Each crate of the workspace (by its directory, the root package as `.`) and the marie
/// crates it may depend on — exactly these, no more and no fewer.
const LAYERS: &[(&str, &[&str])] = &[
    ("vocabulary", &[]),
    ("supervision", &[]),
    ("dm", &["marie-vocabulary"]),
    ("actors", &["marie-vocabulary", "marie-dm"]),
    (
        "cluster",
        &[
            "marie-vocabulary",
            "marie-dm",
            "marie-actors",
            "marie-supervision",
        ],
    ),
    (
        "missions",
        &[
            "marie-vocabulary",
            "marie-dm",
            "marie-actors",
            "marie-supervision",
            "marie-cluster",
            "marie-telemetry",
        ],
    ),
    ("missions/telemetry", &["marie-vocabulary"]),
    ("monitor", &["marie-vocabulary", "marie-telemetry"]),
    (
        "marie",
        &[
            "marie-vocabulary",
            "marie-dm",
            "marie-actors",
            "marie-supervision",
            "marie-cluster",
        ],
    ),
    (
        ".",
        &[
            "marie",
            "marie-missions",
            "marie-monitor",
            "marie-telemetry",
        ],
    ),
    ("embedding/plain-actor", &["marie"]),
    ("embedding/failover", &["marie"]),
];

/// The crates that are the framework itself: they know no robot.
const FRAMEWORK: &[&str] = &["vocabulary", "dm", "actors", "supervision"];

fn manifest(dir: &str) -> toml::Table {
    let path = root().join(dir).join("Cargo.toml");
    let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.parse()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The marie crates among a manifest's (normal, not dev) dependencies.
fn marie_dependencies(manifest: &toml::Table) -> BTreeSet<String> {
    manifest
        .get("dependencies")
        .and_then(toml::Value::as_table)
        .map(|deps| {
            deps.keys()
                .filter(|name| *name == "marie" || name.starts_with("marie-"))
                .cloned()
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn each_crate_builds_on_the_crates_its_layer_allows_and_no_other() {
    let members: BTreeSet<String> = manifest(".")["workspace"]["members"]
        .as_array()
        .expect("workspace members")
        .iter()
        .map(|m| m.as_str().expect("a member path").to_string())
        .chain([".".to_string()])
        .collect();
    let table: BTreeMap<&str, &[&str]> = LAYERS.iter().copied().collect();
    let listed: BTreeSet<String> = table.keys().map(|k| k.to_string()).collect();
    assert_eq!(
        members, listed,
        "every workspace member has its row in LAYERS"
    );
    let mut wrong = Vec::new();
    for (dir, allowed) in LAYERS {
        let found = marie_dependencies(&manifest(dir));
        let allowed: BTreeSet<String> = allowed.iter().map(|s| s.to_string()).collect();
        if found != allowed {
            wrong.push(format!(
                "{dir}: depends on {found:?}, its layer allows {allowed:?}"
            ));
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

#[test]
fn the_check_reads_the_dependencies_and_not_the_dev_dependencies() {
    let text = "[dependencies]\nmarie-dm = { path = \"../dm\" }\nserde = \"1\"\n\
                [dev-dependencies]\nmarie-cluster = { path = \"../cluster\" }\n";
    let found = marie_dependencies(&text.parse().unwrap());
    assert_eq!(found, BTreeSet::from(["marie-dm".to_string()]));
}

/// Every `.rs` file under `path`.
fn files(path: &Path) -> Vec<PathBuf> {
    if path.is_file() {
        return vec![path.to_path_buf()];
    }
    let mut out = Vec::new();
    for entry in fs::read_dir(path).expect("a source directory") {
        out.extend(files(&entry.expect("an entry").path()));
    }
    out.retain(|p| p.extension().is_some_and(|e| e == "rs"));
    out
}

/// The code of a file: no comments, no string literals, no `#[cfg(test)]` module (written
/// last in a file, by the workspace's convention).
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(at) => &text[..at],
        None => text,
    };
    let mut out = String::new();
    for line in text.lines() {
        let mut in_str = false;
        let mut prev = ' ';
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            if in_str {
                if c == '"' && prev != '\\' {
                    in_str = false;
                }
                prev = if prev == '\\' && c == '\\' { ' ' } else { c };
                continue;
            }
            match c {
                '/' if chars.peek() == Some(&'/') => break,
                '"' => {
                    in_str = true;
                    prev = ' ';
                }
                _ => out.push(c),
            }
        }
        out.push('\n');
    }
    out
}

/// The words of `code`, lowercased: identifiers cut at `_` and where a capital follows a
/// small letter (`final_pose`, `CartPose` → …, `pose`), so that `propose` or `purpose` is
/// not taken for a pose.
fn words(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut prev_lower = false;
    for c in code.chars() {
        let cut = !c.is_alphanumeric() || (c.is_uppercase() && prev_lower);
        if cut && !word.is_empty() {
            out.push(std::mem::take(&mut word).to_lowercase());
        }
        if c.is_alphanumeric() {
            word.push(c);
        }
        prev_lower = c.is_lowercase();
    }
    if !word.is_empty() {
        out.push(word.to_lowercase());
    }
    out
}

#[test]
fn words_are_cut_at_underscores_and_capitals_and_code_is_read_without_comments() {
    assert_eq!(
        words("final_pose CartPose propose"),
        ["final", "pose", "cart", "pose", "propose"]
    );
    let text = "use x::pose; // a collision\nlet s = \"collision\";\n#[cfg(test)]\nuse y;";
    let code = code(text);
    assert!(code.contains("x::pose") && !code.contains("collision"));
    assert!(!code.contains("use y"));
}

/// The modules of the folder `src` — a crate's `src` (its top-level modules) or a module's
/// folder such as `cluster/src/net` — and, for each, the sibling modules its code names by one
/// of `paths` (`crate::` for a crate's, `super::` and `crate::net::` for `net`'s; comments and
/// strings left out). `super::` is read only in the files directly in the folder: deeper, it
/// names a module of its own.
fn module_arrows(src: &Path, paths: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let mut graph = BTreeMap::new();
    for entry in fs::read_dir(src).expect("a source folder") {
        let path = entry.expect("an entry").path();
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .expect("a name")
            .to_string();
        if name == "lib" || name == "main" || name == "mod" {
            continue;
        }
        let mut uses = BTreeSet::new();
        for file in files(&path) {
            let code = code(&fs::read_to_string(&file).expect("readable"));
            for prefix in paths {
                if *prefix == "super::" && file.parent() != Some(src) {
                    continue;
                }
                for (at, _) in code.match_indices(prefix) {
                    let module: String = code[at + prefix.len()..]
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    let a_module = module
                        .chars()
                        .all(|c| c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit());
                    if !module.is_empty() && module != name && a_module {
                        uses.insert(module);
                    }
                }
            }
        }
        graph.insert(name, uses);
    }
    graph
}

/// The modules in an order where each comes after every module it names, or the modules
/// that cannot be ordered (those on a cycle, and what stands above them).
fn order(graph: &BTreeMap<String, BTreeSet<String>>) -> Result<Vec<String>, Vec<String>> {
    let mut placed: Vec<String> = Vec::new();
    let mut left: BTreeSet<&String> = graph.keys().collect();
    while !left.is_empty() {
        let ready: Vec<&String> = left
            .iter()
            .copied()
            .filter(|m| {
                graph[*m]
                    .iter()
                    .all(|u| placed.contains(u) || !graph.contains_key(u))
            })
            .collect();
        if ready.is_empty() {
            return Err(left.into_iter().cloned().collect());
        }
        for m in ready {
            left.remove(m);
            placed.push(m.clone());
        }
    }
    Ok(placed)
}

#[test]
fn the_vocabulary_is_layered_run_below_events_below_report() {
    let graph = module_arrows(&root().join("vocabulary/src"), &["crate::"]);
    let order = order(&graph).unwrap_or_else(|stuck| panic!("a cycle among {stuck:?}: {graph:#?}"));
    let rank = |m: &str| order.iter().position(|o| o == m).expect(m);
    assert!(rank("run") < rank("events"), "{order:?}");
    assert!(rank("events") < rank("report"), "{order:?}");
}

#[test]
fn the_top_level_modules_of_the_framework_crates_import_each_other_without_a_cycle() {
    for krate in ["vocabulary", "dm", "actors", "supervision"] {
        let graph = module_arrows(&root().join(krate).join("src"), &["crate::"]);
        if let Err(stuck) = order(&graph) {
            panic!("{krate}: a cycle among {stuck:?}: {graph:#?}");
        }
    }
}

/// A module's folder is checked as a crate's `src` is: its files are its modules, and they
/// name one another as `super::X` or by their whole path.
#[test]
fn the_modules_of_the_cluster_s_transport_import_each_other_without_a_cycle() {
    let graph = module_arrows(
        &root().join("cluster/src/net"),
        &["super::", "crate::net::"],
    );
    assert!(
        graph.contains_key("transport") && graph["transport"].contains("sessions"),
        "the scan reads net's arrows: {graph:#?}"
    );
    if let Err(stuck) = order(&graph) {
        panic!("cluster/src/net: a cycle among {stuck:?}: {graph:#?}");
    }
}

#[test]
fn the_order_sees_a_cycle() {
    let graph: BTreeMap<String, BTreeSet<String>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec![]),
    ]
    .into_iter()
    .map(|(m, us)| (m.to_string(), us.into_iter().map(str::to_string).collect()))
    .collect();
    assert_eq!(
        order(&graph).unwrap_err(),
        ["a", "b", "c"].map(str::to_string)
    );
}

#[test]
fn the_framework_crates_name_no_pose_and_no_collision() {
    let mut found = Vec::new();
    for krate in FRAMEWORK {
        for file in files(&root().join(krate).join("src")) {
            let words = words(&code(&fs::read_to_string(&file).expect("readable")));
            for word in ["pose", "collision"] {
                if words.iter().any(|w| w == word || *w == format!("{word}s")) {
                    found.push(format!("{}: {word}", file.display()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "a robot's words in the framework: {found:#?}"
    );
}

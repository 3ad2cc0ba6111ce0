//! The ground crate's layering, checked from its source: the top-level modules of
//! `actors/src` import one another without a cycle (the vocabulary of a run, `run`, below
//! `events`, below `report`, below `dispatcher`), and its code names no robot — no pose, no
//! collision: what a robot says of a run is a section the crate carries untyped.
//!
//! How: every `crate::MODULE` in a module's code (comments and string literals left out)
//! is an arrow from that module to MODULE; the arrows must admit an order.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file under `path` (or `path` itself).
fn files(path: &Path) -> Vec<PathBuf> {
    if path.is_file() {
        return vec![path.to_path_buf()];
    }
    let mut out = Vec::new();
    for entry in fs::read_dir(path).expect("a source directory") {
        out.extend(files(&entry.expect("an entry").path()));
    }
    out
}

/// The code of a file: no comments, no string or char literals, no `#[cfg(test)]` module
/// (written last in a file, by this crate's convention).
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

/// The top-level modules of the crate and, for each, the modules its code names.
fn arrows() -> BTreeMap<String, BTreeSet<String>> {
    let mut graph = BTreeMap::new();
    for entry in fs::read_dir(src()).expect("actors/src") {
        let path = entry.expect("an entry").path();
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .expect("a name")
            .to_string();
        if name == "lib" {
            continue;
        }
        let mut uses = BTreeSet::new();
        for file in files(&path) {
            let code = code(&fs::read_to_string(&file).expect("readable"));
            for (at, _) in code.match_indices("crate::") {
                let rest = &code[at + "crate::".len()..];
                let module: String = rest
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
        graph.insert(name, uses);
    }
    graph
}

/// The modules in an order where each comes after every module it names, or the modules
/// that cannot be ordered (those on a cycle, and what stands above them).
fn layers(graph: &BTreeMap<String, BTreeSet<String>>) -> Result<Vec<String>, Vec<String>> {
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
fn the_top_level_modules_of_the_ground_crate_import_each_other_without_a_cycle() {
    let graph = arrows();
    let order = layers(&graph).unwrap_or_else(|stuck| {
        let cycle: Vec<String> = stuck
            .iter()
            .map(|m| format!("{m} -> {:?}", graph[m]))
            .collect();
        panic!("a cycle among: {cycle:#?}")
    });
    let rank = |m: &str| order.iter().position(|o| o == m).expect(m);
    // the run's vocabulary lies below the events, the report and the dispatcher
    assert!(rank("run") < rank("events"), "{order:?}");
    assert!(rank("events") < rank("report"), "{order:?}");
    assert!(rank("report") < rank("dispatcher"), "{order:?}");
    for below in ["run", "events", "report"] {
        assert!(
            !graph[below].contains("dispatcher"),
            "{below} names the dispatcher: {:?}",
            graph[below]
        );
    }
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
fn words_are_cut_at_underscores_and_capitals() {
    assert_eq!(
        words("final_pose CartPose propose"),
        ["final", "pose", "cart", "pose", "propose"]
    );
}

#[test]
fn the_ground_crate_names_no_pose_and_no_collision() {
    let mut found = Vec::new();
    for file in files(&src()) {
        let words = words(&code(&fs::read_to_string(&file).expect("readable")));
        for word in ["pose", "collision"] {
            if words.iter().any(|w| w == word || *w == format!("{word}s")) {
                found.push(format!("{}: {word}", file.display()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "a robot's words in marie-actors: {found:#?}"
    );
}

#[test]
fn the_check_sees_a_cycle_and_reads_code_only() {
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
        layers(&graph).unwrap_err(),
        ["a", "b", "c"].map(str::to_string)
    );
    let text = "use crate::x; // crate::y\nlet s = \"crate::z\";\n#[cfg(test)]\nuse crate::w;";
    let code = code(text);
    assert!(code.contains("crate::x") && !code.contains("crate::y"));
    assert!(!code.contains("crate::z") && !code.contains("crate::w"));
}

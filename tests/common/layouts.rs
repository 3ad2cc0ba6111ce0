//! Cluster files the end-to-end tests write: layouts built from the thesis' node configs.

use std::path::{Path, PathBuf};

/// The thesis' node config `name` (cart, features, operations, spare), written into `dir`
/// as `NAME.toml`, with `edit` applied, and — for a node that keeps replicas in the thesis
/// layout — the thesis cluster file's `[[datamanager]]` tables appended: a layout without
/// the thesis cluster file (or without some of its nodes: a replica on a node the layout
/// lacks is one that never answers) keeps them so. Gives its path.
pub(crate) fn thesis_node(dir: &Path, name: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let thesis = repo.join("missions/clusters");
    let mut text =
        edit(std::fs::read_to_string(thesis.join(format!("thesis/{name}.toml"))).unwrap());
    if name != "cart" {
        let cluster = std::fs::read_to_string(thesis.join("thesis.toml")).unwrap();
        let at = cluster
            .find("[[datamanager]]")
            .expect("thesis.toml declares its datamanagers");
        text.push('\n');
        text.push_str(&cluster[at..]);
    }
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Write the layout into `dir`: the thesis' with a wall follower on each node of
/// `followers` (none on the operations node, which may only start one on request when
/// `standby`), those nodes not restarted once lost; gives the cluster file.
pub(crate) fn failover_layout(dir: &Path, followers: &[&str], standby: bool) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let thesis = repo.join("missions/clusters/thesis");
    thesis_node(dir, "operations", |text| {
        text.replace(
            "[[operation]]\nname = \"wall-follower\"\n",
            if standby {
                "[[operation]]\nname = \"wall-follower\"\ninstances = 0\n"
            } else {
                ""
            },
        )
    });
    let features = thesis_node(dir, "features", |text| text);
    for wf in followers {
        std::fs::write(
            dir.join(format!("{wf}.toml")),
            format!(
                "[node]\nname = \"{wf}\"\ndispatcher = false\n[[operation]]\nname = \"wall-follower\"\n"
            ),
        )
        .unwrap();
    }
    let cluster = dir.join("cluster.toml");
    let mut text = format!(
        "[cluster]\ncookie = \"failover\"\nworld = \"{}\"\nseed = 1\n\
         [[node]]\nconfig = \"{}\"\n[[node]]\nconfig = \"{}\"\n\
         [[node]]\nconfig = \"operations.toml\"\n",
        repo.join("missions/worlds/lab.toml").display(),
        thesis.join("cart.toml").display(),
        features.display(),
    );
    // a wall follower's node lost stays lost (`marie up` would start it again, and its
    // wall follower with it): these layouts are about what the survivors do
    for wf in followers {
        text += &format!("[[node]]\nconfig = \"{wf}.toml\"\nrestart = \"temporary\"\n");
    }
    std::fs::write(&cluster, text).unwrap();
    cluster
}

/// The thesis layout (`missions/clusters/thesis.toml`) written into `dir` with `keys` added to
/// its `[cluster]` table (e.g. `restart = "temporary"`); its path.
pub(crate) fn thesis_with(dir: &Path, keys: &str) -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/clusters");
    let layout = std::fs::read_to_string(here.join("thesis.toml"))
        .unwrap()
        .replace(
            "config = \"thesis/",
            &format!("config = \"{}/thesis/", here.display()),
        )
        .replace(
            "world = \"../worlds/lab.toml\"",
            &format!("world = \"{}/../worlds/lab.toml\"\n{keys}", here.display()),
        );
    let file = dir.join("thesis.toml");
    std::fs::write(&file, layout).unwrap();
    file
}

/// The thesis layout written into `dir` with node `node` kept down once stopped
/// (`restart = "temporary"` on its `[[node]]`; the others restarted as ever); its path.
pub(crate) fn thesis_with_temporary(dir: &Path, node: &str) -> PathBuf {
    let cluster = thesis_with(dir, "");
    let layout = std::fs::read_to_string(&cluster).unwrap();
    let line = layout
        .lines()
        .find(|l| l.ends_with(&format!("thesis/{node}.toml\"")))
        .unwrap_or_else(|| panic!("no node {node} in the thesis layout"))
        .to_string();
    let layout = layout.replace(&line, &format!("{line}\nrestart = \"temporary\""));
    std::fs::write(&cluster, layout).unwrap();
    cluster
}

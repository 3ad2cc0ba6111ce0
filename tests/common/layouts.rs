//! Cluster files the end-to-end tests write: layouts built from the thesis' node configs.

use std::path::{Path, PathBuf};

/// Write the layout into `dir`: the thesis' with a wall follower on each node of
/// `followers` (none on the operations node, which may only start one on request when
/// `standby`); gives the cluster file.
pub(crate) fn failover_layout(dir: &Path, followers: &[&str], standby: bool) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let thesis = repo.join("missions/clusters/thesis");
    let operations = std::fs::read_to_string(thesis.join("operations.toml"))
        .unwrap()
        .replace(
            "[[operation]]\nname = \"wall-follower\"\n",
            if standby {
                "[[operation]]\nname = \"wall-follower\"\ninstances = 0\n"
            } else {
                ""
            },
        );
    std::fs::write(dir.join("operations.toml"), operations).unwrap();
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
        thesis.join("features.toml").display(),
    );
    for wf in followers {
        text += &format!("[[node]]\nconfig = \"{wf}.toml\"\n");
    }
    std::fs::write(&cluster, text).unwrap();
    cluster
}

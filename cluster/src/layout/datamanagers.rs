//! A cluster file's `[[datamanager]]` tables: each replicated datamanager declared once, for
//! the whole cluster — its name, the nodes that keep its replicas (the preferred leader
//! first), its durability, catch-up and retention — instead of in the config of every node
//! that keeps a replica. `marie up` gives each node the cluster file (`marie node --cluster
//! FILE`), and a node hosts a replica of each datamanager whose list names it.
//!
//! ```toml
//! [[datamanager]]
//! name = "feature"
//! replicas = ["features", "operations", "spare"]
//! ```

use crate::node::config::load::datamanager;
use crate::node::config::DatamanagerConfig;
use marie_vocabulary::diagnostic::toml::{quote, Reader, Span, Val};
use marie_vocabulary::diagnostic::{read_source, Diagnostics};
use std::path::Path;

/// One `[[datamanager]]` of a cluster file, and where it is (for what is found wrong with
/// it once the nodes are known).
#[derive(Clone, Debug)]
pub(crate) struct Declared {
    pub(crate) config: DatamanagerConfig,
    pub(crate) at: Span,
}

/// The `[[datamanager]]` tables `v` holds, each checked as a node config's are (a node that
/// keeps a replica has a data directory: `marie up` gives every node one); each must name
/// its replicas.
pub(crate) fn read(r: &mut Reader<'_>, v: &Val<'_>) -> Vec<Declared> {
    let mut declared: Vec<Declared> = Vec::new();
    for t in r.table_array(v, "datamanager").into_iter().flatten() {
        let seen: Vec<DatamanagerConfig> = declared.iter().map(|d| d.config.clone()).collect();
        let Some(config) = datamanager(r, &t, &seen, true) else {
            continue;
        };
        if config.replicas.is_empty() {
            r.err(
                &t.span,
                format!(
                    "datamanager {} of a cluster file needs `replicas = [...]` (the nodes that \
                     keep it); one kept by a single node is declared in that node's config",
                    quote(&config.name)
                ),
            );
            continue;
        }
        declared.push(Declared {
            config,
            at: t.span.clone(),
        });
    }
    declared
}

/// The datamanagers a cluster file declares whose replicas include node `node`: what
/// `marie node --cluster FILE` hosts beside its own config's. Only `[[datamanager]]` is
/// read (a node's host need not have the other nodes' configs); its problems are
/// diagnostics at their `file:line:col`.
pub fn declared_for(path: &Path, node: &str) -> Result<Vec<DatamanagerConfig>, Diagnostics> {
    let src = read_source(path, "cluster")?;
    let mut r = Reader::new(&src, path.display().to_string());
    let Some(doc) = r.parse() else {
        return r.finish(None, "the cluster file is not valid");
    };
    let top = r.top(&doc, "the cluster file");
    let declared = match top.get("datamanager") {
        Some(v) => read(&mut r, v),
        None => Vec::new(),
    };
    let mine = declared
        .into_iter()
        .map(|d| d.config)
        .filter(|c| c.replicas.iter().any(|n| n == node))
        .collect();
    Diagnostics(r.into_diagnostics()).into_result(mine)
}

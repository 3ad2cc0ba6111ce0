//! A cluster file: which nodes a cluster runs, as one file `marie up` starts.
//!
//! ```toml
//! [cluster]
//! cookie = "marie-thesis"      # the shared secret every node proves
//! speed = 1                    # the cluster's factor of real time (the same on every node)
//! world = "../worlds/lab.toml" # the simulated robot's world (a mission's or --world wins)
//! seed = 1
//!
//! [[node]]
//! config = "thesis/cart.toml"  # a node config, relative to this file
//! [[node]]
//! config = "thesis/features.toml"
//! listen = "127.0.0.1:7102"    # optional: else a free port on 127.0.0.1
//! restart = "transient"        # optional: how `marie up` restarts it (see `restart`)
//!
//! [[datamanager]]              # a replicated datamanager, declared once (`datamanagers`)
//! name = "feature"
//! replicas = ["features", "operations", "spare"]
//! ```
//!
//! Every node config is loaded and checked with the file, and node names must differ (two
//! processes with one node name cannot connect). Problems are diagnostics at their
//! `file:line:col`, a node config's own ones after the line that names it.
//!
//! ```
//! # use marie_cluster::layout::ClusterLayout;
//! let dir = tempfile::tempdir().unwrap();
//! std::fs::write(dir.path().join("a.toml"), "[node]\nname = \"a\"\n").unwrap();
//! std::fs::write(dir.path().join("c.toml"), "[cluster]\ncookie = \"c\"\n[[node]]\nconfig = \"a.toml\"\n").unwrap();
//! let layout = ClusterLayout::load(&dir.path().join("c.toml"), &[]).unwrap();
//! assert_eq!(layout.nodes[0].config.name, "a");
//! ```

mod datamanagers;
mod restart;

pub use datamanagers::declared_for;
pub use restart::{Exit, NodeRestart, RestartPolicy, RestartTracker, Verdict};

use crate::net::check_cookie;
use crate::node::config::socket_addr;
use crate::node::NodeConfig;
use marie_actors::eo::OperationFactory;
use marie_vocabulary::diagnostic::toml::{Reader, Rule, Tbl};
use marie_vocabulary::diagnostic::{read_source, Diagnostic, Diagnostics};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// Slowest and fastest speed factor of a cluster (it runs on the wall clock: a step period
/// must stay long against a message's trip between processes).
pub const SPEED_RANGE: (f64, f64) = (0.01, 20.0);

/// What a cluster's speed factor must be, for messages.
pub fn speed_expected() -> String {
    let (lo, hi) = SPEED_RANGE;
    format!(
        "expected a factor of real time from {lo} to {hi} (a cluster runs on the wall clock, \
         the same factor on every node)"
    )
}

/// `speed` if it is a cluster's speed factor (within [`SPEED_RANGE`]), else why not.
pub fn cluster_speed(speed: f64) -> Result<f64, SpeedError> {
    let (lo, hi) = SPEED_RANGE;
    if (lo..=hi).contains(&speed) {
        Ok(speed)
    } else if speed < lo {
        Err(SpeedError::TooSlow { speed })
    } else if speed > hi {
        Err(SpeedError::TooFast { speed })
    } else {
        Err(SpeedError::NotANumber)
    }
}

/// Why a number cannot be a cluster's speed factor ([`cluster_speed`]); each displays what
/// was expected ([`speed_expected`]) and what was given.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum SpeedError {
    /// Below the slowest factor, [`SPEED_RANGE`]`.0` (zero and negatives included).
    #[error("{}, got {speed}", speed_expected())]
    TooSlow {
        /// The factor given.
        speed: f64,
    },
    /// Above the fastest factor, [`SPEED_RANGE`]`.1` (infinity, `max`, included): a step
    /// period would be short against a message's trip between processes.
    #[error("{}, got {speed}", speed_expected())]
    TooFast {
        /// The factor given.
        speed: f64,
    },
    /// Not a number (NaN).
    #[error("{}, got NaN", speed_expected())]
    NotANumber,
}

/// A cluster file, checked.
#[derive(Clone, Debug)]
pub struct ClusterLayout {
    /// The file it was read from.
    pub path: PathBuf,
    /// The cookie every node proves.
    pub cookie: String,
    /// The cluster's factor of real time.
    pub speed: f64,
    /// The robot's world, resolved against the file's directory.
    pub world: Option<PathBuf>,
    /// The simulation's seed.
    pub seed: Option<u64>,
    /// The nodes, in file order.
    pub nodes: Vec<LayoutNode>,
    /// How `marie up` restarts a node whose config gives no restart keys of its own.
    pub restart: NodeRestart,
    /// The replicated datamanagers the file declares (`[[datamanager]]`), each once for the
    /// whole cluster; also in the config of every node that keeps a replica.
    pub datamanagers: Vec<crate::node::config::DatamanagerConfig>,
}

impl ClusterLayout {
    /// The node whose config says `dispatcher = "active"`: where `marie up --run`
    /// dispatches the run (its standbys take it over should it be lost); `None`: the run is
    /// dispatched by `marie up` itself.
    pub fn dispatch_node(&self) -> Option<&str> {
        self.nodes
            .iter()
            .find(|n| n.config.desk == Some(crate::node::DeskRole::Active))
            .map(|n| n.config.name.as_str())
    }

    /// The nodes whose config says `dispatcher = "standby"`.
    pub fn standby_nodes(&self) -> Vec<&str> {
        self.nodes
            .iter()
            .filter(|n| n.config.desk == Some(crate::node::DeskRole::Standby))
            .map(|n| n.config.name.as_str())
            .collect()
    }
}

/// One `[[node]]` of a cluster file.
#[derive(Clone, Debug)]
pub struct LayoutNode {
    /// The node config file (resolved).
    pub path: PathBuf,
    /// The node config, checked.
    pub config: NodeConfig,
    /// Where it listens; `None`: a free port on 127.0.0.1.
    pub listen: Option<SocketAddr>,
    /// How `marie up` restarts it when its process ends.
    pub restart: NodeRestart,
}

impl ClusterLayout {
    /// Read and check a cluster file and every node config it names, against `catalog`.
    pub fn load(path: &Path, catalog: &[OperationFactory]) -> Result<ClusterLayout, Diagnostics> {
        let src = read_source(path, "cluster")?;
        let dir = path.parent().unwrap_or(Path::new(""));
        let mut r = Reader::new(&src, path.display().to_string());
        let Some(doc) = r.parse() else {
            return r.finish(None, "the cluster file is not valid");
        };
        let top = r.top(&doc, "the cluster file");
        r.unknown_keys(&top, &["cluster", "node", "datamanager"]);
        let mut layout = ClusterLayout {
            path: path.to_path_buf(),
            cookie: String::new(),
            speed: 1.0,
            world: None,
            seed: None,
            nodes: Vec::new(),
            restart: NodeRestart::default(),
            datamanagers: Vec::new(),
        };
        match top.get("cluster").map(|v| r.table(v, "[cluster]")) {
            None => r.err(
                &(0..0),
                "missing table `[cluster]` (expected `cookie = \"...\"`)",
            ),
            Some(Some(t)) => layout.read_cluster_table(&mut r, &t, dir),
            Some(None) => {}
        }
        // a node config's own diagnostics follow the line that names it, after this file's
        let mut nested: Vec<Diagnostic> = Vec::new();
        match top.get("node") {
            None => r.err(
                &(0..0),
                "no `[[node]]`: a cluster file lists the nodes it runs",
            ),
            Some(v) => {
                for t in r.table_array(v, "node").into_iter().flatten() {
                    layout.read_node(&mut r, &t, dir, catalog, &mut nested);
                }
            }
        }
        if let Some(v) = top.get("datamanager") {
            let declared = datamanagers::read(&mut r, v);
            layout.place(&mut r, declared);
        }
        let mut all = r.into_diagnostics();
        all.extend(nested);
        Diagnostics(all).into_result(layout)
    }

    /// Give each declared datamanager to the nodes its replicas name: every one a node of
    /// this file, none of which declares it in its own config as well.
    fn place(&mut self, r: &mut Reader<'_>, declared: Vec<datamanagers::Declared>) {
        for d in declared {
            let name = &d.config.name;
            if let Some(ghost) = d
                .config
                .replicas
                .iter()
                .find(|n| !self.nodes.iter().any(|node| &node.config.name == *n))
            {
                r.err(
                    &d.at,
                    format!(
                        "datamanager `{name}` keeps a replica on `{ghost}`, which is no node of \
                         this cluster file"
                    ),
                );
                continue;
            }
            if let Some(ghost) = d
                .config
                .spares
                .iter()
                .find(|n| !self.nodes.iter().any(|node| &node.config.name == *n))
            {
                r.err(
                    &d.at,
                    format!(
                        "datamanager `{name}` names spare `{ghost}`, which is no node of this \
                         cluster file"
                    ),
                );
                continue;
            }
            let hosts = |node: &&mut LayoutNode| d.config.replicas.contains(&node.config.name);
            if let Some(twice) = self
                .nodes
                .iter_mut()
                .filter(hosts)
                .find(|n| n.config.datamanagers.iter().any(|own| &own.name == name))
            {
                r.err(
                    &d.at,
                    format!(
                        "datamanager `{name}` is declared here and in node `{}`'s config ({}): \
                         declare it once",
                        twice.config.name,
                        twice.path.display()
                    ),
                );
                continue;
            }
            for node in self.nodes.iter_mut().filter(hosts) {
                node.config.datamanagers.push(d.config.clone());
            }
            self.datamanagers.push(d.config);
        }
    }

    /// `[cluster]`: cookie, speed, world, seed, the nodes' restart settings.
    fn read_cluster_table(&mut self, r: &mut Reader<'_>, t: &Tbl<'_, '_>, dir: &Path) {
        let keys = ["cookie", "speed", "world", "seed"];
        r.unknown_keys(t, &[&keys[..], &restart::KEYS[..]].concat());
        self.restart = NodeRestart::default().read(r, t);
        if let Some(cookie) = r.required_string(t, "cookie") {
            if let Err(e) = check_cookie(&cookie) {
                let span = t.get("cookie").map(|v| v.span()).unwrap_or(0..0);
                r.err(&span, e.to_string());
            }
            self.cookie = cookie;
        }
        let (lo, hi) = SPEED_RANGE;
        self.speed = r
            .num(t, "speed", Some(1.0), Rule::Within(lo, hi))
            .unwrap_or(1.0);
        self.world = r.string(t, "world").map(|w| dir.join(w));
        self.seed = t
            .get("seed")
            .and_then(|_| r.integer(t, "seed", None, 0..=i64::MAX))
            .map(|s| s as u64);
    }

    /// One `[[node]]`: its config file loaded and checked, its name not yet taken.
    fn read_node(
        &mut self,
        r: &mut Reader<'_>,
        t: &Tbl<'_, '_>,
        dir: &Path,
        catalog: &[OperationFactory],
        nested: &mut Vec<Diagnostic>,
    ) {
        r.unknown_keys(t, &[&["config", "listen"][..], &restart::KEYS[..]].concat());
        let restart = self.restart.read(r, t);
        let listen = t.get("listen").and_then(|v| {
            let s = r.string_value(v, "listen")?;
            socket_addr(r, &s, &v.span(), "listen")
        });
        let Some(config_at) = t.get("config").map(|v| v.span()) else {
            r.err(&t.span, "missing `config` in [[node]] (a node config file)");
            return;
        };
        let Some(file) = r.required_string(t, "config") else {
            return;
        };
        let path = dir.join(file);
        let config = match NodeConfig::load(&path, catalog) {
            Ok(config) => config,
            Err(diags) => {
                nested.push(Diagnostic::at(
                    r.file(),
                    r.pos(&config_at),
                    "the node config named here does not load:",
                ));
                nested.extend(diags);
                return;
            }
        };
        let active = |c: &NodeConfig| c.desk == Some(crate::node::DeskRole::Active);
        if let Some(other) = self
            .nodes
            .iter()
            .find(|n| active(&n.config) && active(&config))
        {
            r.err(
                &config_at,
                format!(
                    "node `{}` and node `{}` both say `dispatcher = \"active\"`: a cluster \
                     dispatches its runs on one node (make the others `\"standby\"`)",
                    other.config.name, config.name
                ),
            );
            return;
        }
        if let Some(twin) = self.nodes.iter().find(|n| n.config.name == config.name) {
            r.err(
                &config_at,
                format!(
                    "node `{}` is already named by {}: node names must differ within a cluster",
                    config.name,
                    twin.path.display()
                ),
            );
            return;
        }
        self.nodes.push(LayoutNode {
            path,
            config,
            listen,
            restart,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_speed_out_of_range_is_matched_by_its_side_and_keeps_its_text() {
        assert_eq!(cluster_speed(4.0), Ok(4.0));
        assert_eq!(cluster_speed(0.0), Err(SpeedError::TooSlow { speed: 0.0 }));
        let err = cluster_speed(50.0).unwrap_err();
        assert_eq!(err, SpeedError::TooFast { speed: 50.0 });
        assert_eq!(err.to_string(), format!("{}, got 50", speed_expected()));
        assert!(matches!(
            cluster_speed(f64::INFINITY),
            Err(SpeedError::TooFast { .. })
        ));
        let err = cluster_speed(f64::NAN).unwrap_err();
        assert_eq!(err, SpeedError::NotANumber);
        assert_eq!(err.to_string(), format!("{}, got NaN", speed_expected()));
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// Node configs `a.toml` to `d.toml` in `dir`, each naming its node only.
    fn four_nodes(dir: &Path) {
        for n in ["a", "b", "c", "d"] {
            write(
                dir,
                &format!("{n}.toml"),
                &format!("[node]\nname = \"{n}\"\n"),
            );
        }
    }

    #[test]
    fn a_cluster_file_gives_its_nodes_cookie_speed_and_world() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "a.toml", "[node]\nname = \"a\"\n");
        write(dir.path(), "b.toml", "[node]\nname = \"b\"\n");
        let c = write(
            dir.path(),
            "c.toml",
            "[cluster]\ncookie = \"k\"\nspeed = 4\nworld = \"w.toml\"\nseed = 7\n\
             [[node]]\nconfig = \"a.toml\"\n[[node]]\nconfig = \"b.toml\"\nlisten = \"127.0.0.1:7001\"\n",
        );
        let l = ClusterLayout::load(&c, &[]).unwrap();
        assert_eq!((l.cookie.as_str(), l.speed, l.seed), ("k", 4.0, Some(7)));
        assert_eq!(l.world, Some(dir.path().join("w.toml")));
        let names: Vec<_> = l.nodes.iter().map(|n| n.config.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(l.nodes[1].listen, Some("127.0.0.1:7001".parse().unwrap()));
    }

    #[test]
    fn a_node_restarts_as_the_cluster_says_unless_its_own_keys_say_otherwise() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "a.toml", "[node]\nname = \"a\"\n");
        write(dir.path(), "b.toml", "[node]\nname = \"b\"\n");
        let c = write(
            dir.path(),
            "c.toml",
            "[cluster]\ncookie = \"k\"\nmax_restarts = 2\nbackoff = 0.5\n\
             [[node]]\nconfig = \"a.toml\"\n\
             [[node]]\nconfig = \"b.toml\"\nrestart = \"temporary\"\nrestart_period = 5\n",
        );
        let l = ClusterLayout::load(&c, &[]).unwrap();
        let a = l.nodes[0].restart;
        assert_eq!(a.policy, RestartPolicy::Permanent);
        assert_eq!((a.max_restarts, a.backoff), (2, Duration::from_millis(500)));
        let b = l.nodes[1].restart;
        assert_eq!(b.policy, RestartPolicy::Temporary);
        assert_eq!((b.max_restarts, b.period), (2, Duration::from_secs(5)));
        // a file without restart keys: every node permanent, OTP-like defaults
        let c = write(
            dir.path(),
            "plain.toml",
            "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"a.toml\"\n",
        );
        let l = ClusterLayout::load(&c, &[]).unwrap();
        assert_eq!(l.nodes[0].restart, NodeRestart::default());
    }

    #[test]
    fn bad_restart_settings_are_reported_at_their_line() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "a.toml", "[node]\nname = \"a\"\n");
        let c = write(
            dir.path(),
            "c.toml",
            "[cluster]\ncookie = \"k\"\nrestart = \"always\"\nmax_restarts = -1\n\
             [[node]]\nconfig = \"a.toml\"\nbackoff = 2\nmax_backoff = 1\nrestart_period = 0\n",
        );
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        let f = c.display().to_string();
        for want in [
            format!("{f}:3:11: `restart` must be \"permanent\", \"transient\" or \"temporary\", found \"always\""),
            format!("{f}:4:16: `max_restarts` must be an integer in [0, 1000], found -1"),
            format!("{f}:9:18: `restart_period` must be in (0, 86400], found 0"),
            format!("{f}:8:15: `max_backoff` (1 s) must be at least `backoff` (2 s)"),
        ] {
            assert!(text.contains(&want), "{want}\nnot in:\n{text}");
        }
    }

    #[test]
    fn a_replicated_datamanager_is_declared_once_and_given_to_each_node_it_names() {
        let dir = tempfile::tempdir().unwrap();
        four_nodes(dir.path());
        let c = write(
            dir.path(),
            "cluster.toml",
            "[cluster]\ncookie = \"k\"\n\
             [[node]]\nconfig = \"a.toml\"\n[[node]]\nconfig = \"b.toml\"\n\
             [[node]]\nconfig = \"c.toml\"\n[[node]]\nconfig = \"d.toml\"\n\
             [[datamanager]]\nname = \"feature\"\nreplicas = [\"b\", \"c\", \"d\"]\ncatch_up = 100\n",
        );
        let l = ClusterLayout::load(&c, &[]).unwrap();
        assert_eq!(l.datamanagers.len(), 1);
        let hosts: Vec<(&str, usize)> = l
            .nodes
            .iter()
            .map(|n| (n.config.name.as_str(), n.config.datamanagers.len()))
            .collect();
        assert_eq!(hosts, [("a", 0), ("b", 1), ("c", 1), ("d", 1)]);
        let on_c = &l.nodes[2].config.datamanagers[0];
        assert_eq!((on_c.replicas.len(), on_c.catch_up), (3, Some(100)));
        // what `marie node --cluster FILE` hosts: the tables that name it, only
        assert_eq!(declared_for(&c, "c").unwrap().len(), 1);
        assert!(declared_for(&c, "a").unwrap().is_empty());
    }

    #[test]
    fn a_datamanager_on_no_node_of_the_file_declared_twice_or_without_replicas_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "a.toml", "[node]\nname = \"a\"\n");
        write(
            dir.path(),
            "b.toml",
            "[node]\nname = \"b\"\n[[datamanager]]\nname = \"world\"\n",
        );
        let c = write(
            dir.path(),
            "c.toml",
            "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"a.toml\"\n[[node]]\nconfig = \"b.toml\"\n\
             [[datamanager]]\nname = \"feature\"\nreplicas = [\"a\", \"b\", \"ghost\"]\n\
             [[datamanager]]\nname = \"world\"\nreplicas = [\"a\", \"b\"]\n\
             [[datamanager]]\nname = \"parameter\"\n",
        );
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        let f = c.display().to_string();
        for want in [
            format!("{f}:7:1: datamanager `feature` keeps a replica on `ghost`, which is no node of this cluster file"),
            format!("{f}:10:1: datamanager `world` is declared here and in node `b`'s config"),
            format!("{f}:13:1: datamanager `parameter` of a cluster file needs `replicas = [...]`"),
        ] {
            assert!(text.contains(&want), "{want}\nnot in:\n{text}");
        }
    }

    #[test]
    fn replacement_keys_are_read_and_each_bad_one_is_reported_at_its_line() {
        let dir = tempfile::tempdir().unwrap();
        four_nodes(dir.path());
        let nodes = "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"a.toml\"\n[[node]]\nconfig = \"b.toml\"\n\
                     [[node]]\nconfig = \"c.toml\"\n[[node]]\nconfig = \"d.toml\"\n";
        let good = write(
            dir.path(),
            "good.toml",
            &format!("{nodes}[[datamanager]]\nname = \"feature\"\nreplicas = [\"a\", \"b\", \"c\"]\nreplace_after = 2.5\nspares = [\"d\"]\n"),
        );
        let on_a = declared_for(&good, "a").unwrap();
        assert_eq!(on_a[0].replace_after, Some(Duration::from_millis(2500)));
        assert_eq!(on_a[0].spares, ["d"]);
        let bad = write(
            dir.path(),
            "bad.toml",
            &format!(
                "{nodes}[[datamanager]]\nname = \"feature\"\nreplicas = [\"a\", \"b\", \"c\"]\nreplace_after = 0\n\
                 [[datamanager]]\nname = \"world\"\nreplicas = [\"a\", \"b\", \"c\"]\nspares = [\"d\"]\n\
                 [[datamanager]]\nname = \"run\"\nreplicas = [\"a\", \"b\", \"c\"]\nreplace_after = 9\nspares = [\"ghost\"]\n"
            ),
        );
        let text = ClusterLayout::load(&bad, &[]).unwrap_err().to_string();
        let f = bad.display().to_string();
        for want in [
            format!("{f}:14:17: `replace_after` must be"),
            format!("{f}:18:11: `spares` are the nodes that may take a gone replica's place: give `replace_after = SECONDS` too"),
            format!("{f}:19:1: datamanager `run` names spare `ghost`, which is no node of this cluster file"),
        ] {
            assert!(text.contains(&want), "{want}\nnot in:\n{text}");
        }
    }

    #[test]
    fn each_bad_cluster_setting_is_reported_at_its_line() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "a.toml", "[node]\nname = \"a\"\n");
        write(dir.path(), "bad.toml", "[node]\nname = 3\n");
        let c = write(
            dir.path(),
            "c.toml",
            "[cluster]\ncookie = \"k\"\nspeed = 50\n\
             [[node]]\nconfig = \"a.toml\"\nlisten = \"nowhere\"\n\
             [[node]]\nconfig = \"a.toml\"\n\
             [[node]]\nconfig = \"bad.toml\"\n",
        );
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        let f = c.display().to_string();
        assert!(
            text.contains(&format!("{f}:3:9: `speed` must be")),
            "{text}"
        );
        assert!(
            text.contains(&format!("{f}:6:10: `listen`: `nowhere`")),
            "{text}"
        );
        assert!(
            text.contains(&format!("{f}:8:10: node `a` is already named")),
            "{text}"
        );
        assert!(
            text.contains(&format!(
                "{f}:10:10: the node config named here does not load:"
            )),
            "{text}"
        );
        assert!(text.contains("bad.toml:2:8"), "{text}");
    }

    #[test]
    fn a_cluster_dispatches_on_its_one_active_node_and_says_where_the_standbys_are() {
        let dir = tempfile::tempdir().unwrap();
        write(
            dir.path(),
            "a.toml",
            "[node]\nname = \"a\"\ndispatcher = \"active\"\n",
        );
        write(
            dir.path(),
            "b.toml",
            "[node]\nname = \"b\"\ndispatcher = \"standby\"\n",
        );
        write(
            dir.path(),
            "c.toml",
            "[node]\nname = \"c\"\ndispatcher = false\n",
        );
        write(
            dir.path(),
            "d.toml",
            "[node]\nname = \"d\"\ndispatcher = \"active\"\n",
        );
        write(
            dir.path(),
            "e.toml",
            "[node]\nname = \"e\"\ndispatcher = \"boss\"\n",
        );
        let c = write(
            dir.path(),
            "c1.toml",
            "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"a.toml\"\n\
             [[node]]\nconfig = \"b.toml\"\n[[node]]\nconfig = \"c.toml\"\n",
        );
        let l = ClusterLayout::load(&c, &[]).unwrap();
        assert_eq!(l.dispatch_node(), Some("a"));
        assert_eq!(l.standby_nodes(), ["b"]);
        assert!(
            !l.nodes[0].config.dispatcher,
            "a desk runs no run of its own"
        );
        // two active nodes: refused at the second
        let c = write(
            dir.path(),
            "c2.toml",
            "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"a.toml\"\n\
             [[node]]\nconfig = \"d.toml\"\n",
        );
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        let f = c.display();
        assert!(
            text.contains(&format!("{f}:6:10: node `a` and node `d` both say")),
            "{text}"
        );
        // a role that is none: at its place in the node config
        let c = write(
            dir.path(),
            "c3.toml",
            "[cluster]\ncookie = \"k\"\n[[node]]\nconfig = \"e.toml\"\n",
        );
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        assert!(
            text.contains("e.toml:3:14: `boss` is not a dispatcher role"),
            "{text}"
        );
    }

    #[test]
    fn a_cluster_file_without_cookie_or_nodes_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let c = write(dir.path(), "c.toml", "[cluster]\nspeed = 1\n");
        let text = ClusterLayout::load(&c, &[]).unwrap_err().to_string();
        assert!(text.contains("missing `cookie`"), "{text}");
        assert!(text.contains("no `[[node]]`"), "{text}");
    }
}

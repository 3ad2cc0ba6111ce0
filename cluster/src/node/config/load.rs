//! Reading a node config file: the TOML walked by the shared reader, every problem a
//! diagnostic at its `file:line:col`, each operation checked against the catalogue.

use super::*;
use crate::net::detector::{HeartbeatConfig, DEFAULT_DEADLINE, MIN_DEADLINE};
use crate::net::{ClusterConfig, TlsFiles};
use marie_vocabulary::diagnostic::toml::{quote, Reader, Rule, Span, Tbl};
use marie_vocabulary::diagnostic::{beside, read_source, Diagnostic, Diagnostics};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

impl NodeConfig {
    /// Read and check a node config file against `catalog`. Every problem is a diagnostic
    /// at its `file:line:column`; a relative `world`, `data_dir` or TLS file is resolved
    /// against the file's directory.
    pub fn load(path: &Path, catalog: &[OperationFactory]) -> Result<NodeConfig, Diagnostics> {
        let src = read_source(path, "node config")?;
        NodeConfig::parse(&src, Some(path), catalog)
    }

    /// [`NodeConfig::load`] on text; `path` names it in diagnostics (`<node>` without one).
    pub fn parse(
        src: &str,
        path: Option<&Path>,
        catalog: &[OperationFactory],
    ) -> Result<NodeConfig, Diagnostics> {
        let file = path.map_or_else(|| "<node>".to_string(), |p| p.display().to_string());
        let mut r = Reader::new(src, file);
        let Some(doc) = r.parse() else {
            return r.finish(None, "the node config is not valid");
        };
        let top = r.top(&doc, "the node config");
        r.unknown_keys(
            &top,
            &[
                "node",
                "datamanager",
                "simulation",
                "supervisor",
                "operation",
                "cluster",
            ],
        );
        let mut config = NodeConfig::new("");
        match top.get("node") {
            None => r.err(
                &(0..0),
                "missing table `[node]` (expected `name = \"...\"`)",
            ),
            Some(v) => {
                if let Some(t) = r.table(v, "[node]") {
                    r.unknown_keys(&t, &["name", "dispatcher", "data_dir"]);
                    config.name = r.required_string(&t, "name").unwrap_or_default();
                    match r.string_if_one(&t, "dispatcher") {
                        Some((role, span)) => match role.parse() {
                            // a desk runs the cluster's runs: none of its own
                            Ok(role) => {
                                config.desk = Some(role);
                                config.dispatcher = false;
                            }
                            Err(e) => r.err(&span, e.to_string()),
                        },
                        _ => config.dispatcher = r.boolean(&t, "dispatcher", true),
                    }
                    config.data_dir = data_dir(&mut r, &t, path);
                }
            }
        }
        if let Some(v) = top.get("datamanager") {
            let has_data_dir = config.data_dir.is_some();
            for t in r.table_array(v, "datamanager").into_iter().flatten() {
                if let Some(d) = datamanager(&mut r, &t, &config.datamanagers, has_data_dir) {
                    config.datamanagers.push(d);
                }
            }
        }
        if let Some(v) = top.get("simulation") {
            if let Some(t) = r.table(v, "[simulation]") {
                config.simulation = Some(simulation(&mut r, &t, path));
            }
        }
        if let Some(v) = top.get("supervisor") {
            for t in r.table_array(v, "supervisor").into_iter().flatten() {
                if let Some(s) = supervisor(&mut r, &t, &config.supervisors) {
                    config.supervisors.push(s);
                }
            }
        }
        if let Some(v) = top.get("operation") {
            let supervisors: Vec<String> = config
                .operation_supervisors()
                .into_iter()
                .map(|s| s.name)
                .collect();
            for t in r.table_array(v, "operation").into_iter().flatten() {
                if let Some(op) = operation(&mut r, &t, catalog, &supervisors) {
                    config.operations.push(op);
                }
            }
        }
        if let Some(v) = top.get("cluster") {
            if let Some(t) = r.table(v, "[cluster]") {
                config.cluster = cluster(&mut r, &t, &config.name, path);
            }
        }
        r.finish(Some(config), "the node config is not valid")
    }
}

/// `[node] data_dir`: a directory, relative to the config file's; `None` when absent.
fn data_dir(r: &mut Reader<'_>, t: &Tbl<'_, '_>, path: Option<&Path>) -> Option<PathBuf> {
    let dir = r.string(t, "data_dir")?;
    if dir.trim().is_empty() {
        let span = t.get("data_dir").map_or(t.span.clone(), |v| v.span());
        r.err(
            &span,
            "`data_dir` must name a directory (leave it out to keep nothing on disk)",
        );
        return None;
    }
    Some(beside(path, dir))
}

/// `durability` of a `[[datamanager]]`: memory, process or sync; `None` when absent (the
/// node's default). `process` and `sync` need the node's `data_dir`.
fn durability(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    has_data_dir: bool,
) -> Result<Option<Durability>, ()> {
    let Some(v) = t.get("durability") else {
        return Ok(None);
    };
    let text = r.string_value(v, "durability").ok_or(())?;
    let Some(durability) = Durability::ALL.into_iter().find(|d| d.as_str() == text) else {
        let expected: Vec<&str> = Durability::ALL.iter().map(|d| d.as_str()).collect();
        r.err(
            &v.span(),
            format!(
                "unknown durability {} (expected one of: {})",
                quote(&text),
                expected.join(", ")
            ),
        );
        return Err(());
    };
    if durability != Durability::Memory && !has_data_dir {
        r.err(
            &v.span(),
            format!(
                "durability {} keeps a journal on disk, and this node has no `data_dir` \
                 (set `data_dir` in [node], or use \"memory\")",
                quote(&text)
            ),
        );
        return Err(());
    }
    Ok(Some(durability))
}

/// One `[[datamanager]]`: a known name (feature, parameter, world) or a name with an `id`,
/// and its durability.
pub(crate) fn datamanager(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    seen: &[DatamanagerConfig],
    has_data_dir: bool,
) -> Option<DatamanagerConfig> {
    r.unknown_keys(
        t,
        &[
            "name",
            "id",
            "durability",
            "replicas",
            "copies",
            "catch_up",
            "retention",
            "class_retention",
            "replace_after",
            "spares",
        ],
    );
    let retention = r
        .integer(t, "retention", Some(0), 1..=i64::MAX)
        .filter(|n| *n > 0)
        .map(|n| usize::try_from(n).unwrap_or(usize::MAX));
    let class_retention = class_retention(r, t);
    let catch_up = r
        .integer(t, "catch_up", Some(0), 1..=i64::from(u32::MAX))
        .filter(|n| *n > 0)
        .map(|n| n as usize);
    let durability = durability(r, t, has_data_dir);
    let replicas = replicas(r, t);
    let (replace_after, spares) = replacement(r, t, replicas.as_deref().unwrap_or_default());
    let name = r.required_string(t, "name")?;
    let known = [dm::FEATURE, dm::PARAMETER, dm::WORLD, dm::RUN];
    let id = r.integer(t, "id", Some(0), 0..=i64::from(u32::MAX));
    let spec = match known.iter().find(|k| k.name == name) {
        Some(k) => DatamanagerConfig::from(*k),
        None => {
            let Some(id) = id.filter(|id| *id > 0) else {
                r.err(
                    &t.span,
                    format!(
                        "datamanager {} is not one of feature, parameter, world, run: it needs an `id`",
                        quote(&name)
                    ),
                );
                return None;
            };
            DatamanagerConfig::new(name, id as u32)
        }
    };
    if seen.iter().any(|d| d.name == spec.name) {
        r.err(
            &t.span,
            format!("datamanager {} is declared twice", quote(&spec.name)),
        );
        return None;
    }
    Some(DatamanagerConfig {
        durability: durability.ok()?,
        replicas: replicas?,
        catch_up,
        retention,
        class_retention,
        replace_after,
        spares,
        ..spec
    })
}

/// `class_retention = { CLASS = N, ... }`: bounds of particular classes, each at least 1.
fn class_retention(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
) -> std::collections::BTreeMap<String, usize> {
    let mut bounds = std::collections::BTreeMap::new();
    let Some(v) = t.get("class_retention") else {
        return bounds;
    };
    let Some(table) = r.table_or(
        v,
        "class_retention",
        "a table of class names and record counts for `class_retention`",
    ) else {
        return bounds;
    };
    for (class, n) in table.in_file_order() {
        let Some(n) = r.int_value(n, class.get_ref()) else {
            continue;
        };
        if n < 1 {
            r.err(
                &class.span(),
                format!(
                    "the retention of class {} must be at least 1 record, found {n}",
                    quote(class.get_ref())
                ),
            );
            continue;
        }
        bounds.insert(
            class.get_ref().to_string(),
            usize::try_from(n).unwrap_or(usize::MAX),
        );
    }
    bounds
}

/// The nodes keeping replicas of a datamanager: `replicas = [...]`, or `copies`, its name in
/// builds before the word was settled (read alike; both at once is an error).
fn replicas(r: &mut Reader<'_>, t: &Tbl<'_, '_>) -> Option<Vec<String>> {
    let names = |list: Option<Vec<(String, _)>>| -> Vec<String> {
        list.unwrap_or_default()
            .into_iter()
            .map(|(s, _)| s)
            .collect()
    };
    let replicas = r.string_array(t, "replicas");
    let copies = r.string_array(t, "copies");
    if replicas.is_some() && copies.is_some() {
        r.err(
            &t.span,
            "give the datamanager's `replicas` once: `copies` is their old name",
        );
        return None;
    }
    Some(names(replicas.or(copies)))
}

/// The longest `replace_after`: a day (a node gone longer is an operator's matter).
const REPLACE_AFTER_MAX: f64 = 86_400.0;

/// `replace_after = SECONDS` and `spares = [...]` of a `[[datamanager]]` with `replicas`:
/// after a replica's node has been gone that long, the leader puts a replica on a spare
/// (or, without `spares`, on any live node that keeps none) and removes the gone one.
fn replacement(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    replicas: &[String],
) -> (Option<std::time::Duration>, Vec<String>) {
    let after = r.num(
        t,
        "replace_after",
        Some(0.0),
        Rule::AboveUpTo(0.0, REPLACE_AFTER_MAX),
    );
    let after = after.filter(|_| t.get("replace_after").is_some());
    let spares: Vec<(String, _)> = r.string_array(t, "spares").unwrap_or_default();
    if let Some((_, span)) = spares.first().filter(|_| t.get("replace_after").is_none()) {
        r.err(
            span,
            "`spares` are the nodes that may take a gone replica's place: give `replace_after = SECONDS` too",
        );
    }
    if let Some(v) = t.get("replace_after").filter(|_| replicas.is_empty()) {
        r.err(
            &v.span(),
            "`replace_after` replaces a gone replica: the datamanager keeps none (give `replicas = [...]`)",
        );
    }
    let mut names = Vec::new();
    for (name, span) in spares {
        if names.contains(&name) {
            r.err(&span, format!("spare {} is named twice", quote(&name)));
        } else {
            names.push(name);
        }
    }
    (after.map(std::time::Duration::from_secs_f64), names)
}

/// The `[simulation]` table.
fn simulation(r: &mut Reader<'_>, t: &Tbl<'_, '_>, path: Option<&Path>) -> SimulationConfig {
    r.unknown_keys(t, &["world", "seed", "drivers"]);
    let world_at = t.get("world").map(|v| {
        Diagnostic::at(
            r.file(),
            r.pos(&v.span()),
            "the world named here does not load:",
        )
    });
    let world = r.string(t, "world").map(|w| beside(path, w));
    let seed = r
        .integer(t, "seed", Some(-1), 0..=i64::MAX)
        .filter(|s| *s >= 0)
        .map(|s| s as u64);
    SimulationConfig {
        world,
        world_at,
        seed: t.get("seed").and(seed),
        drivers: r.boolean(t, "drivers", true),
    }
}

/// One `[[supervisor]]`.
fn supervisor(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    seen: &[SupervisorConfig],
) -> Option<SupervisorConfig> {
    r.unknown_keys(t, &["name", "strategy", "max_restarts", "period_s"]);
    let name = r.required_string(t, "name");
    let strategy = match t.get("strategy") {
        None => Some(Strategy::OneForOne),
        Some(v) => match r.string_value(v, "strategy").as_deref() {
            Some("one_for_one") => Some(Strategy::OneForOne),
            Some("one_for_all") => Some(Strategy::OneForAll),
            Some("rest_for_one") => Some(Strategy::RestForOne),
            Some(other) => {
                r.err(
                    &v.span(),
                    format!(
                        "unknown strategy {} (expected one of: one_for_one, one_for_all, rest_for_one)",
                        quote(other)
                    ),
                );
                None
            }
            None => None,
        },
    };
    let max_restarts = r.integer(
        t,
        "max_restarts",
        Some(DEFAULT_RESTARTS as i64),
        0..=MAX_RESTARTS as i64,
    );
    let period = r.num(
        t,
        "period_s",
        Some(DEFAULT_PERIOD.as_secs_f64()),
        Rule::AboveUpTo(0.0, MAX_PERIOD_S),
    );
    let name = name?;
    if seen.iter().any(|s| s.name == name) {
        r.err(
            &t.span,
            format!("supervisor {} is declared twice", quote(&name)),
        );
        return None;
    }
    Some(SupervisorConfig {
        name,
        strategy: strategy?,
        max_restarts: max_restarts? as usize,
        period: Duration::from_secs_f64(period?),
    })
}

/// One `[[operation]]`, checked against the catalogue and the declared supervisors.
fn operation(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    catalog: &[OperationFactory],
    supervisors: &[String],
) -> Option<OperationConfig> {
    r.unknown_keys(
        t,
        &[
            "name",
            "version",
            "instances",
            "supervisor",
            "restart",
            "pin",
            "fail_first_activations",
        ],
    );
    let name = r.required_string(t, "name");
    let version = match t.get("version") {
        None => Some(semver::VersionReq::STAR),
        Some(v) => {
            let text = r.string_value(v, "version");
            match text.as_deref().map(semver::VersionReq::parse) {
                Some(Ok(req)) => Some(req),
                Some(Err(e)) => {
                    r.err(
                        &v.span(),
                        format!(
                            "`version` must be a semver requirement such as \"1\", \"^2.1\" or \"*\": {e}"
                        ),
                    );
                    None
                }
                None => None,
            }
        }
    };
    let instances = r.integer(t, "instances", Some(1), 0..=MAX_INSTANCES as i64);
    let failing = r.integer(
        t,
        "fail_first_activations",
        Some(0),
        0..=MAX_FAILING_ACTIVATIONS as i64,
    );
    let supervisor = match t.get("supervisor") {
        None => Some(OPERATIONS.to_string()),
        Some(v) => {
            let s = r.string_value(v, "supervisor")?;
            if supervisors.contains(&s) {
                Some(s)
            } else {
                r.err(
                    &v.span(),
                    format!(
                        "no supervisor {} is declared (expected one of: {})",
                        quote(&s),
                        supervisors.join(", ")
                    ),
                );
                None
            }
        }
    };
    let restart = match t.get("restart") {
        None => Some(Restart::Permanent),
        Some(v) => match r.string_value(v, "restart").as_deref() {
            Some("permanent") => Some(Restart::Permanent),
            Some("transient") => Some(Restart::Transient),
            Some("temporary") => Some(Restart::Temporary),
            Some(other) => {
                r.err(
                    &v.span(),
                    format!(
                        "unknown restart {} (expected one of: permanent, transient, temporary)",
                        quote(other)
                    ),
                );
                None
            }
            None => None,
        },
    };
    let op = OperationConfig {
        name: name?,
        version: version?,
        instances: instances? as usize,
        supervisor: supervisor?,
        restart: restart?,
        pin: r.boolean(t, "pin", false),
        fail_first_activations: failing? as u64,
    };
    if let Err(problem) = check_operation(&op, catalog) {
        let (span, message) = match problem {
            OpProblem::Unknown(known) => (
                t.get("name").map_or(t.span.clone(), |v| v.span()),
                format!(
                    "this node cannot host operation {} (expected one of: {known})",
                    quote(&op.name)
                ),
            ),
            OpProblem::NoVersion(available) => (
                t.get("version").map_or(t.span.clone(), |v| v.span()),
                format!(
                    "no version of {} matches `{}` (available: {available})",
                    quote(&op.name),
                    op.version
                ),
            ),
        };
        r.err(&span, message);
        return None;
    }
    Some(op)
}

/// `[cluster]`: where the node listens, whom it joins, its cookie, its failure detector's
/// deadline (`deadline_ms`, default 1200, at least 300) and heartbeat period
/// (`heartbeat_ms`, default a fifth of the deadline, at most half of it), and `[cluster.tls]`.
fn cluster(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    node: &str,
    path: Option<&Path>,
) -> Option<ClusterConfig> {
    r.unknown_keys(
        t,
        &[
            "listen",
            "peers",
            "cookie",
            "deadline_ms",
            "heartbeat_ms",
            "tls",
        ],
    );
    // every key is read, and every problem reported, before any is acted on
    let tls = t
        .get("tls")
        .map(|v| r.table(v, "[cluster.tls]").and_then(|t| tls(r, &t, path)));
    let listen = t.get("listen").map(|v| (r.string(t, "listen"), v.span()));
    let listen = match listen {
        None => {
            r.err(
                &t.span,
                "missing `listen` in [cluster] (e.g. \"127.0.0.1:7100\")",
            );
            None
        }
        Some((text, span)) => text.and_then(|s| socket_addr(r, &s, &span, "listen")),
    };
    let peers: Vec<SocketAddr> = r
        .string_array(t, "peers")
        .unwrap_or_default()
        .into_iter()
        .filter_map(|(s, span)| {
            let addr = socket_addr(r, &s, &span, "peers")?;
            if addr.port() == 0 {
                r.err(&span, format!("peer {} needs its port", quote(&s)));
                return None;
            }
            Some(addr)
        })
        .collect();
    let cookie = r.required_string(t, "cookie");
    let min = MIN_DEADLINE.as_millis() as i64;
    let deadline = r.integer(
        t,
        "deadline_ms",
        Some(DEFAULT_DEADLINE.as_millis() as i64),
        min..=3_600_000,
    );
    // the period is checked against the deadline given, or the default one
    let most = deadline.unwrap_or(DEFAULT_DEADLINE.as_millis() as i64) / 2;
    let period = t
        .get("heartbeat_ms")
        .map(|_| r.integer(t, "heartbeat_ms", None, 1..=most));
    let mut heartbeat = HeartbeatConfig::with_deadline(Duration::from_millis(deadline? as u64));
    if let Some(period) = period {
        heartbeat.period = Duration::from_millis(period? as u64);
    }
    let mut config = ClusterConfig::new(listen?, cookie?);
    config.peers = peers;
    config.heartbeat = heartbeat;
    config.tls = match tls {
        None => None,
        Some(files) => Some(files?),
    };
    if let Err(e) = config.validate(node) {
        r.err(&t.span, e.to_string());
        return None;
    }
    Some(config)
}

/// `[cluster.tls]`: `cert`, `key` and `ca` (PEM files, relative to the config file's
/// directory, each checked to be readable here; their contents are checked when the node
/// starts) and an optional `server_name`.
fn tls(r: &mut Reader<'_>, t: &Tbl<'_, '_>, path: Option<&Path>) -> Option<TlsFiles> {
    r.unknown_keys(t, &["cert", "key", "ca", "server_name"]);
    let file = |r: &mut Reader<'_>, key: &str| -> Option<PathBuf> {
        let f = beside(path, r.required_string(t, key)?);
        if let Err(e) = std::fs::File::open(&f) {
            let span = t.get(key).map(|v| v.span()).unwrap_or(t.span.clone());
            r.err(&span, format!("`{key}`: cannot read {}: {e}", f.display()));
            return None;
        }
        Some(f)
    };
    let cert = file(r, "cert");
    let key = file(r, "key");
    let ca = file(r, "ca");
    let server_name = r.string(t, "server_name");
    Some(TlsFiles {
        cert: cert?,
        key: key?,
        ca: ca?,
        server_name,
    })
}

/// `IP:PORT`, or a diagnostic at `span`.
pub(crate) fn socket_addr(
    r: &mut Reader<'_>,
    s: &str,
    span: &Span,
    field: &str,
) -> Option<SocketAddr> {
    match s.parse() {
        Ok(a) => Some(a),
        Err(_) => {
            r.err(
                span,
                format!(
                    "`{field}`: {} is not an address (expected IP:PORT, e.g. \"127.0.0.1:7100\")",
                    quote(s)
                ),
            );
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(src: &str) -> Result<NodeConfig, String> {
        NodeConfig::parse(src, None, &[]).map_err(|d| d.to_string())
    }

    #[test]
    fn a_cluster_section_gives_listen_peers_and_cookie() {
        let c = parse(
            "[node]\nname = \"beta\"\n[cluster]\nlisten = \"127.0.0.1:7101\"\n\
             peers = [\"127.0.0.1:7100\", \"127.0.0.1:7102\"]\ncookie = \"thesis\"\n",
        )
        .unwrap();
        let cluster = c.cluster.unwrap();
        assert_eq!(cluster.listen, "127.0.0.1:7101".parse().unwrap());
        assert_eq!(cluster.peers.len(), 2);
        assert_eq!(cluster.cookie, "thesis");
        assert_eq!(parse("[node]\nname = \"solo\"\n").unwrap().cluster, None);
    }

    #[test]
    fn a_tls_table_names_files_relative_to_the_config_and_each_must_be_readable() {
        let dir = tempfile::tempdir().unwrap();
        for f in ["n.pem", "n.key", "ca.pem"] {
            std::fs::write(dir.path().join(f), "").unwrap();
        }
        let path = dir.path().join("node.toml");
        let cluster =
            "[node]\nname = \"n\"\n[cluster]\nlisten = \"127.0.0.1:7101\"\ncookie = \"c\"\n";
        let good =
            format!("{cluster}[cluster.tls]\ncert = \"n.pem\"\nkey = \"n.key\"\nca = \"ca.pem\"\n");
        let c = NodeConfig::parse(&good, Some(&path), &[]).unwrap();
        let tls = c.cluster.unwrap().tls.unwrap();
        assert_eq!(tls.cert, dir.path().join("n.pem"));
        assert_eq!(tls.ca, dir.path().join("ca.pem"));
        assert_eq!(tls.server_name, None);

        let bad =
            format!("{cluster}[cluster.tls]\ncert = \"gone.pem\"\nca = \"ca.pem\"\nsni = 1\n");
        let e = NodeConfig::parse(&bad, Some(&path), &[])
            .unwrap_err()
            .to_string();
        for want in [
            "node.toml:7:8: `cert`: cannot read",
            "gone.pem",
            "missing `key`",
            "node.toml:9:1: unknown key `sni`",
        ] {
            assert!(e.contains(want), "{want:?} not in:\n{e}");
        }
        // a bad [cluster.tls] hides nothing else in [cluster]
        let both = bad.replace("127.0.0.1:7101", "nowhere");
        let both = both.replace("[cluster.tls]", "deadline_ms = 5\n[cluster.tls]");
        let e = NodeConfig::parse(&both, Some(&path), &[])
            .unwrap_err()
            .to_string();
        for want in [
            "`nowhere` is not an address",
            "gone.pem",
            "`deadline_ms` must be",
        ] {
            assert!(e.contains(want), "{want:?} not in:\n{e}");
        }
    }

    #[test]
    fn a_data_dir_is_relative_to_the_config_and_makes_datamanagers_durable_by_default() {
        let dir = Path::new("/etc/marie/nodes");
        let path = dir.join("n.toml");
        let c = NodeConfig::parse(
            "[node]\nname = \"n\"\ndata_dir = \"../data/n\"\n\
             [[datamanager]]\nname = \"feature\"\n\
             [[datamanager]]\nname = \"world\"\ndurability = \"sync\"\n\
             [[datamanager]]\nname = \"parameter\"\ndurability = \"memory\"\n",
            Some(&path),
            &[],
        )
        .unwrap();
        assert_eq!(c.data_dir, Some(dir.join("../data/n")));
        let durability: Vec<_> = c.datamanagers.iter().map(|d| d.durability).collect();
        assert_eq!(
            durability,
            [None, Some(Durability::Sync), Some(Durability::Memory)]
        );
        let resolved: Vec<_> = c.datamanagers.iter().map(|d| c.durability_of(d)).collect();
        assert_eq!(
            resolved,
            [Durability::Process, Durability::Sync, Durability::Memory]
        );
        // an absolute data_dir stays as written
        let c = NodeConfig::parse(
            "[node]\nname = \"n\"\ndata_dir = \"/var/lib/marie\"\n",
            Some(&path),
            &[],
        )
        .unwrap();
        assert_eq!(c.data_dir, Some(PathBuf::from("/var/lib/marie")));
    }

    #[test]
    fn without_a_data_dir_datamanagers_are_in_memory_and_nothing_is_on_disk() {
        let c = parse(
            "[node]\nname = \"n\"\n[[datamanager]]\nname = \"feature\"\n\
             [[datamanager]]\nname = \"world\"\ndurability = \"memory\"\n",
        )
        .unwrap();
        assert_eq!(c.data_dir, None);
        for d in &c.datamanagers {
            assert_eq!(c.durability_of(d), Durability::Memory, "{}", d.name);
        }
        c.validate(&[]).unwrap();
    }

    #[test]
    fn a_durable_datamanager_without_a_data_dir_and_an_unknown_durability_are_refused_at_their_value(
    ) {
        let e = parse(
            "[node]\nname = \"n\"\n\
             [[datamanager]]\nname = \"feature\"\ndurability = \"process\"\n\
             [[datamanager]]\nname = \"world\"\ndurability =  \"sync\"\n\
             [[datamanager]]\nname = \"parameter\"\ndurability = \"disk\"\n\
             [[datamanager]]\nname = \"map\"\nid = 7\ndurability = 1\n",
        )
        .unwrap_err();
        for want in [
            "<node>:5:14: durability `process` keeps a journal on disk, and this node has no \
             `data_dir` (set `data_dir` in [node], or use \"memory\")",
            "<node>:8:15: durability `sync` keeps a journal on disk",
            "<node>:11:14: unknown durability `disk` (expected one of: memory, process, sync)",
            "<node>:15:14: expected a string for `durability`",
        ] {
            assert!(e.contains(want), "{want:?} not in:\n{e}");
        }
        // with a data_dir, an unknown value is still refused
        let e = parse(
            "[node]\nname = \"n\"\ndata_dir = \"d\"\n\
             [[datamanager]]\nname = \"feature\"\ndurability = \"Sync\"\n",
        )
        .unwrap_err();
        assert!(e.contains("<node>:6:14: unknown durability `Sync`"), "{e}");
        let e = parse("[node]\nname = \"n\"\ndata_dir = \" \"\n").unwrap_err();
        assert!(
            e.contains("<node>:3:12: `data_dir` must name a directory"),
            "{e}"
        );
        let e = parse("[node]\nname = \"n\"\ndata_dir = 3\n").unwrap_err();
        assert!(e.contains("<node>:3:12:"), "{e}");
    }

    #[test]
    fn a_config_value_with_a_durable_datamanager_needs_a_data_dir() {
        let mut c = NodeConfig::new("n");
        c.datamanagers
            .push(DatamanagerConfig::from(dm::FEATURE).with_durability(Durability::Sync));
        let e = c.validate(&[]).unwrap_err();
        assert_eq!(
            e,
            ConfigError::NoDataDir {
                datamanager: "feature".into(),
                durability: Durability::Sync
            }
        );
        assert!(e.to_string().contains("needs the node's data_dir"), "{e}");
        c.with_data_dir("/tmp/n").validate(&[]).unwrap();
    }

    #[test]
    fn replicas_and_their_catch_up_are_read_and_a_bad_catch_up_is_refused_at_its_value() {
        // `copies`, the old name, reads as `replicas`
        let c = parse(
            "[node]\nname = \"r1\"\ndata_dir = \"d\"\n\
             [[datamanager]]\nname = \"feature\"\nreplicas = [\"r1\", \"r2\", \"r3\"]\n\
             catch_up = 500\n\
             [[datamanager]]\nname = \"world\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n",
        )
        .unwrap();
        assert_eq!(c.datamanagers[0].replicas, ["r1", "r2", "r3"]);
        assert_eq!(c.datamanagers[1].replicas, ["r1", "r2", "r3"]);
        assert_eq!(c.datamanagers[0].catch_up, Some(500));
        assert_eq!(c.datamanagers[1].catch_up, None);
        let e = parse(
            "[node]\nname = \"r1\"\ndata_dir = \"d\"\n\
             [[datamanager]]\nname = \"feature\"\nreplicas = [\"r1\"]\ncopies = [\"r1\"]\n",
        )
        .unwrap_err();
        assert!(
            e.contains("<node>:4:1:") && e.contains("`copies` is their old name"),
            "{e}"
        );
        for bad in ["0", "-3", "\"many\""] {
            let e = parse(&format!(
                "[node]\nname = \"r1\"\ndata_dir = \"d\"\n\
                 [[datamanager]]\nname = \"feature\"\ncatch_up = {bad}\n"
            ))
            .unwrap_err();
            assert!(e.contains("<node>:6:12:"), "{bad}: {e}");
        }
    }

    #[test]
    fn the_run_datamanager_keeps_a_bounded_number_of_checkpoints_unless_told_otherwise() {
        use marie_actors::dispatcher::checkpoint::{CHECKPOINTS_KEPT, CHECKPOINT_CLASS};
        let c = parse(
            "[node]\nname = \"n\"\n\
             [[datamanager]]\nname = \"run\"\n\
             [[datamanager]]\nname = \"world\"\n",
        )
        .unwrap();
        let run = c.datamanagers[0].limits();
        assert_eq!(run.retention_for(CHECKPOINT_CLASS), CHECKPOINTS_KEPT);
        let world = c.datamanagers[1].limits();
        assert_eq!(
            world.retention_for(CHECKPOINT_CLASS),
            marie_dm::DmConfig::DEFAULT_RETENTION
        );
        let told = parse(
            "[node]\nname = \"n\"\n\
             [[datamanager]]\nname = \"run\"\nclass_retention = { checkpoint = 9000 }\n",
        )
        .unwrap();
        assert_eq!(
            told.datamanagers[0]
                .limits()
                .retention_for(CHECKPOINT_CLASS),
            9000
        );
    }

    #[test]
    fn retention_is_read_per_datamanager_and_class_and_a_bad_bound_is_refused_at_its_value() {
        let c = parse(
            "[node]\nname = \"n\"\n\
             [[datamanager]]\nname = \"feature\"\nretention = 50000\n\
             class_retention = { sonar = 200000, wall = 500 }\n\
             [[datamanager]]\nname = \"world\"\n",
        )
        .unwrap();
        let feature = c.datamanagers[0].limits();
        assert_eq!(feature.retention_for("line"), 50_000);
        assert_eq!(feature.retention_for("sonar"), 200_000);
        assert_eq!(feature.retention_for("wall"), 500);
        let world = c.datamanagers[1].limits();
        assert_eq!(
            world.retention_for("wall"),
            marie_dm::DmConfig::DEFAULT_RETENTION
        );
        for (bad, at) in [
            ("retention = 0", "<node>:5:13:"),
            ("retention = \"lots\"", "<node>:5:13:"),
            ("class_retention = { sonar = 0 }", "<node>:5:21:"),
            ("class_retention = { sonar = \"x\" }", "<node>:5:29:"),
            ("class_retention = 7", "<node>:5:19:"),
        ] {
            let e = parse(&format!(
                "[node]\nname = \"n\"\n[[datamanager]]\nname = \"feature\"\n{bad}\n"
            ))
            .unwrap_err();
            assert!(e.contains(at), "{bad}: {e}");
        }
    }

    #[test]
    fn each_bad_cluster_setting_is_reported_at_its_line() {
        let e = parse(
            "[node]\nname = \"beta\"\n[cluster]\nlisten = \"localhost\"\n\
             peers = [\"127.0.0.1:0\", 7, \"nowhere\"]\ncookie = \"c\"\nport = 1\n",
        )
        .unwrap_err();
        for want in [
            "<node>:4:10: `listen`: `localhost` is not an address",
            "<node>:5:10: peer `127.0.0.1:0` needs its port",
            "<node>:5:25: expected a string for `peers`, found integer",
            "<node>:5:28: `peers`: `nowhere` is not an address",
            "<node>:7:1: unknown key `port`",
        ] {
            assert!(e.contains(want), "{want:?} not in:\n{e}");
        }
        let e =
            parse("[node]\nname = \"a@b\"\n[cluster]\nlisten = \"127.0.0.1:1\"\ncookie = \"\"\n")
                .unwrap_err();
        assert!(
            e.contains("missing `cookie`") || e.contains("cookie"),
            "{e}"
        );
        let e =
            parse("[node]\nname = \"a@b\"\n[cluster]\nlisten = \"127.0.0.1:1\"\ncookie = \"x\"\n")
                .unwrap_err();
        assert!(e.contains("cannot join a cluster"), "{e}");
    }

    /// A do-nothing operation, for a catalogue to check `[[operation]]` tables against.
    #[derive(Default)]
    struct Idle;
    impl marie_actors::eo::Operation for Idle {
        fn identity(&self) -> marie_actors::eo::Identity {
            marie_actors::eo::Identity::new("idle", 4801, "1.0.0", "does nothing")
        }
        async fn step(
            &mut self,
            _: &mut marie_actors::eo::OpContext,
        ) -> Result<marie_actors::eo::Step, marie_actors::eo::OpError> {
            Ok(marie_actors::eo::Step::Continue)
        }
    }

    #[test]
    fn the_pin_and_the_fail_first_activations_knob_are_read_and_checked() {
        let catalog = [OperationFactory::new::<Idle>()];
        let parse = |extra: &str| {
            NodeConfig::parse(
                &format!("[node]\nname = \"n\"\n[[operation]]\nname = \"idle\"\n{extra}"),
                None,
                &catalog,
            )
            .map_err(|d| d.to_string())
        };
        assert_eq!(parse("").unwrap().operations[0].fail_first_activations, 0);
        let c = parse("fail_first_activations = 2\n").unwrap();
        assert_eq!(c.operations[0].fail_first_activations, 2);
        assert!(!c.operations[0].pin);
        assert!(parse("pin = true\n").unwrap().operations[0].pin);
        let e = parse("pin = 1\n").unwrap_err();
        assert!(e.contains("<node>:5:7") && e.contains("pin"), "{e}");
        let e = parse("fail_first_activations = -1\n").unwrap_err();
        assert!(
            e.contains("<node>:5:26") && e.contains("fail_first_activations"),
            "{e}"
        );
        let e = parse("fail_first_activations = 1001\n").unwrap_err();
        assert!(e.contains("fail_first_activations"), "{e}");
        // as a Rust value, the same bound
        let mut c = c;
        c.operations[0].fail_first_activations = MAX_FAILING_ACTIVATIONS + 1;
        assert!(matches!(
            c.validate(&catalog),
            Err(ConfigError::Range { .. })
        ));
    }
}

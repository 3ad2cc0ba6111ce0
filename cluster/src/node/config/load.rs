//! Reading a node config file: the TOML walked by the shared reader, every problem a
//! diagnostic at its `file:line:col`, each operation checked against the catalogue.

use super::*;
use marie_actors::diagnostic::toml::{quote, Reader, Rule, Tbl};
use marie_actors::diagnostic::{read_source, Diagnostic, Diagnostics};
use std::path::{Path, PathBuf};

impl NodeConfig {
    /// Read and check a node config file against `catalog`. Every problem is a diagnostic
    /// at its `file:line:column`; a relative `world` is resolved against the file's directory.
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
                    r.unknown_keys(&t, &["name", "dispatcher"]);
                    config.name = r.required_string(&t, "name").unwrap_or_default();
                    config.dispatcher = r.boolean(&t, "dispatcher", true);
                }
            }
        }
        if let Some(v) = top.get("datamanager") {
            for t in r.table_array(v, "datamanager").into_iter().flatten() {
                if let Some(d) = datamanager(&mut r, &t, &config.datamanagers) {
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
        r.finish(Some(config), "the node config is not valid")
    }
}

/// One `[[datamanager]]`: a known name (feature, parameter, world) or a name with an `id`.
fn datamanager(
    r: &mut Reader<'_>,
    t: &Tbl<'_, '_>,
    seen: &[DatamanagerConfig],
) -> Option<DatamanagerConfig> {
    r.unknown_keys(t, &["name", "id"]);
    let name = r.required_string(t, "name")?;
    let known = [dm::FEATURE, dm::PARAMETER, dm::WORLD];
    let id = r.integer(t, "id", Some(0), 0..=i64::from(u32::MAX));
    let spec = match known.iter().find(|k| k.name == name) {
        Some(k) => DatamanagerConfig::from(*k),
        None => {
            let Some(id) = id.filter(|id| *id > 0) else {
                r.err(
                    &t.span,
                    format!(
                        "datamanager {} is not one of feature, parameter, world: it needs an `id`",
                        quote(&name)
                    ),
                );
                return None;
            };
            DatamanagerConfig {
                id: id as u32,
                name,
            }
        }
    };
    if seen.iter().any(|d| d.name == spec.name) {
        r.err(
            &t.span,
            format!("datamanager {} is declared twice", quote(&spec.name)),
        );
        return None;
    }
    Some(spec)
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
    let world = r.string(t, "world").map(|w| {
        let w = PathBuf::from(w);
        match path.and_then(Path::parent) {
            Some(dir) if w.is_relative() => dir.join(w),
            _ => w,
        }
    });
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
        &["name", "version", "instances", "supervisor", "restart"],
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

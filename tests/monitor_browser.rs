//! The monitor's page in a real headless Chromium (issue 13): opened during a docking run
//! with a fault injected, it shows the loss, the rebind and the mission's success; on a
//! cluster (`marie up --monitor --allow-faults`) it asks the bound wall follower for its
//! properties and stops its node's process, and shows the cluster fail over; a replayed
//! events file ends with every action of the task tree succeeded; a viewer without the
//! token of a monitor that requires one is refused; a behaviour tree of 200 items (issue
//! 24), fed live, is drawn whole with its running branch, retry counts and timeouts, and an
//! update redraws only the rows that changed. On the thesis cluster kept up (issue 43): a
//! node killed and restarted, the strength panel says each datamanager's redundancy
//! restored, when and after how long; and with `--allow-changes` the page adds a replica of
//! a datamanager on a node and removes it again, and says why it will not for bad input.
//!
//! Every `marie` process and the browser are killed when the test ends, also on panic.

use crate::common;

use common::browser::Browser;
use common::cluster::{ls_join_rows, node_line, signal_pid, Proc};
use common::layouts::failover_layout;
use common::monitor::{monitored_run, monitored_up, page_of, recorded_run, replay_monitor, url_of};
use marie::clock::{Clock, ManualClock};
use marie::events::{ActionPlan, EventBus, EventKind, PlanItem};
use marie::run::OpEnd;
use marie_monitor::{Monitor, MonitorHandle, MonitorOptions};
use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

/// Generous: the page is fed live while a loaded 2-core machine also runs the mission.
const PAGE_TIMEOUT: Duration = Duration::from_secs(120);

/// The thesis' cluster, and its cookie.
const THESIS: &str = "missions/clusters/thesis.toml";
const THESIS_COOKIE: &str = "marie-thesis";
/// The datamanagers of the thesis' cluster, each kept in three replicas.
const THESIS_DMS: [&str; 4] = ["feature", "parameter", "world", "run"];

/// The wall follower's losses and rebinds in its binding's history.
const LOST: &str =
    "#bindings tr.history-row[data-op=\"wall-follower\"] .history li[data-type=\"lost\"]";
const REBOUND: &str =
    "#bindings tr.history-row[data-op=\"wall-follower\"] .history li[data-type=\"rebound\"]";

/// Wait until `js` holds on the page ([`PAGE_TIMEOUT`]); `what` names it if it never does.
#[track_caller]
fn shows(browser: &mut Browser, js: &str, what: &str) {
    if let Err(e) = browser.wait_for(js, PAGE_TIMEOUT) {
        panic!("{what}: {e:#}");
    }
}

/// JavaScript: `selector` matches something.
fn any(selector: &str) -> String {
    format!("document.querySelectorAll({selector:?}).length > 0")
}

/// How many elements `selector` matches on the page.
fn count(browser: &mut Browser, selector: &str) -> u64 {
    let js = format!("document.querySelectorAll({selector:?}).length");
    browser
        .evaluate(&js)
        .unwrap_or_else(|e| panic!("{js}: {e:#}"))
        .as_u64()
        .unwrap_or(0)
}

#[test]
fn the_page_shows_the_loss_the_rebind_and_the_success_of_a_docking_run_with_a_fault() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let mut run = monitored_run();
    let url = url_of(&run.wait_line("monitor: http://"));
    browser.navigate(&url).unwrap();
    // live: the task tree and the robot in its world while the mission runs
    shows(
        &mut browser,
        &any("#tree .action[data-state=\"running\"]"),
        "an action runs on the page",
    );
    shows(
        &mut browser,
        "document.querySelector('#world')?.dataset.hasWorld === 'true'",
        "the robot's world is drawn",
    );
    // the fault: the wall follower is lost, then rebound
    shows(&mut browser, &any(REBOUND), "the rebind shows");
    assert!(count(&mut browser, LOST) >= 1, "the loss shows");
    // without --allow-faults the page offers no fault, and the API refuses one
    assert_eq!(count(&mut browser, "button.fault, button.stop-node"), 0);
    let (addr, _) = page_of(&url);
    let kill = serde_json::json!({"fault": "kill", "operation": "wall-follower"});
    let (status, answer) = common::http::post_json(addr, "/api/fault", &kill);
    assert_eq!(status, 403, "{answer}");
    // with the epoch the stand-in's commands carry, above the first instance's
    let epoch = browser
        .evaluate(
            "Number(document.querySelector('#bindings tr.binding[data-op=\"wall-follower\"]').dataset.epoch)",
        )
        .unwrap();
    assert!(epoch.as_u64().unwrap_or(0) > 0, "epoch: {epoch}");
    // and the mission's success
    shows(
        &mut browser,
        "document.querySelector('#outcome')?.dataset.outcome === 'succeeded'",
        "the outcome shows",
    );
    assert_eq!(
        count(&mut browser, "#tree .action[data-state=\"succeeded\"]"),
        4
    );
    assert!(count(&mut browser, "#timeline li.entry.rebind") >= 1);
    let points = browser
        .evaluate("Number(document.querySelector('#path')?.dataset.points ?? 0)")
        .unwrap();
    assert!(points.as_u64().unwrap_or(0) > 100, "driven path: {points}");
    screenshot(&mut browser, "monitor-docking.png");
    run.signal("INT");
    assert_eq!(run.wait_exit(), Some(0), "{}", run.seen().join("\n"));
}

/// Save the page as `name` in the tests' target directory; it must be a picture with content.
fn screenshot(browser: &mut Browser, name: &str) {
    let shot = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let png = browser.screenshot(&shot).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{name}: {} bytes",
        png.len()
    );
}

/// Evaluate `js` on the page, as a string.
fn text_of(browser: &mut Browser, js: &str) -> String {
    let v = browser
        .evaluate(js)
        .unwrap_or_else(|e| panic!("{js}: {e:#}"));
    v.as_str().unwrap_or_default().to_string()
}

#[test]
fn the_page_stops_the_wall_followers_node_and_shows_the_cluster_fail_over() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let cluster = failover_layout(dir.path(), &["wf-a", "wf-b"], false);
    let (mut up, line) = monitored_up(
        cluster.to_str().unwrap(),
        &[
            "--run",
            "missions/docking.toml",
            "--speed",
            "4",
            "--allow-faults",
        ],
    );
    let url = url_of(&line);
    browser.navigate(&url).unwrap();
    // the wall follower runs: its binding offers kill and hang, its node a stop
    let kill = "#bindings button.fault[data-fault=\"kill\"][data-op=\"wall-follower\"]";
    shows(
        &mut browser,
        &format!(
            "document.querySelector('#tree .action[data-action=\"follow-wall\"]')?.dataset.state \
                 === 'running' && document.querySelector({kill:?}) !== null"
        ),
        "the wall follower runs, with its faults offered",
    );
    let node = text_of(
        &mut browser,
        &format!("document.querySelector({kill:?}).dataset.node"),
    );
    assert!(
        ["wf-a", "wf-b"].contains(&node.as_str()),
        "bound on {node:?}"
    );
    let other = if node == "wf-a" { "wf-b" } else { "wf-a" };
    // a click on the binding asks the live instance for its properties
    browser
        .evaluate(
            "document.querySelector('#bindings tr.binding[data-op=\"wall-follower\"]').click()",
        )
        .unwrap();
    shows(
        &mut browser,
        "document.querySelector('#props')?.dataset.live === 'true' \
             && document.querySelectorAll('#props .live-props tr.param').length > 0",
        "the live properties of the wall follower",
    );
    let version = text_of(
        &mut browser,
        "document.querySelector('#props .live-props').dataset.version",
    );
    assert!(!version.is_empty(), "its version");
    // stop its node's process from the page
    let stop = format!("#cluster button.stop-node[data-node=\"{node}\"]");
    browser
        .evaluate(&format!("document.querySelector({stop:?}).click()"))
        .unwrap();
    shows(
        &mut browser,
        "document.querySelector('#control-result')?.dataset.ok === 'true'",
        "the stop is done",
    );
    // the cluster loses the node, the dispatcher rebinds to the other one, docking succeeds
    shows(&mut browser, &any(REBOUND), "the rebind shows");
    shows(&mut browser, &format!(
                "['lost', 'down'].includes(document.querySelector('#cluster .node[data-node=\"{node}\"]')?.dataset.status)"
            ), "the stopped node is no longer up");
    shows(&mut browser, &format!(
                "document.querySelector({kill:?})?.dataset.node === {other:?} \
                 || document.querySelector('#bindings tr.binding[data-op=\"wall-follower\"] td:nth-child(3)')?.textContent === {other:?}"
            ), "the wall follower is bound on the other node");
    assert!(
        count(&mut browser, "#timeline li.entry.fault") >= 1,
        "the stop is in the timeline"
    );
    shows(
        &mut browser,
        "document.querySelector('#outcome')?.dataset.outcome === 'succeeded'",
        "the mission succeeds",
    );
    // a datamanager says what it holds: the layout keeps copies, so its role and term too
    shows(
        &mut browser,
        "document.querySelector('#cluster .module[data-module=\"feature\"] + .dm-state')\
             ?.textContent.includes('records, process, journal')\
             && document.querySelector('#cluster .module[data-module=\"feature\"] + .dm-state')\
             .textContent.includes('leader (term ')",
        "the feature datamanager's records, journal and role",
    );
    // any operation of the cluster panel answers a click with its live properties: here
    // one of the survivor's wall followers
    let module = format!(
        "#cluster .module[data-kind=\"operation\"][data-module=\"wall-follower\"][data-node=\"{other}\"]"
    );
    browser
        .evaluate(&format!("document.querySelector({module:?}).click()"))
        .unwrap();
    shows(
        &mut browser,
        &format!(
            "document.querySelector('#module-props')?.dataset.live === 'true' \
             && document.querySelector('#module-props').dataset.node === {other:?} \
             && document.querySelector('#module-props .live-props') !== null"
        ),
        "the properties of a module in the cluster panel",
    );
    // tall enough for every panel: the bindings and the cluster under the robot
    browser.set_viewport(1400, 1500).unwrap();
    screenshot(&mut browser, "monitor-cluster-failover.png");
    up.wait_line("the run is over");
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0), "{}", up.seen().join("\n"));
    assert!(
        up.seen()
            .iter()
            .any(|l| l.contains(&format!("node {node} was killed"))),
        "{}",
        up.seen().join("\n")
    );
}

#[test]
fn a_replayed_run_ends_with_every_action_of_the_task_tree_succeeded() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let events = recorded_run(dir.path());
    let (_monitor, line) = replay_monitor(&events, &[]);
    let url = url_of(&line);
    browser.navigate(&url).unwrap();
    shows(
        &mut browser,
        "document.querySelector('#mode')?.dataset.mode === 'replay' \
             && !document.querySelector('#replay-controls').hidden",
        "replay controls",
    );
    // at the start nothing has run yet
    shows(
        &mut browser,
        "document.querySelectorAll('#tree .action').length === 4",
        "the task tree",
    );
    assert_eq!(
        count(&mut browser, "#tree .action[data-state=\"succeeded\"]"),
        0
    );
    // the slider to the end, as a user drags it
    browser
        .evaluate(
            "(() => { const s = document.querySelector('#slider'); s.value = s.max; \
             s.dispatchEvent(new Event('input')); return s.max; })()",
        )
        .unwrap();
    shows(
        &mut browser,
        "document.querySelectorAll('#tree .action[data-state=\"succeeded\"]').length === 4",
        "every action succeeded at the end of the replay",
    );
    shows(
        &mut browser,
        "document.querySelector('#outcome')?.dataset.outcome === 'succeeded'",
        "the outcome at the end",
    );
    assert!(count(&mut browser, "#timeline li.entry.rebind") >= 1);
}

#[test]
fn a_viewer_without_the_token_is_refused() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("empty.jsonl");
    std::fs::write(&events, "").unwrap();
    let (_monitor, line) = replay_monitor(&events, &["--require-token"]);
    let url = url_of(&line);
    assert!(url.contains("?token="), "{url}");
    let bare = url.split('?').next().unwrap().to_string();
    browser.navigate(&bare).unwrap();
    let body = browser.evaluate("document.body.innerText").unwrap();
    assert!(
        body.as_str().unwrap_or("").contains("requires its token"),
        "{body}"
    );
    assert_eq!(count(&mut browser, "#tree"), 0, "the page must not load");
    // with the token the page loads
    browser.navigate(&url).unwrap();
    shows(
        &mut browser,
        "document.querySelector('#mode')?.dataset.mode === 'replay'",
        "the page with its token",
    );
}

/// A behaviour tree of exactly 200 items over 86 actions, as a run announces it: a schedule
/// (`big`) of 14 guarded groups — each a retry of a timeout of a fallback over a sequence
/// (an action, then a recover of two), a reactive sequence (a condition, an action) and a
/// parallel of two actions — and a closing sequence of two actions. Its action names, in
/// preorder.
///
/// Group 0's ids: retry 1, timeout 2, fallback 3 (`g00`), sequence 4, `g00-approach` 5,
/// recover 6, `g00-align` 7, `g00-back-off` 8, reactive 9, condition 10, `g00-creep` 11,
/// parallel 12, `g00-left` 13, `g00-right` 14.
fn big_plan() -> (Vec<PlanItem>, Vec<String>) {
    #[derive(Default)]
    struct Plan {
        nodes: Vec<PlanItem>,
        actions: Vec<String>,
    }
    impl Plan {
        fn add(&mut self, parent: Option<usize>, kind: &str, label: &str, detail: &str) -> usize {
            let id = self.nodes.len();
            self.nodes.push(PlanItem {
                id,
                parent,
                kind: kind.into(),
                label: label.into(),
                detail: detail.into(),
            });
            id
        }
        fn action(&mut self, parent: usize, name: String) {
            self.add(Some(parent), "action", &name, "cart");
            self.actions.push(name);
        }
    }
    let mut p = Plan::default();
    let root = p.add(None, "schedule", "big", "");
    for g in 0..14 {
        let name = format!("g{g:02}");
        let retry = p.add(
            Some(root),
            "retry",
            &format!("retry({name})"),
            "3 attempts, 2.0 s apart",
        );
        let timeout = p.add(
            Some(retry),
            "timeout",
            &format!("timeout({name})"),
            "40.0 s",
        );
        let fallback = p.add(Some(timeout), "fallback", &name, "");
        let main = p.add(Some(fallback), "sequence", &format!("{name}-main"), "");
        p.action(main, format!("{name}-approach"));
        let recover = p.add(
            Some(main),
            "recover",
            &format!("recover({name}-align, then {name}-back-off)"),
            "",
        );
        p.action(recover, format!("{name}-align"));
        p.action(recover, format!("{name}-back-off"));
        let careful = p.add(
            Some(fallback),
            "reactive",
            &format!("{name}-careful"),
            "while wall-found",
        );
        p.add(
            Some(careful),
            "condition",
            "condition(0x1)",
            "needs wall-found",
        );
        p.action(careful, format!("{name}-creep"));
        let both = p.add(
            Some(fallback),
            "parallel",
            &format!("{name}-both"),
            "succeeds at 1 of 2, fails at 2",
        );
        p.action(both, format!("{name}-left"));
        p.action(both, format!("{name}-right"));
    }
    let finish = p.add(Some(root), "sequence", "finish", "");
    p.action(finish, "park".into());
    p.action(finish, "report".into());
    (p.nodes, p.actions)
}

/// A live monitor on a bus of its own, fed by the test.
struct Fed {
    bus: EventBus,
    clock: ManualClock,
    monitor: MonitorHandle,
}

impl Fed {
    /// Publish `kinds`, a tenth of a second apart, and wait until the monitor holds them.
    fn publish(&self, kinds: impl IntoIterator<Item = EventKind>) {
        for kind in kinds {
            self.clock.advance(Duration::from_millis(100));
            self.bus.publish(kind);
        }
        assert!(
            self.monitor.flush(PAGE_TIMEOUT),
            "the monitor takes the events"
        );
    }

    fn run_ms(&self) -> u64 {
        self.clock.now().as_millis() as u64
    }

    fn started(&self, action: &str) -> EventKind {
        EventKind::ActionStarted {
            action: action.into(),
            run_ms: self.run_ms(),
            operations: vec![],
        }
    }

    fn ended(&self, action: &str) -> EventKind {
        EventKind::ActionEnded {
            action: action.into(),
            run_ms: self.run_ms(),
            flags: vec![],
            status: 0,
            result: None,
        }
    }

    fn decided(&self, node: &str, decision: &str) -> EventKind {
        EventKind::Control {
            item: node.into(),
            decision: decision.into(),
            run_ms: self.run_ms(),
        }
    }
}

fn op_ended(action: &str, ended: OpEnd) -> EventKind {
    EventKind::OpEnded {
        action: action.into(),
        key: "cart".into(),
        ended,
        flags: vec![],
    }
}

/// JavaScript: the row of node `id` of the behaviour tree.
fn row(id: usize) -> String {
    format!("document.querySelector('#control-tree .titem[data-id=\"{id}\"]')")
}

/// A number the page keeps in a data attribute (`document.body.dataset.renderMs`, …).
fn number(browser: &mut Browser, js: &str) -> f64 {
    let v = browser
        .evaluate(&format!("Number({js})"))
        .unwrap_or_else(|e| panic!("{js}: {e:#}"));
    v.as_f64().unwrap_or(f64::NAN)
}

#[test]
fn a_behaviour_tree_of_200_items_shows_its_running_branch_retries_and_timeouts() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let clock = ManualClock::new();
    let bus = EventBus::new("robot", Arc::new(clock.clone()));
    let monitor = Monitor::live(&bus, MonitorOptions::new("127.0.0.1:0".parse().unwrap()))
        .expect("a live monitor");
    let fed = Fed {
        bus,
        clock,
        monitor,
    };
    let (plan, actions) = big_plan();
    assert_eq!(plan.len(), 200);
    assert_eq!(actions.len(), 86);
    browser.navigate(&fed.monitor.url()).unwrap();
    shows(
        &mut browser,
        "document.querySelector('#mode')?.dataset.mode === 'live'",
        "the live page",
    );

    // a run without its tree yet (as an older stream has none): the list of actions
    fed.publish([EventKind::RunStarted {
        mission: "big".into(),
        actions: actions
            .iter()
            .map(|name| ActionPlan {
                name: name.clone(),
                when: vec![],
                ops: vec!["cart".into()],
                ends_on: vec!["cart".into()],
            })
            .collect(),
        success: vec![],
    }]);
    shows(
        &mut browser,
        "document.querySelectorAll('#tree .action').length === 86 \
         && !document.querySelector('#tree').hidden \
         && document.querySelector('#control-tree').hidden",
        "the task tree of a run without a behaviour tree",
    );

    // the plan: every node drawn, in place of the list
    fed.publish([EventKind::ControlPlan {
        items: plan.clone(),
    }]);
    shows(
        &mut browser,
        "document.querySelectorAll('#control-tree .titem').length === 200 \
         && document.querySelector('#tree').hidden",
        "the 200 items of the behaviour tree",
    );
    let build_ms = number(
        &mut browser,
        "document.querySelector('#control-tree').dataset.renderMs",
    );
    let labels = browser
        .evaluate(
            "Array.from(document.querySelectorAll('#control-tree .titem'), \
             (li) => li.dataset.label + '/' + li.dataset.kind + '/' + li.dataset.depth)",
        )
        .unwrap();
    let want: Vec<String> = plan
        .iter()
        .map(|n| {
            let mut depth = 0;
            let mut up = n.parent;
            while let Some(p) = up {
                depth += 1;
                up = plan[p].parent;
            }
            format!("{}/{}/{depth}", n.label, n.kind)
        })
        .collect();
    assert_eq!(labels, serde_json::json!(want), "every node, in preorder");

    // group 0's first attempt: its recovery runs, it falls back, its timeout fires
    fed.publish([
        fed.started("g00-approach"),
        op_ended("g00-approach", OpEnd::Finished),
        fed.ended("g00-approach"),
        fed.started("g00-align"),
        op_ended("g00-align", OpEnd::Failed),
        fed.ended("g00-align"),
        fed.decided(
            "recover(g00-align, then g00-back-off)",
            "recovery `g00-back-off`",
        ),
        fed.started("g00-back-off"),
        fed.ended("g00-back-off"),
        fed.decided("g00", "fallback to `g00-careful`"),
        fed.started("g00-creep"),
        fed.decided("timeout(g00)", "timeout after 40.0 s"),
        fed.ended("g00-creep"),
    ]);
    shows(
        &mut browser,
        &format!(
            "{}?.dataset.state === 'halted' && {}?.dataset.state === 'failed'",
            row(11),
            row(2)
        ),
        "the creep halted by the timeout, which failed",
    );
    let timeout = text_of(
        &mut browser,
        &format!("{}.querySelector('.mark.timeout')?.textContent", row(2)),
    );
    assert!(
        timeout.contains("timed out"),
        "the timeout's mark: {timeout:?}"
    );
    assert_eq!(
        text_of(&mut browser, &format!("{}.dataset.state", row(7))),
        "failed",
        "the align failed"
    );
    assert_eq!(
        count(&mut browser, "#control-tree .titem .mark.fallback"),
        1
    );
    assert_eq!(
        count(&mut browser, "#control-tree .titem .mark.recovery"),
        1
    );
    assert_eq!(
        count(&mut browser, "#control-tree .titem[data-state=\"running\"]"),
        0
    );

    // the retry's second attempt runs: the running branch from the root to the action
    fed.publish([
        fed.decided("retry(g00)", "retry 2 of 3"),
        fed.started("g00-approach"),
    ]);
    shows(
        &mut browser,
        &format!(
            "{}?.querySelector('.mark.attempt')?.textContent === 'attempt 2 of 3'",
            row(1)
        ),
        "the retry count",
    );
    let running = browser
        .evaluate(
            "Array.from(document.querySelectorAll('#control-tree .titem[data-state=\"running\"]'), \
             (li) => Number(li.dataset.id))",
        )
        .unwrap();
    assert_eq!(
        running,
        serde_json::json!([0, 1, 2, 3, 4, 5]),
        "the running branch"
    );
    assert_eq!(
        count(&mut browser, "#control-tree .titem .mark.timeout"),
        1,
        "the timeout of the first attempt stays counted"
    );
    assert!(text_of(
        &mut browser,
        &format!("{}.querySelector('.mark.starts')?.textContent", row(5))
    )
    .contains("run 2"));
    assert!(text_of(
        &mut browser,
        "document.querySelector('#control-summary').textContent"
    )
    .contains("running g00-approach"));
    // tall enough for the tree's panel and the timeline under it
    browser.set_viewport(1400, 1000).unwrap();
    screenshot(&mut browser, "monitor-behaviour-tree.png");

    // updates: each shows on the page; only the rows that changed are redrawn, the tree is
    // never built again
    let steps: Vec<(bool, &str)> = [
        "g00-approach",
        "g00-align",
        "g01-approach",
        "g01-align",
        "g02-approach",
        "g02-align",
        "g03-approach",
        "g03-align",
        "g04-approach",
        "g04-align",
    ]
    .iter()
    .enumerate()
    .flat_map(|(i, a)| {
        // g00-approach runs already
        let start = (i > 0).then_some((true, *a));
        start.into_iter().chain([(false, *a)])
    })
    .collect();
    let (mut tree_ms, mut page_ms, mut redrawn) = (Vec::new(), Vec::new(), Vec::new());
    for (start, action) in &steps {
        let (event, state) = match start {
            true => (fed.started(action), "running"),
            false => (fed.ended(action), "succeeded"),
        };
        fed.publish([event]);
        shows(
            &mut browser,
            &format!(
                "document.querySelector('#control-tree .titem[data-label=\"{action}\"]')\
                 ?.dataset.state === '{state}'"
            ),
            &format!("{action} {state}"),
        );
        tree_ms.push(number(
            &mut browser,
            "document.querySelector('#control-tree').dataset.renderMs",
        ));
        page_ms.push(number(&mut browser, "document.body.dataset.renderMs"));
        redrawn.push(number(
            &mut browser,
            "document.querySelector('#control-tree').dataset.updated",
        ));
    }
    // group 0 succeeded with its second attempt, up to the retry
    assert_eq!(
        text_of(&mut browser, &format!("{}.dataset.state", row(1))),
        "succeeded"
    );
    assert_eq!(
        text_of(
            &mut browser,
            "document.querySelector('#control-tree').dataset.builds"
        ),
        "1",
        "the tree is built once per plan"
    );
    assert!(
        redrawn.iter().all(|n| *n < 50.0),
        "an update redraws the rows that changed, not the tree: {redrawn:?}"
    );
    // the script and the browser's style and layout of one update, measured in the page:
    // the running action moves to another group's
    let with_layout = number(
        &mut browser,
        "(() => { const was = latest; const s = structuredClone(was); \
           for (const n of s.tree.items) n.running = false; \
           for (const id of [0, 43, 44, 45, 46, 47]) s.tree.items[id].running = true; \
           const t0 = performance.now(); render(s); document.body.getBoundingClientRect(); \
           document.querySelector('#control-tree').scrollHeight; \
           const ms = performance.now() - t0; render(was); return ms; })()",
    );
    let updates = browser
        .evaluate("Number(document.body.dataset.renders)")
        .unwrap();
    let stats = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[v.len() - 1])
    };
    let (tree_median, tree_max) = stats(&mut tree_ms);
    let (page_median, page_max) = stats(&mut page_ms);
    // past the harness's capture: the numbers are the point
    let _ = writeln!(
        std::io::stderr(),
        "monitor_browser: a tree of 200 items: built and drawn in {build_ms:.2} ms; \
         an update of the tree {tree_median:.2} ms (median of {}, max {tree_max:.2}), \
         of the whole page {page_median:.2} ms (max {page_max:.2}), \
         {with_layout:.2} ms with style and layout; rows redrawn per update {redrawn:?}; \
         {updates} renders",
        tree_ms.len()
    );
    // generous: the page showed every update within the waits above; a bound that cannot
    // flake, for a page that would redraw everything on a slow machine too
    assert!(tree_max < PAGE_TIMEOUT.as_millis() as f64, "{tree_max} ms");
    fed.monitor.stop();
}

/// `marie up` of the thesis' cluster at speed 4 with its page (and `extra` flags): the
/// process, the page's URL, and each node's (name, address, pid).
fn thesis_up(extra: &[&str]) -> (Proc, String, Vec<(String, String, u32)>) {
    let mut args = vec!["--speed", "4"];
    args.extend_from_slice(extra);
    let (up, line) = monitored_up(THESIS, &args);
    // the nodes are listed before the page's line
    let nodes: Vec<_> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    assert_eq!(nodes.len(), 4, "{}", up.seen().join("\n"));
    (up, url_of(&line), nodes)
}

/// JavaScript: every datamanager of the thesis' cluster shows its leader in the cluster
/// panel (the page has asked them what they hold).
fn every_dm_led() -> String {
    THESIS_DMS
        .iter()
        .map(|dm| {
            format!(
                "Array.from(document.querySelectorAll('#cluster .module[data-module=\"{dm}\"] + .dm-state'))\
                 .some((s) => s.textContent.includes('leader (term '))"
            )
        })
        .collect::<Vec<_>>()
        .join(" && ")
}

/// Stop `up` with Ctrl-C: it stops the cluster and exits 0.
fn stop_up(mut up: Proc) {
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0), "{}", up.seen().join("\n"));
}

/// `… redundancy restored, all 3 replicas current 2.3 s after the first was lost` → the
/// datamanager and the seconds.
fn restored_line(line: &str) -> Option<(String, f64)> {
    let (_, rest) = line.split_once("datamanager ")?;
    let (dm, rest) = rest.split_once(": redundancy restored, all ")?;
    let (_, rest) = rest.split_once(" replicas current ")?;
    let secs = rest.split_once(" s after")?.0.parse().ok()?;
    Some((dm.to_string(), secs))
}

#[test]
fn the_strength_panel_shows_each_datamanagers_redundancy_restored_after_a_node_is_killed_and_restarted(
) {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let (mut up, url, nodes) = thesis_up(&[]);
    browser.navigate(&url).unwrap();
    shows(&mut browser, &every_dm_led(), "every datamanager led");
    // without --allow-changes the page offers no change of replicas
    assert_eq!(
        browser
            .evaluate("document.querySelector('#replicas').hidden")
            .unwrap(),
        serde_json::json!(true)
    );
    // the operations node, which keeps a replica of every datamanager, killed by something
    // else than marie: `up` starts it again
    let (_, _, pid) = nodes.iter().find(|(n, _, _)| n == "operations").unwrap();
    let mark = up.seen().len();
    signal_pid(*pid, "KILL");
    up.wait_line_since(mark, "node operations was killed (SIGKILL): restarting it");
    up.wait_line_since(mark, "node operations restarted: listening on ");
    // each datamanager's leader tells its redundancy restored (on up's output); the page
    // says it in the strength panel, with when and after how long — the restoration told
    // last since the kill, as the line says it (a leader elected meanwhile may tell one
    // again)
    for dm in THESIS_DMS {
        up.wait_line_since(
            mark,
            &format!("datamanager {dm}: redundancy restored, all 3 replicas current"),
        );
    }
    let deadline = std::time::Instant::now() + PAGE_TIMEOUT;
    loop {
        up.drain();
        let told: std::collections::BTreeMap<String, f64> = up.seen()[mark..]
            .iter()
            .filter_map(|l| restored_line(l))
            .collect();
        let shown = browser
            .evaluate(
                "Object.fromEntries(Array.from(document.querySelectorAll('#strength .strength'), \
                 (d) => [d.dataset.dm, { text: d.querySelector('.restored')?.textContent ?? '', \
                 after_ms: Number(d.querySelector('.restored')?.dataset.afterMs ?? -1) }]))",
            )
            .unwrap();
        let matches = |dm: &str| {
            let (Some(secs), Some(page)) = (told.get(dm), shown.get(dm)) else {
                return false;
            };
            let after = page["after_ms"].as_f64().unwrap_or(-1.0) / 1000.0;
            // the line says tenths of a second
            after >= 0.0 && (after - secs).abs() <= 0.051
        };
        if THESIS_DMS.iter().all(|dm| matches(dm)) {
            for dm in THESIS_DMS {
                let text = shown[dm]["text"].as_str().unwrap();
                let (at, rest) = text
                    .strip_prefix("redundancy restored at ")
                    .and_then(|t| t.split_once(" s: all 3 replicas current "))
                    .unwrap_or_else(|| panic!("{dm}: {text:?}"));
                // from the page's first event, on the nodes' clock (which runs 4 times
                // real time): within the test's life, not decades away
                assert!(
                    at.parse::<f64>().is_ok_and(|t| t > 0.0 && t < 3600.0),
                    "{dm}: {text:?}"
                );
                assert!(rest.ends_with(" s after the first loss"), "{dm}: {text:?}");
                assert!(
                    shown[dm]["after_ms"].as_f64().unwrap() > 0.0,
                    "restored after a loss that took time: {dm}: {text:?}"
                );
            }
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the strength panel does not say what the leaders told: told {told:?}, shown {shown:#}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    // and the node back in the cluster panel
    shows(
        &mut browser,
        "document.querySelector('#cluster .node[data-node=\"operations\"] .back') !== null \
         && document.querySelector('#cluster .node[data-node=\"operations\"]').dataset.status === 'up'",
        "operations back",
    );
    let back = text_of(
        &mut browser,
        "document.querySelector('#cluster .node[data-node=\"operations\"] .back').textContent",
    );
    let at = back
        .strip_prefix("(back at ")
        .and_then(|b| b.split_once(" s after "))
        .and_then(|(at, _)| at.parse::<f64>().ok());
    assert!(at.is_some_and(|t| t > 0.0 && t < 3600.0), "{back:?}");
    browser.set_viewport(1400, 1500).unwrap();
    screenshot(&mut browser, "monitor-strength.png");
    stop_up(up);
}

/// How long the page may wait for a change of replicas: a learner catching up, on a loaded
/// machine (the control's own bound is a minute).
const CHANGE_TIMEOUT: Duration = Duration::from_secs(150);

/// Type `dm` and `node` into the page's replicas form and click `add` or `remove`; wait for
/// the answer: whether it was done, and what the page says.
fn change_from_page(browser: &mut Browser, change: &str, dm: &str, node: &str) -> (bool, String) {
    let clicked = browser
        .evaluate(&format!(
            "(() => {{ document.querySelector('#replica-dm').value = {dm:?}; \
             document.querySelector('#replica-node').value = {node:?}; \
             document.querySelector('#replica-{change}').click(); \
             return document.querySelector('#control-result').dataset.ok; }})()"
        ))
        .unwrap();
    assert_eq!(clicked, "pending", "{change} {dm} on {node}: the page asks");
    if let Err(e) = browser.wait_for(
        "document.querySelector('#control-result').dataset.ok !== 'pending'",
        CHANGE_TIMEOUT,
    ) {
        panic!("{change} {dm} on {node}: no answer on the page: {e:#}");
    }
    let ok = text_of(
        browser,
        "document.querySelector('#control-result').dataset.ok",
    );
    let said = text_of(
        browser,
        "document.querySelector('#control-result').textContent",
    );
    (ok == "true", said)
}

/// The voters of datamanager `dm` as its leader tells them (`marie ls --json`), sorted,
/// asked of the node at `addr` until `done` holds of them (at most [`CHANGE_TIMEOUT`]).
fn voters_until(addr: &str, dm: &str, done: impl Fn(&[String]) -> bool) -> Vec<String> {
    let deadline = std::time::Instant::now() + CHANGE_TIMEOUT;
    loop {
        let (_, rows, _) = ls_join_rows(addr, THESIS_COOKIE, &[]);
        let voters: Vec<String> = rows
            .iter()
            .find(|r| r["name"] == dm && r["replica"].is_object())
            .and_then(|r| r["replica"]["members"].as_array().cloned())
            .unwrap_or_default()
            .iter()
            .filter_map(|v| v.as_str().map(str::to_string))
            .collect();
        let mut voters = voters;
        voters.sort();
        if done(&voters) {
            return voters;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "{dm}: voters {voters:?}; rows {rows:#?}"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// JavaScript: whether the feature datamanager's leader lists a replica on `node`.
fn feature_lists(node: &str) -> String {
    format!(
        "Array.from(document.querySelectorAll('#cluster .module[data-module=\"feature\"] + .dm-state'))\
         .some((s) => s.querySelector('.replica[data-node=\"{node}\"]') !== null)"
    )
}

#[test]
fn the_page_adds_a_replica_on_a_node_and_removes_it_and_says_why_not_for_bad_input() {
    let Some(mut browser) = Browser::launch_or_skip("monitor_browser") else {
        return;
    };
    let (up, url, nodes) = thesis_up(&["--allow-changes"]);
    let (_, cart, _) = &nodes[0];
    browser.navigate(&url).unwrap();
    shows(
        &mut browser,
        "document.body.dataset.changes === 'true' && !document.querySelector('#replicas').hidden",
        "the replicas' form",
    );
    shows(&mut browser, &every_dm_led(), "every datamanager led");
    shows(
        &mut browser,
        &format!(
            "{} && {}",
            feature_lists("operations"),
            feature_lists("spare")
        ),
        "the feature datamanager's replicas on operations and spare",
    );
    // changes allowed, faults not: each has its own permission
    assert_eq!(count(&mut browser, "button.fault, button.node-fault"), 0);
    let declared = ["features", "operations", "spare"];
    assert_eq!(
        voters_until(cart, "feature", |v| v.len() == 3),
        declared.map(String::from)
    );

    // what the cluster will not do, said on the page in `marie dm`'s words
    let refusals = [
        (
            "remove",
            "feature",
            "spare",
            "would leave 2 voting replicas",
        ),
        (
            "add",
            "feature",
            "nowhere",
            "no node `nowhere` hosts replicas in the cluster",
        ),
        (
            "add",
            "feature",
            "features",
            "features already keeps a replica",
        ),
        (
            "add",
            "nothing",
            "cart",
            "no datamanager `nothing` in the cluster",
        ),
        ("remove", "feature", "cart", "cart keeps no replica"),
        (
            "add",
            "feature",
            "",
            "name the node whose replica of feature to add",
        ),
    ];
    for (change, dm, node, why) in refusals {
        let (ok, said) = change_from_page(&mut browser, change, dm, node);
        assert!(!ok, "{change} {dm} on {node:?}: {said}");
        assert!(
            said.starts_with("refused: ") && said.contains(why),
            "{change} {dm} on {node:?}: {said}"
        );
    }
    assert_eq!(
        voters_until(cart, "feature", |v| v.len() == 3),
        declared.map(String::from)
    );

    // a fourth replica, on the cart's node: it catches up, then votes
    let (ok, said) = change_from_page(&mut browser, "add", "feature", "cart");
    assert!(ok, "{said}");
    assert!(
        said.starts_with("feature: replica on cart added (replica started on cart; ")
            && said.contains("cart votes: voters "),
        "{said}"
    );
    let voters = voters_until(cart, "feature", |v| v.len() == 4);
    assert!(voters.iter().any(|v| v == "cart"), "{voters:?}");
    shows(
        &mut browser,
        &feature_lists("cart"),
        "the leader lists the replica on cart",
    );
    shows(
        &mut browser,
        &any("#timeline li.entry.datamanager"),
        "the change in the timeline",
    );
    assert!(
        text_of(
            &mut browser,
            "document.querySelector('#timeline').textContent"
        )
        .contains("datamanager feature: the replica on cart caught up and votes now"),
        "the promotion told in the timeline"
    );
    browser.set_viewport(1400, 1500).unwrap();
    screenshot(&mut browser, "monitor-replicas.png");

    // and removed again: back to the three declared
    let (ok, said) = change_from_page(&mut browser, "remove", "feature", "cart");
    assert!(ok, "{said}");
    assert!(
        said.starts_with("feature: replica on cart removed (configuration committed at seq ")
            && said.contains("cart removed: voters "),
        "{said}"
    );
    assert_eq!(
        voters_until(cart, "feature", |v| v.len() == 3),
        declared.map(String::from)
    );
    shows(
        &mut browser,
        &format!("!({})", feature_lists("cart")),
        "the leader no longer lists a replica on cart",
    );
    assert!(
        text_of(
            &mut browser,
            "document.querySelector('#timeline').textContent"
        )
        .contains("datamanager feature: the replica on cart was removed"),
        "the removal told in the timeline"
    );
    stop_up(up);
}

//! The monitor's page in a real headless Chromium (issue 13): opened during a docking run
//! with a fault injected, it shows the loss, the rebind and the mission's success; on a
//! cluster (`marie up --monitor --allow-faults`) it asks the bound wall follower for its
//! properties and stops its node's process, and shows the cluster fail over; a replayed
//! events file ends with every action of the task tree succeeded; a viewer without the
//! token of a monitor that requires one is refused.
//!
//! Every `marie` process and the browser are killed when the test ends, also on panic.

use crate::common;

use common::browser::Browser;
use common::layouts::failover_layout;
use common::monitor::{monitored_run, monitored_up, page_of, recorded_run, replay_monitor, url_of};
use std::time::Duration;

/// Generous: the page is fed live while a loaded 2-core machine also runs the mission.
const PAGE_TIMEOUT: Duration = Duration::from_secs(120);

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
             .textContent.includes('primary (term ')",
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

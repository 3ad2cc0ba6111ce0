//! The monitor's page in a real headless Chromium (issue 13): opened during a docking run
//! with a fault injected, it shows the loss, the rebind and the mission's success; a
//! replayed events file ends with every action of the task tree succeeded; a viewer
//! without the token of a monitor that requires one is refused.
//!
//! Every `marie` process and the browser are killed when the test ends, also on panic.

mod common;

use common::browser::Browser;
use common::monitor::{monitored_run, recorded_run, replay_monitor, url_of};
use std::time::Duration;

/// Generous: the page is fed live while a loaded 2-core machine also runs the mission.
const PAGE_TIMEOUT: Duration = Duration::from_secs(120);

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
    browser
        .wait_for(
            "document.querySelectorAll('#tree .action[data-state=\"running\"]').length > 0",
            PAGE_TIMEOUT,
        )
        .expect("an action runs on the page");
    browser
        .wait_for(
            "document.querySelector('#world')?.dataset.hasWorld === 'true'",
            PAGE_TIMEOUT,
        )
        .expect("the robot's world is drawn");
    // the fault: the wall follower is lost, then rebound
    let lost =
        "#bindings tr.history-row[data-op=\"wall-follower\"] .history li[data-type=\"lost\"]";
    let rebound =
        "#bindings tr.history-row[data-op=\"wall-follower\"] .history li[data-type=\"rebound\"]";
    browser
        .wait_for(
            &format!("document.querySelectorAll({rebound:?}).length > 0"),
            PAGE_TIMEOUT,
        )
        .expect("the rebind shows");
    assert!(count(&mut browser, lost) >= 1, "the loss shows");
    // with the epoch the stand-in's commands carry, above the first instance's
    let epoch = browser
        .evaluate(
            "Number(document.querySelector('#bindings tr.binding[data-op=\"wall-follower\"]').dataset.epoch)",
        )
        .unwrap();
    assert!(epoch.as_u64().unwrap_or(0) > 0, "epoch: {epoch}");
    // and the mission's success
    browser
        .wait_for(
            "document.querySelector('#outcome')?.dataset.outcome === 'succeeded'",
            PAGE_TIMEOUT,
        )
        .expect("the outcome shows");
    assert_eq!(
        count(&mut browser, "#tree .action[data-state=\"succeeded\"]"),
        4
    );
    assert!(count(&mut browser, "#timeline li.entry.rebind") >= 1);
    let points = browser
        .evaluate("Number(document.querySelector('#path')?.dataset.points ?? 0)")
        .unwrap();
    assert!(points.as_u64().unwrap_or(0) > 100, "driven path: {points}");
    let shot = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("monitor-docking.png");
    let png = browser.screenshot(&shot).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{}",
        png.len()
    );
    run.signal("INT");
    assert_eq!(run.wait_exit(), Some(0), "{}", run.seen().join("\n"));
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
    browser
        .wait_for(
            "document.querySelector('#mode')?.dataset.mode === 'replay' \
             && !document.querySelector('#replay-controls').hidden",
            PAGE_TIMEOUT,
        )
        .expect("replay controls");
    // at the start nothing has run yet
    browser
        .wait_for(
            "document.querySelectorAll('#tree .action').length === 4",
            PAGE_TIMEOUT,
        )
        .expect("the task tree");
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
    browser
        .wait_for(
            "document.querySelectorAll('#tree .action[data-state=\"succeeded\"]').length === 4",
            PAGE_TIMEOUT,
        )
        .expect("every action succeeded at the end of the replay");
    browser
        .wait_for(
            "document.querySelector('#outcome')?.dataset.outcome === 'succeeded'",
            PAGE_TIMEOUT,
        )
        .expect("the outcome at the end");
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
    browser
        .wait_for(
            "document.querySelector('#mode')?.dataset.mode === 'replay'",
            PAGE_TIMEOUT,
        )
        .expect("the page with its token");
}

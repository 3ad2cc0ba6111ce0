//! The headless Chromium driver of the tests (`common::browser`), proven on a page of its
//! own: it navigates, waits for a script that runs later, evaluates values, takes a
//! screenshot, reports exceptions and timeouts, and leaves no process behind.

use crate::common;

use common::browser::Browser;
use serde_json::json;
use std::io::{Read, Write};
use std::net::TcpListener;
use std::time::Duration;

/// The page: draws, then marks the body and sets a value 300 ms after it loaded.
const PAGE: &str = r##"<!doctype html>
<html><head><meta charset="utf-8"><title>marie browser test</title></head>
<body style="margin:0;background:#fff">
<h1 id="title">marie</h1>
<canvas id="c" width="400" height="200"></canvas>
<script>
const g = document.getElementById("c").getContext("2d");
g.fillStyle = "#0a8"; g.fillRect(20, 20, 300, 120);
g.strokeStyle = "#222"; g.lineWidth = 4; g.strokeRect(10, 10, 380, 180);
setTimeout(() => {
  window.answer = { sum: 2 + 40, words: ["dock", "found"] };
  document.body.setAttribute("data-ready", "yes");
}, 300);
</script>
</body></html>
"##;

/// Serve [`PAGE`] at `/` (404 elsewhere) from a thread; its base URL.
fn serve() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let _ = stream.set_read_timeout(Some(Duration::from_secs(10)));
            let mut request = Vec::new();
            let mut buf = [0u8; 1024];
            while !request.windows(4).any(|w| w == b"\r\n\r\n") {
                match stream.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => request.extend_from_slice(&buf[..n]),
                }
            }
            let root = request.starts_with(b"GET / ");
            let (status, body) = if root {
                ("200 OK", PAGE)
            } else {
                ("404 Not Found", "")
            };
            let _ = write!(
                stream,
                "HTTP/1.1 {status}\r\nContent-Type: text/html; charset=utf-8\r\n\
                 Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
                body.len()
            );
        }
    });
    url
}

/// Processes of group `pgid` that still run (zombies waiting for a reaper do not).
fn live_in_group(pgid: u32) -> Vec<String> {
    let mut live = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        // pid (comm) state ppid pgrp ...: comm may hold spaces, so read after its ')'
        let Some((_, rest)) = stat.rsplit_once(')') else {
            continue;
        };
        let fields: Vec<&str> = rest.split_whitespace().collect();
        if fields.get(2) == Some(&pgid.to_string().as_str()) && fields.first() != Some(&"Z") {
            live.push(stat);
        }
    }
    live
}

#[test]
fn the_driver_navigates_waits_evaluates_screenshots_and_leaves_nothing_behind() {
    let Some(mut browser) = Browser::launch_or_skip("browser") else {
        return;
    };
    let url = serve();
    browser.navigate(&url).unwrap();
    assert_eq!(
        browser.evaluate("document.title").unwrap(),
        json!("marie browser test")
    );

    // the script marks the page 300 ms after it loaded
    browser
        .wait_for(
            "document.body.getAttribute('data-ready') === 'yes'",
            Duration::from_secs(30),
        )
        .unwrap();
    assert_eq!(
        browser.evaluate("window.answer").unwrap(),
        json!({"sum": 42, "words": ["dock", "found"]})
    );
    assert_eq!(
        browser
            .evaluate("new Promise(done => setTimeout(() => done(6 * 7), 10))")
            .unwrap(),
        json!(42),
        "a promise is awaited"
    );
    assert_eq!(browser.evaluate("undefined").unwrap(), json!(null));

    // errors say what went wrong
    let thrown = browser.evaluate("nosuchthing.at.all").unwrap_err();
    assert!(
        format!("{thrown:#}").contains("nosuchthing is not defined"),
        "{thrown:#}"
    );
    let late = browser
        .wait_for("window.never === true", Duration::from_millis(300))
        .unwrap_err();
    assert!(format!("{late:#}").contains("not true after"), "{late:#}");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("page.png");
    let png = browser.screenshot(&path).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "a PNG");
    assert!(
        png.len() > 2000,
        "a drawn page, not a blank: {} bytes",
        png.len()
    );
    assert_eq!(std::fs::read(&path).unwrap(), png);
    // IHDR: the viewport asked for
    let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
    let height = u32::from_be_bytes(png[20..24].try_into().unwrap());
    assert_eq!((width, height), (1280, 800));

    // dropped: Chromium and every process it started are gone
    let pid = browser.pid();
    assert!(
        !live_in_group(pid).is_empty(),
        "Chromium runs in its own group"
    );
    drop(browser);
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    loop {
        let live = live_in_group(pid);
        if live.is_empty() {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "left behind: {live:#?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

//! A headless Chromium driven over the Chrome DevTools Protocol (CDP), for tests of the pages
//! marie serves (the live monitor of issue 13).
//!
//! # Why this way
//! A page's behaviour — scripts that draw from server-sent events — is only tested in a real
//! browser. WebDriver would need a chromedriver binary matching the browser; CDP is spoken
//! by Chromium itself: started with `--remote-debugging-port=0` it prints
//! `DevTools listening on ws://…` on stderr, lists its page targets at the HTTP endpoint
//! `/json/list`, and each target takes JSON commands over a WebSocket. A test needs four of
//! them: `Page.navigate`, `Runtime.evaluate` (also polled: [`Browser::wait_for`]) and
//! `Page.captureScreenshot`. Everything is blocking (tests are plain threads): a
//! [`tungstenite`] client, `std::net` for the one HTTP GET.
//!
//! # Invariants
//! - Chromium runs in a process group of its own, with a fresh profile directory: dropping
//!   the [`Browser`] (also while a failed test unwinds) kills the whole group by its pid, so
//!   no renderer or helper process outlives the test, and removes the profile.
//! - Every wait has a deadline; a command that gets no answer is an error naming it.
//! - Under `CI` a missing Chromium fails the test ([`Browser::launch_or_skip`]); elsewhere
//!   it is skipped with a message saying what to install.

use anyhow::{anyhow, bail, Context, Result};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

/// Where Debian's `chromium` package puts the browser.
pub(crate) const CHROMIUM: &str = "/usr/bin/chromium";

/// The page's viewport, CSS pixels: screenshots are this size.
pub(crate) const VIEWPORT: (u32, u32) = (1280, 800);
/// How long Chromium may take to start and open its first page (a loaded 2-core machine).
const START: Duration = Duration::from_secs(60);
/// How long one CDP command may take to be answered.
const ANSWER: Duration = Duration::from_secs(30);
/// How often [`Browser::wait_for`] asks again.
const POLL: Duration = Duration::from_millis(50);

/// A headless Chromium with one page, killed (with every process it started) when dropped.
pub(crate) struct Browser {
    page: WebSocket<MaybeTlsStream<TcpStream>>,
    next_id: u64,
    chromium: Chromium,
}

/// The running Chromium: killed with its process group when dropped, then its profile
/// removed (fields drop after `drop`).
struct Chromium {
    child: Child,
    _profile: tempfile::TempDir,
}

impl Browser {
    /// The Chromium binary: `$MARIE_CHROMIUM`, else [`CHROMIUM`], else `chromium` on the
    /// `PATH`; `None` when there is none.
    pub(crate) fn chromium() -> Option<PathBuf> {
        if let Some(path) = std::env::var_os("MARIE_CHROMIUM") {
            return Some(PathBuf::from(path));
        }
        if Path::new(CHROMIUM).exists() {
            return Some(PathBuf::from(CHROMIUM));
        }
        std::env::var_os("PATH").and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|dir| dir.join("chromium"))
                .find(|p| p.is_file())
        })
    }

    /// A browser for test `test`; `None` (after saying so on stderr) when no Chromium is
    /// installed — except under `CI`, where a missing browser fails the test.
    #[track_caller]
    pub(crate) fn launch_or_skip(test: &str) -> Option<Browser> {
        match Browser::chromium() {
            Some(path) => Some(
                Browser::launch(&path)
                    .unwrap_or_else(|e| panic!("{test}: cannot drive {}: {e:#}", path.display())),
            ),
            None if std::env::var_os("CI").is_some() => panic!(
                "{test}: no Chromium at {CHROMIUM} or on the PATH, and CI must run the browser \
                 tests: apt-get install chromium"
            ),
            None => {
                // past the test harness's capture (eprintln! is captured): a skip must be seen
                let _ = writeln!(
                    std::io::stderr(),
                    "{test}: skipped — no Chromium at {CHROMIUM} or on the PATH \
                     (apt-get install chromium, or set MARIE_CHROMIUM)"
                );
                None
            }
        }
    }

    /// Start the Chromium at `path` headless on `about:blank` and attach to its page.
    pub(crate) fn launch(path: &Path) -> Result<Browser> {
        let profile = tempfile::tempdir().context("a profile directory")?;
        let mut child = Command::new(path)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--window-size=1280,800",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg("about:blank")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            // its own group: dropping the browser kills its renderers and helpers too
            .process_group(0)
            .spawn()
            .with_context(|| format!("cannot start {}", path.display()))?;
        let stderr = child.stderr.take().expect("stderr is piped");
        // from here on, an error drops `chromium` and so kills it
        let chromium = Chromium {
            child,
            _profile: profile,
        };
        let port = port_of(&devtools_url(stderr)?)?;
        let page = page_target(port)?;
        let (page, _) =
            tungstenite::connect(page.as_str()).with_context(|| format!("connect to {page}"))?;
        let mut browser = Browser {
            page,
            next_id: 0,
            chromium,
        };
        // the window's size less its (headless) frame is not a fixed viewport: set one
        browser.set_viewport(VIEWPORT.0, VIEWPORT.1)?;
        Ok(browser)
    }

    /// Make the page's viewport `width` × `height` CSS pixels at scale 1 (screenshots have
    /// that size; [`Browser::launch`] sets [`VIEWPORT`]).
    pub(crate) fn set_viewport(&mut self, width: u32, height: u32) -> Result<()> {
        self.call(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        )?;
        Ok(())
    }

    /// Chromium's process id (also its process group's).
    pub(crate) fn pid(&self) -> u32 {
        self.chromium.child.id()
    }

    /// Load `url` in the page and wait until its document is complete.
    pub(crate) fn navigate(&mut self, url: &str) -> Result<()> {
        // a mark on the old page's window: gone once the new page has replaced it
        self.evaluate("window.__marieOld = true")?;
        let answer = self.call("Page.navigate", json!({ "url": url }))?;
        if let Some(error) = answer.get("errorText").and_then(Value::as_str) {
            bail!("cannot load {url}: {error}");
        }
        self.wait_for(
            "window.__marieOld === undefined && document.readyState === 'complete'",
            START,
        )
        .with_context(|| format!("{url} did not finish loading"))
    }

    /// The value of JavaScript `expression` in the page, as JSON (`null` for `undefined`; a
    /// promise is awaited). An exception is an error with its message.
    pub(crate) fn evaluate(&mut self, expression: &str) -> Result<Value> {
        let answer = self.call(
            "Runtime.evaluate",
            json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }),
        )?;
        if let Some(exception) = answer.get("exceptionDetails") {
            let why = exception["exception"]["description"]
                .as_str()
                .or_else(|| exception["text"].as_str())
                .unwrap_or("an exception");
            bail!("`{expression}` threw: {why}");
        }
        Ok(answer["result"]
            .get("value")
            .cloned()
            .unwrap_or(Value::Null))
    }

    /// Wait until JavaScript `expression` is `true`, asking every 50 ms for at most
    /// `timeout`; an error says what it was last (its value or what it threw).
    pub(crate) fn wait_for(&mut self, expression: &str, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            let last = match self.evaluate(expression) {
                Ok(Value::Bool(true)) => return Ok(()),
                Ok(other) => other.to_string(),
                Err(e) => format!("{e:#}"),
            };
            if Instant::now() >= deadline {
                bail!("`{expression}` not true after {timeout:?}: it is {last}");
            }
            std::thread::sleep(POLL);
        }
    }

    /// A PNG screenshot of the page's viewport, written to `path`; its bytes.
    pub(crate) fn screenshot(&mut self, path: &Path) -> Result<Vec<u8>> {
        let answer = self.call("Page.captureScreenshot", json!({ "format": "png" }))?;
        let data = answer["data"]
            .as_str()
            .ok_or_else(|| anyhow!("a screenshot without data: {answer}"))?;
        let png = data_encoding::BASE64
            .decode(data.as_bytes())
            .context("the screenshot's base64")?;
        std::fs::write(path, &png).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(png)
    }

    /// Send CDP command `method` to the page and wait for its answer's `result` (events that
    /// come meanwhile are passed over).
    pub(crate) fn call(&mut self, method: &str, params: Value) -> Result<Value> {
        self.next_id += 1;
        let id = self.next_id;
        let command = json!({ "id": id, "method": method, "params": params });
        self.page
            .send(Message::text(command.to_string()))
            .with_context(|| format!("cannot send {method}"))?;
        let deadline = Instant::now() + ANSWER;
        set_read_timeout(&self.page, Some(POLL))?;
        loop {
            if Instant::now() >= deadline {
                bail!("no answer to {method} within {ANSWER:?}");
            }
            let text = match self.page.read() {
                Ok(Message::Text(text)) => text,
                Ok(_) => continue,
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue
                }
                Err(e) => return Err(e).with_context(|| format!("waiting for {method}")),
            };
            let message: Value = serde_json::from_str(text.as_str())
                .with_context(|| format!("not JSON from Chromium: {text}"))?;
            if message["id"].as_u64() != Some(id) {
                continue; // an event, or an older command's late answer
            }
            if let Some(error) = message.get("error") {
                bail!("{method} failed: {error}");
            }
            return Ok(message["result"].clone());
        }
    }
}

/// The WebSocket URL of the first page target of the browser whose DevTools listen on
/// `port` (`/json/list`; it may take a moment to appear).
fn page_target(port: u16) -> Result<String> {
    let deadline = Instant::now() + START;
    loop {
        let targets = http_get(port, "/json/list")?;
        let list: Value = serde_json::from_str(&targets)
            .with_context(|| format!("/json/list is not JSON: {targets}"))?;
        let page = list.as_array().into_iter().flatten().find_map(|t| {
            (t["type"] == "page")
                .then(|| t["webSocketDebuggerUrl"].as_str())
                .flatten()
        });
        if let Some(url) = page {
            return Ok(url.to_string());
        }
        if Instant::now() >= deadline {
            bail!("no page target within {START:?}: {targets}");
        }
        std::thread::sleep(POLL);
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        // the whole group (renderers, zygote, helpers), then reap the browser itself
        let pid = self.child.id() as libc::pid_t;
        // SAFETY: kill(2) with a negative pid signals the group Chromium leads, which it
        // was made to lead at spawn; no memory is involved.
        unsafe {
            libc::kill(-pid, libc::SIGKILL);
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Read Chromium's stderr until it says where DevTools listen; keep draining it afterwards
/// (a full pipe would stall the browser).
fn devtools_url(stderr: std::process::ChildStderr) -> Result<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut tx = Some(tx);
        let mut seen = Vec::new();
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if let Some(sender) = &tx {
                if let Some(at) = line.find("DevTools listening on ") {
                    let url = line[at + "DevTools listening on ".len()..]
                        .trim()
                        .to_string();
                    let _ = sender.send(Ok(url));
                    tx = None;
                } else if seen.len() < 40 {
                    seen.push(line);
                }
            }
        }
        if let Some(sender) = tx {
            let _ = sender.send(Err(seen.join("\n")));
        }
    });
    match rx.recv_timeout(START) {
        Ok(Ok(url)) => Ok(url),
        Ok(Err(said)) => bail!("Chromium exited before listening for DevTools; it said:\n{said}"),
        Err(_) => bail!("Chromium did not say where DevTools listen within {START:?}"),
    }
}

/// The port of `ws://127.0.0.1:PORT/devtools/browser/ID`.
fn port_of(url: &str) -> Result<u16> {
    let rest = url
        .strip_prefix("ws://")
        .ok_or_else(|| anyhow!("not a ws:// URL: {url}"))?;
    let host = rest.split('/').next().unwrap_or_default();
    let port = host.rsplit(':').next().unwrap_or_default();
    port.parse()
        .with_context(|| format!("no port in the DevTools URL {url}"))
}

/// The body of `GET path` on the DevTools HTTP endpoint (HTTP/1.1, connection closed after).
fn http_get(port: u16, path: &str) -> Result<String> {
    let mut stream = TcpStream::connect(("127.0.0.1", port))
        .with_context(|| format!("connect to DevTools on port {port}"))?;
    stream.set_read_timeout(Some(ANSWER))?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )?;
    let mut response = Vec::new();
    let mut buf = [0u8; 8192];
    // read until the body is complete (by Content-Length) or the server closes
    loop {
        let n = stream.read(&mut buf).context("reading /json/list")?;
        if n == 0 {
            break;
        }
        response.extend_from_slice(&buf[..n]);
        if let Some((head, body)) = split_response(&response) {
            if content_length(head).is_some_and(|len| body.len() >= len) {
                break;
            }
        }
    }
    let (head, body) =
        split_response(&response).ok_or_else(|| anyhow!("a truncated HTTP answer to {path}"))?;
    if !head.starts_with("HTTP/1.1 200") {
        bail!("GET {path}: {}", head.lines().next().unwrap_or_default());
    }
    let len = content_length(head).unwrap_or(body.len()).min(body.len());
    Ok(String::from_utf8_lossy(&body[..len]).into_owned())
}

fn split_response(response: &[u8]) -> Option<(&str, &[u8])> {
    let at = response.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = std::str::from_utf8(&response[..at]).ok()?;
    Some((head, &response[at + 4..]))
}

fn content_length(head: &str) -> Option<usize> {
    head.lines().find_map(|l| {
        let (name, value) = l.split_once(':')?;
        name.eq_ignore_ascii_case("content-length")
            .then(|| value.trim().parse().ok())
            .flatten()
    })
}

fn set_read_timeout(
    socket: &WebSocket<MaybeTlsStream<TcpStream>>,
    timeout: Option<Duration>,
) -> Result<()> {
    match socket.get_ref() {
        MaybeTlsStream::Plain(stream) => Ok(stream.set_read_timeout(timeout)?),
        _ => bail!("a DevTools socket is plain TCP"),
    }
}

//! A tiny HTTP/1.1 client over `std::net::TcpStream`: enough to ask a monitor for JSON and
//! to read the first events of its live stream, without another dependency.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// Generous: a loaded 2-core machine.
pub(crate) const TIMEOUT: Duration = Duration::from_secs(30);

/// `GET path` (with `headers`); the status and the body.
pub(crate) fn get(addr: SocketAddr, path: &str, headers: &[(&str, &str)]) -> (u16, String) {
    request(addr, "GET", path, headers, "")
}

/// `POST path` with `body` as JSON; the status and the answer as JSON (`Null` if it is not).
pub(crate) fn post_json(
    addr: SocketAddr,
    path: &str,
    body: &serde_json::Value,
) -> (u16, serde_json::Value) {
    let (status, text) = request(
        addr,
        "POST",
        path,
        &[("Content-Type", "application/json")],
        &body.to_string(),
    );
    (
        status,
        serde_json::from_str(&text).unwrap_or(serde_json::Value::Null),
    )
}

/// `METHOD path` with `headers` and `body`; the status and the body.
pub(crate) fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> (u16, String) {
    let mut s = TcpStream::connect_timeout(&addr, TIMEOUT).expect("connect");
    s.set_read_timeout(Some(TIMEOUT)).unwrap();
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    if !body.is_empty() || method != "GET" {
        req.push_str(&format!("Content-Length: {}\r\n", body.len()));
    }
    req.push_str("\r\n");
    req.push_str(body);
    s.write_all(req.as_bytes()).unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).expect("read the answer");
    let text = String::from_utf8_lossy(&raw).to_string();
    let (head, body) = text.split_once("\r\n\r\n").expect("a head and a body");
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("a status");
    let body = if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        unchunk(body)
    } else {
        body.to_string()
    };
    (status, body)
}

/// `GET path` as JSON, which must answer 200.
pub(crate) fn get_json(addr: SocketAddr, path: &str) -> serde_json::Value {
    let (status, body) = get(addr, path, &[]);
    assert_eq!(status, 200, "{path}: {body}");
    serde_json::from_str(&body).unwrap_or_else(|e| panic!("{path}: {e}: {body}"))
}

fn unchunk(body: &str) -> String {
    let mut out = String::new();
    let mut rest = body;
    while let Some((size, after)) = rest.split_once("\r\n") {
        let n = usize::from_str_radix(size.trim(), 16).unwrap_or(0);
        if n == 0 || after.len() < n {
            break;
        }
        out.push_str(&after[..n]);
        rest = after[n..].trim_start_matches("\r\n");
    }
    out
}

/// A live stream (`GET path`, server-sent events over a chunked body), read event by
/// event.
pub(crate) struct EventStream {
    raw: BufReader<TcpStream>,
    /// De-chunked text not yet split into lines.
    text: String,
}

impl EventStream {
    /// Open `path`; panics unless it answers 200.
    pub(crate) fn open(addr: SocketAddr, path: &str) -> EventStream {
        let mut s = TcpStream::connect_timeout(&addr, TIMEOUT).expect("connect");
        s.set_read_timeout(Some(TIMEOUT)).unwrap();
        write!(
            s,
            "GET {path} HTTP/1.1\r\nHost: {addr}\r\nAccept: text/event-stream\r\n\r\n"
        )
        .unwrap();
        let mut raw = BufReader::new(s);
        let mut status = String::new();
        raw.read_line(&mut status).unwrap();
        assert!(status.contains(" 200 "), "{path}: {status}");
        let mut chunked = false;
        loop {
            let mut l = String::new();
            raw.read_line(&mut l).unwrap();
            chunked |= l
                .to_ascii_lowercase()
                .starts_with("transfer-encoding: chunked");
            if l == "\r\n" || l.is_empty() {
                break;
            }
        }
        assert!(chunked, "{path}: a stream is chunked");
        EventStream {
            raw,
            text: String::new(),
        }
    }

    /// The next line of the body (without its end).
    fn line(&mut self) -> String {
        loop {
            if let Some(i) = self.text.find('\n') {
                let line: String = self.text.drain(..=i).collect();
                return line.trim_end_matches(['\r', '\n']).to_string();
            }
            let mut size = String::new();
            let n = self.raw.read_line(&mut size).expect("a chunk in time");
            assert!(n > 0, "the stream ended");
            let size = usize::from_str_radix(size.trim(), 16).expect("a chunk size");
            assert!(size > 0, "the stream ended");
            let mut chunk = vec![0; size + 2];
            self.raw.read_exact(&mut chunk).expect("a whole chunk");
            self.text.push_str(&String::from_utf8_lossy(&chunk[..size]));
        }
    }

    /// The next event: its name and data (keep-alive comments skipped); panics after
    /// [`TIMEOUT`] without one.
    pub(crate) fn next(&mut self) -> (String, String) {
        let deadline = std::time::Instant::now() + TIMEOUT;
        let (mut name, mut data) = (String::new(), String::new());
        loop {
            assert!(std::time::Instant::now() < deadline, "no event in time");
            let l = self.line();
            if let Some(v) = l.strip_prefix("event:") {
                name = v.trim().to_string();
            } else if let Some(v) = l.strip_prefix("data:") {
                data.push_str(v.strip_prefix(' ').unwrap_or(v));
            } else if l.is_empty() && !name.is_empty() {
                return (name, data);
            }
        }
    }
}

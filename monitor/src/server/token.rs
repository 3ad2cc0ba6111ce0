//! The access token: a monitor listening beyond the loopback interface shows a robot's run
//! (and its cluster's layout) to whoever reaches the port, so it requires a random token on
//! every request — the page, its assets, the API and the live connection.
//!
//! The token is 128 bits from the OS (`/dev/urandom`; where that cannot be read, the
//! standard library's randomly keyed hasher), as hex. A request carries it as the query
//! parameter `token=` (what the printed URL holds and the page passes on, since a browser's
//! `EventSource` cannot set headers) or as `Authorization: Bearer TOKEN`.

use axum::extract::{Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::SocketAddr;
use std::sync::Arc;

/// Whether a monitor on `listen` needs a token: beyond loopback always; on loopback when
/// `forced`.
pub(crate) fn required(listen: SocketAddr, forced: bool) -> bool {
    forced || !listen.ip().is_loopback()
}

/// A fresh random token (32 hex digits).
pub(crate) fn generate() -> String {
    let mut bytes = [0u8; 16];
    let from_os = std::fs::File::open("/dev/urandom")
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut bytes));
    if from_os.is_err() {
        use std::hash::{BuildHasher, Hasher};
        for chunk in bytes.chunks_mut(8) {
            let mut h = std::collections::hash_map::RandomState::new().build_hasher();
            h.write_u128(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos()),
            );
            h.write_u32(std::process::id());
            chunk.copy_from_slice(&h.finish().to_le_bytes()[..chunk.len()]);
        }
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The token a request carries, if any: `token=` in the query, or a bearer token.
pub(crate) fn carried(req: &Request) -> Option<String> {
    let from_query = req.uri().query().and_then(|q| {
        q.split('&')
            .filter_map(|kv| kv.split_once('='))
            .find(|(k, _)| *k == "token")
            .map(|(_, v)| v.to_string())
    });
    from_query.or_else(|| {
        req.headers()
            .get(header::AUTHORIZATION)?
            .to_str()
            .ok()?
            .strip_prefix("Bearer ")
            .map(|t| t.trim().to_string())
    })
}

/// Equal in time independent of where they differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// The middleware: 401 for a request without the token (when one is required).
pub(crate) async fn check(
    State(token): State<Arc<Option<String>>>,
    req: Request,
    next: Next,
) -> Response {
    match token.as_deref() {
        None => next.run(req).await,
        Some(expected) if carried(&req).is_some_and(|t| same(&t, expected)) => next.run(req).await,
        Some(_) => (
            StatusCode::UNAUTHORIZED,
            [(header::WWW_AUTHENTICATE, "Bearer")],
            "this monitor requires its token: ?token=... as printed at its start, or \
             Authorization: Bearer ...\n",
        )
            .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beyond_loopback_a_token_is_required() {
        assert!(!required("127.0.0.1:7700".parse().unwrap(), false));
        assert!(!required("[::1]:7700".parse().unwrap(), false));
        assert!(required("127.0.0.1:7700".parse().unwrap(), true));
        assert!(required("0.0.0.0:7700".parse().unwrap(), false));
        assert!(required("192.168.1.20:7700".parse().unwrap(), false));
        assert!(required("[::]:7700".parse().unwrap(), false));
    }

    #[test]
    fn tokens_are_random_hex() {
        let (a, b) = (generate(), generate());
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }

    #[test]
    fn a_token_is_read_from_the_query_or_a_bearer_header() {
        let req = Request::builder()
            .uri("/api/state?x=1&token=abc")
            .body(axum::body::Body::empty())
            .unwrap();
        assert_eq!(carried(&req).as_deref(), Some("abc"));
        let req = Request::builder()
            .uri("/api/state")
            .header("authorization", "Bearer def")
            .body(axum::body::Body::empty())
            .unwrap();
        assert_eq!(carried(&req).as_deref(), Some("def"));
        let req = Request::builder()
            .uri("/api/state?tokens=abc")
            .body(axum::body::Body::empty())
            .unwrap();
        assert_eq!(carried(&req), None);
        assert!(same("abc", "abc") && !same("abc", "abd") && !same("abc", "ab"));
    }
}

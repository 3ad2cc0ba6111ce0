//! The monitor's HTTP server: the page and its API, on a thread of its own.
//!
//! Routes (every one behind the token when one is required, see [`token`]):
//!
//! | route | answer |
//! |---|---|
//! | `GET /` | the page (`/app.js`, `/style.css` beside it) |
//! | `GET /api/info` | `{"mode": "live" \| "replay", "token_required": bool, "faults_allowed": bool, "changes_allowed": bool, "offers": {"properties", "operation_faults", "stoppable_nodes", "cuttable"}, "fault_kinds": {"operation": [..], "node": [..], "cut": [..], "datamanager": [..]}}`: what the page may offer ([`Offers`]), and the fault kinds by what they aim at (the page draws a button per kind) |
//! | `GET /api/state` | the state now (live) or after the whole run (replay), JSON |
//! | `GET /api/live` | live only: server-sent events — `snapshot` (the state), then `state` on each change (at most 10 a second), `lagged` (`{"missed": n}`) then `snapshot` after a viewer fell behind |
//! | `GET /api/replay/info` | replay only: `{"events", "start_ms", "end_ms", "duration_ms"}` |
//! | `GET /api/replay/state?at_ms=T` | replay only: the state after every event up to T |
//! | `GET /api/props?operation=NAME&node=N&address=A` | live, with a [`Control`]: the operation's properties, asked of it now (404: not running; 502: it did not answer) |
//! | `POST /api/fault` | live, with a [`Control`] and faults allowed: a [`FaultRequest`] as JSON (`Content-Type: application/json`); 200 `{"done": "…"}`, 403 when faults are not allowed, 404 when the target is gone, 422 for an unknown kind or one that aims at something else |
//! | `POST /api/replicas` | live, with a [`Control`] and changes allowed: a [`ReplicaRequest`] as JSON (`Content-Type: application/json`), answered once the change is done; 200 `{"done": "…"}` (its steps), 403 when changes are not allowed, 404 for a datamanager or node the cluster does not have (or a replica the node does not keep), 409 when the cluster refuses it (a replica already there, too few left, no leader, a change under way), 422 for a blank name, 502 when it was tried and failed |
//!
//! Why a fault or a change needs `application/json`: a cross-site page cannot send that
//! content type without the browser asking first (a CORS preflight, which the monitor
//! never grants), so a page elsewhere cannot inject faults into a monitor on loopback, nor
//! move its cluster's replicas.
//!
//! Why changes have a permission of their own: a page allowed to inject faults (a drill on
//! a test cluster) need not be one allowed to reshape where the datamanagers keep their
//! replicas (an operator's console), and the other way round.
//!
//! Why a thread of its own: a node's `marie run` runs on a single-threaded runtime whose
//! clock is virtual; the monitor's serving, serializing and rate limiting must take none of
//! that thread's time and must tick in real time. The monitor runs a current-thread tokio
//! runtime on its thread; the node's side only publishes on its bus, as it always does.

pub(crate) mod assets;
pub(crate) mod live;
pub(crate) mod replay;
pub(crate) mod token;

use crate::control::{Control, ControlError, FaultRequest, Offers, OperationRef, ReplicaRequest};
use crate::error::MonitorError;
use axum::extract::{Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Json;
use axum::Router;
use live::{Feed, Live};
use marie_vocabulary::events::EventBus;
use marie_vocabulary::run::{Aim, FaultKind};
use replay::Replay;
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

/// Where and how a monitor listens, and what its viewers may do beyond watching.
#[derive(Clone)]
pub struct MonitorOptions {
    /// The address to listen on (port 0: one the OS picks; see [`MonitorHandle::addr`]).
    pub listen: SocketAddr,
    /// Require a token on loopback too (beyond loopback one is always required).
    pub require_token: bool,
    /// What answers the page's clicks on a live run (properties; faults when allowed).
    pub control: Option<Arc<dyn Control>>,
    /// Let the page inject faults through [`control`](Self::control) (`--allow-faults`).
    pub allow_faults: bool,
    /// Let the page add and remove datamanagers' replicas through
    /// [`control`](Self::control) (`--allow-changes`).
    pub allow_changes: bool,
    /// How to bind the listener (default: [`std::net::TcpListener::bind`]) — e.g. in
    /// another network namespace than the calling thread's, where a browser reaches it.
    pub binder: Option<Binder>,
}

/// Binds a monitor's listener on an address ([`MonitorOptions::binder`]).
pub type Binder = Arc<dyn Fn(SocketAddr) -> std::io::Result<std::net::TcpListener> + Send + Sync>;

impl MonitorOptions {
    /// Listen on `listen`, a token only beyond loopback, no control.
    pub fn new(listen: SocketAddr) -> MonitorOptions {
        MonitorOptions {
            listen,
            require_token: false,
            control: None,
            allow_faults: false,
            allow_changes: false,
            binder: None,
        }
    }

    /// Bind the listener with `binder` instead of [`std::net::TcpListener::bind`].
    pub fn with_binder(mut self, binder: Binder) -> Self {
        self.binder = Some(binder);
        self
    }

    /// Answer the page's clicks with `control`; faults only when `allow_faults`.
    pub fn with_control(mut self, control: Arc<dyn Control>, allow_faults: bool) -> Self {
        self.control = Some(control);
        self.allow_faults = allow_faults;
        self
    }

    /// Let the page add and remove datamanagers' replicas through the control, when
    /// `allowed` (the page offers it only with a control, on a live run).
    pub fn allowing_changes(mut self, allowed: bool) -> Self {
        self.allow_changes = allowed;
        self
    }
}

impl std::fmt::Debug for MonitorOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MonitorOptions")
            .field("listen", &self.listen)
            .field("require_token", &self.require_token)
            .field("control", &self.control.as_ref().map(|c| c.offers()))
            .field("allow_faults", &self.allow_faults)
            .field("allow_changes", &self.allow_changes)
            .field("binder", &self.binder.is_some())
            .finish()
    }
}

/// The default address of `marie monitor`.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:7700";

/// The monitor's server.
#[derive(Debug)]
pub struct Monitor;

/// A running monitor: where it listens, its token, a feed of more events (live), and how to
/// stop it. Dropping it stops it too.
pub struct MonitorHandle {
    addr: SocketAddr,
    token: Option<String>,
    feed: Option<Feed>,
    /// Asks a live monitor's reducer to catch up ([`MonitorHandle::flush`]).
    flushes: Option<mpsc::UnboundedSender<live::FlushRequest>>,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl std::fmt::Debug for MonitorHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MonitorHandle")
            .field("addr", &self.addr)
            .field("token", &self.token.as_ref().map(|_| "…"))
            .finish_non_exhaustive()
    }
}

/// What the server serves.
enum Source {
    Live(Arc<Live>),
    Replay(Arc<Replay>),
}

struct App {
    source: Source,
    token: Option<String>,
    /// Live only (a replay has no run to ask).
    control: Option<Arc<dyn Control>>,
    allow_faults: bool,
    allow_changes: bool,
}

impl App {
    /// What the page may offer: nothing on a replay; faults only when allowed.
    fn offers(&self) -> Offers {
        let Some(control) = self.live_control() else {
            return Offers::default();
        };
        let offers = control.offers();
        if self.allow_faults {
            offers
        } else {
            Offers {
                properties: offers.properties,
                ..Offers::default()
            }
        }
    }

    fn live_control(&self) -> Option<&Arc<dyn Control>> {
        match self.source {
            Source::Live(_) => self.control.as_ref(),
            Source::Replay(_) => None,
        }
    }
}

type Shared = Arc<App>;

impl Monitor {
    /// Serve the live state of the node whose bus is `bus`: every event it publishes from
    /// now on (more may be fed in, [`MonitorHandle::feed`]).
    pub fn live(bus: &EventBus, options: MonitorOptions) -> Result<MonitorHandle, MonitorError> {
        let subscription = Some(bus.subscribe());
        let (live, feed, fed) = Live::new();
        let (flushes, flush_requests) = mpsc::unbounded_channel();
        let tasks_live = live.clone();
        let tasks_feed = feed.clone();
        let mut handle = start(options, Source::Live(live.clone()), move || {
            tokio::spawn(
                tasks_live
                    .clone()
                    .reduce(subscription, fed, tasks_feed, flush_requests),
            );
            tokio::spawn(tasks_live.tick());
        })?;
        handle.feed = Some(feed);
        handle.flushes = Some(flushes);
        Ok(handle)
    }

    /// Serve the replay of the events file at `path`.
    pub fn replay(path: &Path, options: MonitorOptions) -> Result<MonitorHandle, MonitorError> {
        let replay = Arc::new(Replay::load(path)?);
        start(options, Source::Replay(replay), || {})
    }
}

impl MonitorHandle {
    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The token every request must carry, when one is required.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// The page's URL, with the token when one is required.
    pub fn url(&self) -> String {
        match &self.token {
            Some(t) => format!("http://{}/?token={t}", self.addr),
            None => format!("http://{}/", self.addr),
        }
    }

    /// Feed more events into a live monitor (`None` for a replay).
    pub fn feed(&self) -> Option<Feed> {
        self.feed.clone()
    }

    /// Wait until a live monitor's state holds every event published on its bus and fed
    /// into it before this call — at most `timeout`; false when it did not in time (or the
    /// monitor no longer reduces). A replay's state is complete from the start: true.
    ///
    /// Why: the monitor takes the bus's events every
    /// 10 ms (its bus poll), on its own thread, so its state may trail the bus; a
    /// caller about to say "the run is over" flushes first, and whoever reads the page
    /// after that line sees the run's last events. Blocks the calling thread (the monitor
    /// needs nothing from the caller's runtime, and a deadline in real time holds also on a
    /// runtime whose clock is paused).
    pub fn flush(&self, timeout: Duration) -> bool {
        let Some(flushes) = &self.flushes else {
            return true;
        };
        let (done, acked) = std::sync::mpsc::sync_channel(1);
        if flushes.send(done).is_err() {
            return false;
        }
        acked.recv_timeout(timeout).is_ok()
    }

    /// Stop serving (viewers' connections close) and wait for the monitor's thread.
    pub fn stop(mut self) {
        self.stop_now();
    }

    fn stop_now(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for MonitorHandle {
    fn drop(&mut self) {
        self.stop_now();
    }
}

/// Bind, then serve `source` on a thread of its own; `spawn` starts the source's tasks on
/// the monitor's runtime.
fn start(
    options: MonitorOptions,
    source: Source,
    spawn: impl FnOnce() + Send + 'static,
) -> Result<MonitorHandle, MonitorError> {
    let bind = |source| MonitorError::Bind {
        addr: options.listen,
        source,
    };
    let listener = match &options.binder {
        Some(binder) => binder(options.listen),
        None => std::net::TcpListener::bind(options.listen),
    }
    .map_err(bind)?;
    listener.set_nonblocking(true).map_err(bind)?;
    let addr = listener.local_addr().map_err(bind)?;
    let token = token::required(options.listen, options.require_token).then(token::generate);
    let app = Arc::new(App {
        source,
        token: token.clone(),
        control: options.control.clone(),
        allow_faults: options.allow_faults,
        allow_changes: options.allow_changes,
    });
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(MonitorError::Runtime)?;
    let (stop, stopped) = oneshot::channel::<()>();
    let thread = std::thread::Builder::new()
        .name("marie-monitor".into())
        .spawn(move || {
            runtime.block_on(async move {
                spawn();
                let listener = match tokio::net::TcpListener::from_std(listener) {
                    Ok(l) => l,
                    Err(e) => {
                        tracing::error!(error = %e, "the monitor cannot listen");
                        return;
                    }
                };
                let serve = axum::serve(listener, router(app));
                tokio::select! {
                    served = serve => if let Err(e) = served {
                        tracing::error!(error = %e, "the monitor stopped serving");
                    },
                    _ = stopped => {}
                }
            });
            // dropping the runtime ends the viewers' connections and the source's tasks
        })
        .map_err(MonitorError::Runtime)?;
    tracing::info!(%addr, "monitor listening");
    Ok(MonitorHandle {
        addr,
        token,
        feed: None,
        flushes: None,
        stop: Some(stop),
        thread: Some(thread),
    })
}

fn router(app: Shared) -> Router {
    let token = Arc::new(app.token.clone());
    Router::new()
        .route("/", get(index))
        .route("/index.html", get(index))
        .route("/app.js", get(app_js))
        .route("/style.css", get(style_css))
        .route("/api/info", get(info))
        .route("/api/state", get(state))
        .route("/api/live", get(live_events))
        .route("/api/replay/info", get(replay_info))
        .route("/api/replay/state", get(replay_state))
        .route("/api/props", get(props))
        .route("/api/fault", post(fault))
        .route("/api/replicas", post(replicas))
        .layer(axum::middleware::from_fn_with_state(token, token::check))
        .with_state(app)
}

fn json_of<T: serde::Serialize>(value: &T) -> Response {
    match serde_json::to_string(value) {
        Ok(body) => json_body(body),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

fn json_body(body: impl Into<axum::body::Body>) -> Response {
    (
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body.into(),
    )
        .into_response()
}

fn not_here(what: &str) -> Response {
    (StatusCode::NOT_FOUND, format!("{what}\n")).into_response()
}

async fn index(State(app): State<Shared>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        assets::index(app.token.as_deref()),
    )
        .into_response()
}

async fn app_js() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        assets::APP_JS,
    )
        .into_response()
}

async fn style_css() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        assets::STYLE_CSS,
    )
        .into_response()
}

async fn info(State(app): State<Shared>) -> Response {
    let mode = match app.source {
        Source::Live(_) => "live",
        Source::Replay(_) => "replay",
    };
    json_of(&serde_json::json!({
        "mode": mode,
        "token_required": app.token.is_some(),
        "faults_allowed": app.allow_faults && app.live_control().is_some(),
        "changes_allowed": app.allow_changes && app.live_control().is_some(),
        "offers": app.offers(),
        "fault_kinds": {
            "operation": FaultKind::aiming_at(Aim::Operation).collect::<Vec<_>>(),
            "node": FaultKind::aiming_at(Aim::Node).collect::<Vec<_>>(),
            "cut": FaultKind::aiming_at(Aim::Cut).collect::<Vec<_>>(),
            "datamanager": FaultKind::ALL
                .into_iter()
                .filter(|k| k.hits_datamanager())
                .collect::<Vec<_>>(),
        },
    }))
}

/// A control's refusal as an HTTP answer: `{"error": "…"}`.
fn refused(status: StatusCode, why: impl std::fmt::Display) -> Response {
    (status, Json(serde_json::json!({"error": why.to_string()}))).into_response()
}

fn control_error(e: ControlError) -> Response {
    let status = match e {
        ControlError::NotFound(_) => StatusCode::NOT_FOUND,
        ControlError::Refused(_) => StatusCode::CONFLICT,
        ControlError::Failed(_) => StatusCode::BAD_GATEWAY,
    };
    refused(status, e)
}

async fn props(State(app): State<Shared>, Query(op): Query<OperationRef>) -> Response {
    let Some(control) = app.live_control() else {
        return refused(
            StatusCode::NOT_FOUND,
            "this monitor asks no live operation (a replay shows the recorded choices)",
        );
    };
    match control.properties(op).await {
        Ok(props) => json_of(&props),
        Err(e) => control_error(e),
    }
}

async fn fault(State(app): State<Shared>, Json(request): Json<FaultRequest>) -> Response {
    let Some(control) = app.live_control() else {
        return refused(
            StatusCode::NOT_FOUND,
            "a replay has no run to inject faults into",
        );
    };
    if !app.allow_faults {
        return refused(
            StatusCode::FORBIDDEN,
            "faults from the page are off: start the monitor with --allow-faults",
        );
    }
    if !request.fits() {
        return refused(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("a {} fault does not aim at that", request.fault),
        );
    }
    tracing::warn!(?request, "fault asked from the monitor's page");
    match control.fault(request).await {
        Ok(done) => json_of(&serde_json::json!({ "done": done })),
        Err(e) => control_error(e),
    }
}

async fn replicas(State(app): State<Shared>, Json(request): Json<ReplicaRequest>) -> Response {
    let Some(control) = app.live_control() else {
        return refused(
            StatusCode::NOT_FOUND,
            "a replay has no cluster whose replicas could change",
        );
    };
    if !app.allow_changes {
        return refused(
            StatusCode::FORBIDDEN,
            "changes from the page are off: start the monitor with --allow-changes",
        );
    }
    if let Some(why) = request.unfit() {
        return refused(StatusCode::UNPROCESSABLE_ENTITY, why);
    }
    tracing::warn!(?request, "replica change asked from the monitor's page");
    match control.replicas(request).await {
        Ok(done) => json_of(&serde_json::json!({ "done": done })),
        Err(e) => control_error(e),
    }
}

async fn state(State(app): State<Shared>) -> Response {
    match &app.source {
        Source::Live(live) => json_body(live.snapshot().to_string()),
        Source::Replay(replay) => json_body(replay.final_json().to_string()),
    }
}

async fn live_events(State(app): State<Shared>) -> Response {
    match &app.source {
        Source::Live(live) => live.clone().viewer().into_response(),
        Source::Replay(_) => not_here("a replay has no live stream: ask /api/replay/state?at_ms=T"),
    }
}

async fn replay_info(State(app): State<Shared>) -> Response {
    match &app.source {
        Source::Replay(replay) => json_of(&replay.info()),
        Source::Live(_) => not_here("a live monitor replays nothing: see /api/live"),
    }
}

/// `?at_ms=T`.
#[derive(Deserialize)]
struct At {
    at_ms: u64,
}

async fn replay_state(State(app): State<Shared>, Query(at): Query<At>) -> Response {
    match &app.source {
        Source::Replay(replay) => {
            let replay = replay.clone();
            // applying events is CPU work: off the serving task
            match tokio::task::spawn_blocking(move || replay.state_json_at(at.at_ms)).await {
                Ok(state) => json_body(state),
                Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
            }
        }
        Source::Live(_) => not_here("a live monitor replays nothing: see /api/live"),
    }
}

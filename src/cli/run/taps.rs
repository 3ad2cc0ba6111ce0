//! Everything that follows a run's events while it runs, each a subscriber of the node's
//! bus: the live lines, the `--events` and `--mcap` files, the `--monitor` page, and for a
//! member of a cluster the relays — the cluster's news onto the bus, this member's events
//! to whoever watches the cluster, the other nodes' events into each file.

use super::page::LivePage;
use super::plan::{Outputs, Plan};
use crate::cli::events_file::EventsFile;
use crate::cli::mcap::{McapFile, Written};
use crate::cli::output::LiveLines;
use anyhow::Context;
use marie::cluster::net::Transport;
use marie::cluster::relay::Watch;
use marie::events::EventBus;
use tokio::task::JoinHandle;

/// Events of the other nodes a `run --join --events` keeps while its file writer is behind.
const EVENTS_FROM_OTHERS: usize = 4096;

/// The followers of a run's events, started before it runs.
pub(super) struct Taps {
    /// The cluster's news onto the bus, this member's events to the cluster's watchers.
    relays: Relays,
    lines: LiveLines,
    files: Files,
    page: Option<LivePage>,
}

/// The tasks that carry events between this member and the cluster.
pub(super) struct Relays(Vec<JoinHandle<()>>);

/// The files being written as the run goes.
struct Files {
    events: Option<EventsFile>,
    mcap: Option<McapFile>,
}

/// How the writing of the files ended: `None` for a file not asked for.
pub(super) struct FilesWritten {
    /// `--events`.
    pub(super) events: Option<anyhow::Result<()>>,
    /// `--mcap`.
    pub(super) mcap: Option<anyhow::Result<Written>>,
}

impl Taps {
    /// Start following `bus`, the bus of the node that runs the plan's mission `mission`
    /// (by name, for the page), a member of the cluster over `transport` if any.
    pub(super) async fn start(
        plan: &Plan,
        bus: &EventBus,
        transport: Option<&Transport>,
        mission: &str,
    ) -> anyhow::Result<Taps> {
        // the cluster's news (nodes up, lost, down) join the run's events
        let publisher = transport.map(|t| marie::cluster::net::publish_on(t, bus.clone()));
        // the live lines subscribe to the node's bus, as the events file and the monitor do
        let lines = LiveLines::start(bus, plan.progress);
        // this member's events go to whoever watches the cluster; its events file has theirs
        let forwarder =
            transport.map(|t| marie::cluster::relay::forward(bus.clone(), t.agreement()));
        let relays = Relays(publisher.into_iter().chain(forwarder).collect());
        let files = Files::start(
            &plan.outputs,
            bus,
            transport.is_some(),
            plan.dispatched_elsewhere(),
        )
        .await?;
        let page = match &plan.monitor {
            Some(asked) => Some(
                LivePage::start(
                    asked,
                    bus,
                    transport.is_some(),
                    plan.dispatched_elsewhere(),
                    mission,
                    plan.says(),
                )
                .await?,
            ),
            None => None,
        };
        Ok(Taps {
            relays,
            lines,
            files,
            page,
        })
    }

    /// The lines and the files take what was published before this call and end; the relays
    /// and the page go on (the relays until the node has stopped, the page for as long as it
    /// is read).
    pub(super) async fn finish(self) -> (FilesWritten, Relays, Option<LivePage>) {
        self.lines.finish().await;
        let written = self.files.finish().await;
        (written, self.relays, self.page)
    }
}

impl Relays {
    /// Stop relaying.
    pub(super) fn stop(self) {
        for task in self.0 {
            task.abort();
        }
    }
}

impl Files {
    /// Create the files `outputs` asks for and start writing `bus` into them — and, for a
    /// member of a cluster, the other nodes' events (a watch each; without the dispatcher's
    /// when the run is dispatched elsewhere: those come to this bus).
    async fn start(
        outputs: &Outputs,
        bus: &EventBus,
        in_cluster: bool,
        dispatched_elsewhere: bool,
    ) -> anyhow::Result<Files> {
        // one watcher for both files: the nodes reach each watcher at a moment of their
        // own, and two would each miss different early events (the files then disagree)
        let asked = usize::from(outputs.events.is_some()) + usize::from(outputs.mcap.is_some());
        let mut others: Vec<Option<Watch>> = match in_cluster && asked > 0 {
            true => marie::cluster::relay::watch_each(EVENTS_FROM_OTHERS, asked)
                .await?
                .into_iter()
                .map(|watch| match dispatched_elsewhere {
                    true => Some(watch.without_dispatch()),
                    false => Some(watch),
                })
                .collect(),
            false => Vec::new(),
        };
        let mut next = || others.pop().flatten();
        let events = match &outputs.events {
            Some(p) => Some(
                EventsFile::start(bus, next(), p)
                    .with_context(|| format!("cannot write the events to {}", p.display()))?,
            ),
            None => None,
        };
        let mcap = match &outputs.mcap {
            Some(p) => Some(McapFile::start(bus, next(), p)?),
            None => None,
        };
        Ok(Files { events, mcap })
    }

    /// Write what was published before this call and close the files.
    async fn finish(self) -> FilesWritten {
        let events = match self.events {
            Some(file) => Some(file.finish().await),
            None => None,
        };
        let mcap = match self.mcap {
            Some(file) => Some(file.finish().await),
            None => None,
        };
        FilesWritten { events, mcap }
    }
}

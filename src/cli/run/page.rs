//! `marie run --monitor`: the run's live page — served from before the mission starts, and
//! after it for as long as the user reads it, until Ctrl-C.

use super::plan::MonitorPlan;
use super::MissionOver;
use crate::cli::netns::PrivateNet;
use crate::cli::page_control::PageControl;
use marie::events::EventBus;
use marie_monitor::MonitorHandle;
use std::time::Duration;
use tokio::task::JoinHandle;

/// How long the end of a run waits for its monitor to take the run's last events.
const MONITOR_FLUSH: Duration = Duration::from_secs(5);

/// A run's page being served.
pub(super) struct LivePage {
    monitor: MonitorHandle,
    /// The other nodes' events fed to it, for a member of a cluster.
    relay: Option<JoinHandle<()>>,
    /// Whether the run's lines go to stdout (else its own lines go to stderr).
    says: bool,
}

impl LivePage {
    /// Serve the page of `bus`'s run of `mission` (and the other nodes' events, `in_cluster`)
    /// and print where it is.
    pub(super) async fn start(
        asked: &MonitorPlan,
        bus: &EventBus,
        in_cluster: bool,
        dispatched_elsewhere: bool,
        mission: &str,
        says: bool,
    ) -> anyhow::Result<LivePage> {
        let control = PageControl::new(bus.clone(), asked.processes.clone());
        let options = PrivateNet::monitor_options(asked.listen)
            .with_control(control, asked.allow_faults)
            .allowing_changes(asked.allow_changes);
        let (monitor, relay) =
            crate::cli::monitor::start_live(bus, options, in_cluster, dispatched_elsewhere).await?;
        let what = format!("mission `{mission}`");
        if says {
            crate::cli::monitor::announce(&monitor, &what);
        } else {
            // `--explain --json`: stdout holds the choices alone
            eprintln!("monitor: {} ({what})", monitor.url());
        }
        Ok(LivePage {
            monitor,
            relay,
            says,
        })
    }

    /// The run is over and its outputs written: keep the page up, with the run's last
    /// events, until Ctrl-C — `mission_over` set once the run hears it.
    pub(super) async fn linger(self, mission_over: &MissionOver) {
        let LivePage {
            monitor,
            relay,
            says,
        } = self;
        // the page must hold the run's last events (the outcome) once the line says so
        if !monitor.flush(MONITOR_FLUSH) {
            tracing::warn!(
                "the monitor had not taken the run's last events within {MONITOR_FLUSH:?}"
            );
        }
        // watched before the line: a Ctrl-C right after it is not missed (under `marie up`,
        // watched since before the run: nor is one that came before the line)
        let stop = mission_over.ctrl_c();
        mission_over.set();
        let over = "monitor: the run is over; its page stays up until Ctrl-C";
        if says {
            println!("{over}");
            let _ = std::io::Write::flush(&mut std::io::stdout());
        } else {
            eprintln!("{over}");
        }
        let signal = stop.wait().await;
        if says {
            println!("monitor stopped ({signal})");
        }
        if let Some(relay) = relay {
            relay.abort();
        }
        monitor.stop();
    }
}

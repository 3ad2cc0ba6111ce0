//! `marie dm probe DM --join ADDR --cookie C`: write numbered records into a running
//! cluster's datamanager and read them back, by name and from each replica, until Ctrl-C
//! (or `--for SECS`), saying every 10 s how it goes, then the verdict: reads answered,
//! refused and unanswered per road, stale reads (each described) and whether the newest
//! acknowledged write was read back ([`marie::dm::probe`]). Exit 0 when nothing was wrong,
//! 1 when a read was stale or the newest write missing. What `marie up --probe DM` runs
//! beside its runs (one child, `--json --stop-with-stdin`).

use super::error::BadInput;
use super::join::{join, member_name, JoinArgs};
use super::signal::shutdown_signal;
use marie::dm::probe::{Probe, ProbeConfig};
use std::process::ExitCode;
use std::time::Duration;

/// How often a probe says how it goes.
const PROGRESS: Duration = Duration::from_secs(10);

/// The flags of `marie dm probe`.
#[derive(clap::Args, Debug)]
pub(crate) struct ProbeArgs {
    /// The datamanager (its name, e.g. `feature`).
    pub dm: String,
    /// `--join ADDR --cookie C` (required): the running cluster.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// Stop after this many seconds (default: at Ctrl-C or SIGTERM).
    #[arg(long = "for", value_name = "SECS", value_parser = clap::value_parser!(u64).range(1..=604_800))]
    pub for_secs: Option<u64>,
    /// Print the verdict as one line of JSON (the progress lines go to stderr).
    #[arg(long)]
    pub json: bool,
    /// Stop, as on SIGTERM, when standard input closes (what `marie up --probe` gives it).
    #[arg(long)]
    pub stop_with_stdin: bool,
}

/// Run the probe.
pub(crate) async fn probe(args: ProbeArgs) -> anyhow::Result<ExitCode> {
    let Some(target) = args.cluster.target() else {
        return Err(BadInput(
            "marie dm probe acts on a running cluster: give --join ADDR --cookie C".into(),
        )
        .into());
    };
    // watched before anything is said, so that a signal right after the first line stops it
    let stop = shutdown_signal(args.stop_with_stdin);
    let transport = join(&member_name("probe"), &target).await?;
    let config = ProbeConfig::new(&args.dm);
    let probe = match Probe::start(config.clone()).await {
        Ok(p) => p,
        Err(e) => {
            transport.stop().await;
            return Err(BadInput(format!(
                "marie dm probe {}: no leader of it found within {:?} ({e}); `marie ls --join …` lists the datamanagers",
                args.dm, config.patience
            ))
            .into());
        }
    };
    eprintln!(
        "probing {}: a write every {:?}, a read per road every {:?}; {}",
        args.dm,
        config.write_pause,
        config.read_pause,
        match args.for_secs {
            Some(s) => format!("for {s} s"),
            None => "until Ctrl-C".to_string(),
        }
    );
    let until = async {
        match args.for_secs {
            Some(s) => tokio::time::sleep(Duration::from_secs(s)).await,
            None => std::future::pending().await,
        }
    };
    tokio::pin!(stop, until);
    let mut every = tokio::time::interval_at(tokio::time::Instant::now() + PROGRESS, PROGRESS);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = &mut until => break,
            _ = every.tick() => eprintln!("{}", probe.tally()),
        }
    }
    let verdict = probe.stop().await;
    transport.stop().await;
    match args.json {
        true => println!("{}", serde_json::to_string(&verdict)?),
        false => {
            println!("{verdict}");
            for stale in &verdict.stale_reads {
                println!("  stale: {stale}");
            }
        }
    }
    Ok(match verdict.holds() {
        true => ExitCode::SUCCESS,
        false => ExitCode::from(1),
    })
}

//! marie's end-to-end tests, one binary: every `tests/*.rs` is a module of it, and
//! `tests/common/` what they share (a cluster's processes, the monitor's page, a headless
//! Chromium, network namespaces, the acceptance's schedules, the soak's reading).
//!
//! Why one binary: each test file used to be a binary of its own — one link each, and
//! `cargo test` ran them one after another, each waiting for its longest test before the
//! next began. Run one file's tests with `cargo test --test e2e takeover::`, one test by
//! its name.
//!
//! Every test starts real `marie` processes (`CARGO_BIN_EXE_marie`) and kills them by
//! their pids when it ends, also on panic; none shares a process, a port or a directory
//! with another, so they run side by side on the test threads.

mod common;

mod acceptance;
mod bad_input;
mod browser;
mod cli;
mod cluster;
mod cluster_failover;
mod compat;
mod data_dir;
mod diff;
mod dm_backpressure;
mod dm_checker;
mod dm_failover;
mod dm_membership;
mod dm_replicas;
mod dm_strength;
mod events_file;
mod examples;
mod export;
mod failure_detector;
mod frozen_node_events;
mod layers;
mod monitor;
mod monitor_browser;
mod monitor_faults;
mod node_faults;
mod nodes;
mod partition;
mod probe;
mod protocol_range;
mod provenance;
mod recovery;
mod replay;
mod robot;
mod selection;
mod selection_cluster;
mod self_healing;
mod soak;
mod speed;
mod takeover;
mod tls;
mod two_builds;
mod up;
mod upgrade_cluster;

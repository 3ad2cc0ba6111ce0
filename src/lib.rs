//! # marie
//!
//! An actor framework for robot control with supervision and self-healing: the control
//! architecture of the MARIE mobile robot (elementary operations, datamanagers, an action
//! dispatcher, a location table) re-created as [ractor] actors.
//!
//! This crate is the facade: it re-exports the member crates — the node is
//! [`cluster::node`] ([`node`] here too), the robot [`missions`] — and offers
//! [`embedded::Embedded`], the single-process node the `marie` command runs.
//!
//! ```no_run
//! use marie::node::{Node, NodeConfig, NodeOptions};
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let catalog = marie::missions::catalog();
//! let config = NodeConfig::everything("solo", &catalog);
//! let node = Node::start(config, NodeOptions::with_catalog(catalog)).await?;
//! let mission = node.load_mission(std::path::Path::new("missions/demo.toml")).await?;
//! let report = node.run(mission).await?;
//! println!("{:?}", report.outcome);
//! node.shutdown().await;
//! # Ok(()) }
//! ```

#![warn(missing_docs)]

pub use marie_actors as actors;
pub use marie_cluster as cluster;
pub use marie_missions as missions;
pub use marie_supervision as supervision;

pub use marie_cluster::{fault, layout, net, node, relay};

/// Everything an operation author needs in one import: `use marie::prelude::*;` (see
/// [`actors::prelude`]).
pub use marie_actors::prelude;

pub mod embedded;

//! The wall follower, version 1.2 (`1.2.0-rc.1`): the next build's (feature
//! `next-protocol`), made to prove an upgrade across two real builds — a node restarted
//! with the next build hosts it, and a binding on version 1 moves to it at an action's start.
//!
//! Version 1.1's parameters, migrations and behaviour: a newer compatible version, no more. What differs
//! is the build it comes in: it reads the followed wall's record of its own build, which has
//! a field the build before lacks ([`WallRecord`](crate::ops::WallRecord)'s `seen_among`),
//! from a datamanager that holds the records of both builds — those of the build before
//! without it, which it reads as absent.
//!
//! A release candidate, like version 1.1: hosted only where a node names it exactly
//! (`version = "=1.2.0-rc.1"`).

use super::{WallFollowerV1_1, CONTROL_PERIOD};
use marie_actors::declare::Migrations;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_vocabulary::property::ParamSchema;
use std::time::Duration;

/// The wall follower's version in the next build.
pub const NEXT_VERSION: &str = "1.2.0-rc.1";

/// The wall follower, version 1.2 (`1.2.0-rc.1`), of the next build: version 1.1 under a
/// newer version (its parameters, migrations and behaviour, by delegation); see the module.
#[derive(Debug, Default)]
pub struct WallFollowerV1_2 {
    v1_1: WallFollowerV1_1,
}

impl Operation for WallFollowerV1_2 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            NEXT_VERSION,
            "follows a wall at a distance, at a chosen speed (the next build's)",
        )
    }

    fn parameters(&self) -> ParamSchema {
        self.v1_1.parameters()
    }

    fn migrations(&self) -> Migrations {
        self.v1_1.migrations()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.v1_1.step(ctx).await
    }

    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        self.v1_1.activate(ctx).await
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.v1_1.suspend(ctx).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_is_a_newer_compatible_version_of_the_wall_follower() {
        let next = WallFollowerV1_2::default().identity();
        let before = super::super::WallFollowerV1_1::default().identity();
        assert_eq!(
            (next.name.as_str(), next.id),
            (before.name.as_str(), before.id)
        );
        assert!(next.version > before.version && next.version.major == before.version.major);
        assert_eq!(next.version.to_string(), NEXT_VERSION);
    }
}

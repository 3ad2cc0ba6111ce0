//! The wall follower, version 1.2 (`1.2.0-rc.1`): the next build's (feature
//! `next-protocol`), made to prove an upgrade across two real builds — a node restarted
//! with the next build hosts it, and a binding on version 1 moves to it at an action's start.
//!
//! Version 1.1's parameters and behaviour: a newer compatible version, no more. What differs
//! is the build it comes in: it reads the followed wall's record of its own build, which has
//! a field the build before lacks ([`WallRecord`](crate::ops::WallRecord)'s `seen_among`),
//! from a datamanager that holds the records of both builds — those of the build before
//! without it, which it reads as absent.
//!
//! A release candidate, like version 1.1: hosted only where a node names it exactly
//! (`version = "=1.2.0-rc.1"`).

use super::{follow_params, FollowMode, Follower, WallFollowerV1_1Params, CONTROL_PERIOD};
use marie_actors::declare::DeclaredParams;
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_vocabulary::property::ParamSchema;
use std::time::Duration;

/// The wall follower's version in the next build.
pub const NEXT_VERSION: &str = "1.2.0-rc.1";

/// The wall follower, version 1.2 (`1.2.0-rc.1`), of the next build: see the module.
#[derive(Debug, Default)]
pub struct WallFollowerV1_2 {
    follower: Follower,
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
        WallFollowerV1_1Params::schema()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let WallFollowerV1_1Params { distance, speed } = ctx.params().read()?;
        let params = follow_params(distance, FollowMode::Wall, speed);
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
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

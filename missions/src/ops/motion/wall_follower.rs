//! The wall follower (1514), versions 1, 1.1 and 2: the cart kept at a distance from the
//! followed wall (version 2 also along a corridor's middle), with a stall check. The next
//! build (feature `next-protocol`) adds version 1.2 (`wall_follower/next.rs`).

#[cfg(feature = "next-protocol")]
pub(crate) mod next;

use super::follow::{follow_params, follow_step};
use super::{stop_cart, CONTROL_PERIOD};
use crate::algo::follow::{FollowMode, FollowParams};
use crate::geom::Pose;
use crate::hardware::CartClient;
use marie_actors::declare::{DeclaredParams, Migrations};
use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
use marie_vocabulary::property::ParamSchema;
use std::time::Duration;

/// How long a wall follower may see the cart make no progress before it gives up: something
/// (an obstacle, the collision avoidance's stop) keeps it from following the wall.
const STALL_TIME: Duration = Duration::from_secs(15);

/// How far the cart must move to count as progress, m.
const STALL_DISTANCE: f64 = 0.1;

/// What both wall followers do with the cart: a follow step and a stall check per control
/// step, stop on suspension.
#[derive(Debug, Default)]
struct Follower {
    cart: Option<CartClient>,
    stall: Stall,
}

impl Follower {
    /// A new activation: the stall check starts afresh.
    fn activate(&mut self) -> Result<Step, OpError> {
        self.stall = Stall::default();
        Ok(Step::Continue)
    }

    async fn step(&mut self, ctx: &mut OpContext, params: &FollowParams) -> Result<Step, OpError> {
        let (_, pose) = follow_step(ctx, &mut self.cart, params).await?;
        self.stall.check(pose, ctx.now())?;
        Ok(Step::Continue)
    }

    fn suspend(&mut self, ctx: &OpContext) -> Result<(), OpError> {
        stop_cart(&mut self.cart, ctx)
    }
}

/// Watches that a follower's cart keeps moving.
#[derive(Debug, Default)]
struct Stall {
    /// Where and when the cart last made progress.
    anchor: Option<(Pose, Duration)>,
}

impl Stall {
    /// Record the cart at `pose` at `now`; an error once it has not moved for [`STALL_TIME`].
    fn check(&mut self, pose: Pose, now: Duration) -> Result<(), OpError> {
        match self.anchor {
            Some((at, since)) if (pose.point() - at.point()).norm() < STALL_DISTANCE => {
                if now.saturating_sub(since) >= STALL_TIME {
                    return Err(OpError::failed(format!(
                        "the cart has made no progress along the wall for {:.0} s, blocked at ({:.2}, {:.2})",
                        STALL_TIME.as_secs_f64(),
                        pose.x,
                        pose.y
                    )));
                }
            }
            _ => self.anchor = Some((pose, now)),
        }
        Ok(())
    }
}

marie_actors::params! {
    /// The parameters of the wall follower, version 1.
    pub struct WallFollowerV1Params {
        /// distance kept from the wall
        pub distance: f64 = 0.6, range(0.3, 3.0), unit("m");
    }
}

/// The wall follower, version 1: keeps the cart at `distance` from the followed wall, driving
/// forwards, until suspended. One parameter.
#[derive(Debug, Default)]
pub struct WallFollowerV1 {
    follower: Follower,
}

/// Forward speed of the wall followers.
const FOLLOW_SPEED: f64 = 0.3;

impl Operation for WallFollowerV1 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            "1.0.0",
            "follows a wall at a distance",
        )
    }

    fn parameters(&self) -> ParamSchema {
        WallFollowerV1Params::schema()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let WallFollowerV1Params { distance } = ctx.params().read()?;
        let params = follow_params(distance, FollowMode::Wall, FOLLOW_SPEED);
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
    }
}

marie_actors::params! {
    /// The parameters of the wall follower, version 1.1: version 1's `distance` renamed
    /// `wall_distance` (declared as a migration) and kept within 2.5 m, and the forward
    /// speed.
    pub struct WallFollowerV1_1Params {
        /// distance kept from the wall (version 1's `distance`), at most 2.5 m: beyond it the
        /// side sonar's echo of a wall is too faint to hold a distance on
        pub wall_distance: f64 = 0.6, range(0.3, 2.5), unit("m");
        /// forward speed along the wall
        pub speed: f64 = FOLLOW_SPEED, range(0.1, 0.5), unit("m/s");
    }
}

/// The wall follower, version 1.1 (`1.1.0-rc.1`): version 1 with one more parameter, the
/// forward speed, whose default is version 1's — so a mission written for version 1 drives
/// the same with it. It is what a newer compatible build of an operation looks like: a
/// binding on version 1 moves to it at an action's start when it appears
/// (`marie_actors::dispatcher::upgrade`).
///
/// It also exercises both parameter changes a newer version may make: version 1's
/// `distance` is called `wall_distance` here, and a declared migration
/// ([`Operation::migrations`]) maps a mission's `distance` onto it; and its range is
/// narrowed to 2.5 m, so a mission asking for more is refused by `marie check` (never
/// clamped) and a binding carrying such a value does not move to it.
///
/// A release candidate on purpose: semver requirements (`version = "1"` in a node's config,
/// `*` when it names none) never match a pre-release, so it is hosted only where a node
/// names it exactly (`version = "=1.1.0-rc.1"`), and every cluster that hosted version 1
/// hosts what it did.
#[derive(Debug, Default)]
pub struct WallFollowerV1_1 {
    follower: Follower,
}

impl Operation for WallFollowerV1_1 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            "1.1.0-rc.1",
            "follows a wall at a distance, at a chosen speed",
        )
    }

    fn parameters(&self) -> ParamSchema {
        WallFollowerV1_1Params::schema()
    }

    fn migrations(&self) -> Migrations {
        Migrations::new().rename("distance", "wall_distance")
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let WallFollowerV1_1Params {
            wall_distance,
            speed,
        } = ctx.params().read()?;
        let params = follow_params(wall_distance, FollowMode::Wall, speed);
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
    }
}

marie_actors::choice! {
    /// What the wall follower, version 2, follows.
    pub enum WallFollowerMode {
        /// One wall, at a distance.
        Wall = "wall",
        /// The middle between two walls.
        Corridor = "corridor",
    }
}

marie_actors::params! {
    /// The parameters of the wall follower, version 2.
    pub struct WallFollowerV2Params {
        /// distance kept from the wall (wall mode)
        pub distance: f64 = 0.6, range(0.3, 3.0), unit("m");
        /// follow one wall, or the middle between two
        pub mode: WallFollowerMode = WallFollowerMode::Wall;
    }
}

/// The wall follower, version 2: like version 1, and it can also keep to the middle of a
/// corridor. Two parameters: same kind and id as version 1, another schema.
#[derive(Debug, Default)]
pub struct WallFollowerV2 {
    follower: Follower,
}

impl Operation for WallFollowerV2 {
    fn identity(&self) -> Identity {
        Identity::new(
            "wall-follower",
            1514,
            "2.0.0",
            "follows a wall at a distance, or a corridor's middle",
        )
    }

    fn parameters(&self) -> ParamSchema {
        WallFollowerV2Params::schema()
    }

    fn period(&self) -> Duration {
        CONTROL_PERIOD
    }

    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: WallFollowerV2Params = ctx.params().read()?;
        let mode = match p.mode {
            WallFollowerMode::Wall => FollowMode::Wall,
            WallFollowerMode::Corridor => FollowMode::Corridor,
        };
        let params = follow_params(p.distance, mode, FOLLOW_SPEED);
        self.follower.step(ctx, &params).await
    }

    async fn activate(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
        self.follower.activate()
    }

    async fn suspend(&mut self, ctx: &mut OpContext) -> Result<(), OpError> {
        self.follower.suspend(ctx)
    }
}

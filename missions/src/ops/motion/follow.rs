//! Wall following, one control step: what both wall followers and the sensor-based
//! controller drive the cart with.

use crate::algo::follow::{follow_command, is_aligned, FollowMode, FollowParams};
use crate::algo::wall::{sense_wall, WallParams};
use crate::geom::Pose;
use crate::hardware::CartClient;
use crate::ops::perception::wall_from;
use crate::ops::records::{SEGMENTS, WALL};
use crate::ops::{cart, cart_err, newest};
use marie_actors::eo::{OpContext, OpError};
use marie_dm::{FEATURE, WORLD};

/// How far the cart may run past the last seen end of the wall before the follower gives up,
/// m: more than a docking spot's breadth, which looks like the wall's end until its far side
/// is seen.
const WALL_END_MARGIN: f64 = 3.5;

/// The wall-following parameters of a follower: the defaults, but for its distance, mode and
/// speed.
pub(super) fn follow_params(distance: f64, mode: FollowMode, speed: f64) -> FollowParams {
    FollowParams {
        distance,
        mode,
        speed,
        ..FollowParams::default()
    }
}

/// One control step of wall following: reads the wall, steers the cart, and fails once the
/// cart has run past the end of the wall seen so far. Returns whether the cart is aligned,
/// and its pose.
pub(super) async fn follow_step(
    ctx: &mut OpContext,
    slot: &mut Option<CartClient>,
    params: &FollowParams,
) -> Result<(bool, Pose), OpError> {
    let status = cart(slot, ctx)?.status().await.map_err(cart_err)?;
    if status.collided {
        return Err(OpError::failed(
            "the cart collided while following the wall",
        ));
    }
    let Some(wall) = newest(ctx, WORLD, WALL).await? else {
        return Err(OpError::failed("no wall in the world DM to follow"));
    };
    let now = crate::ops::correction(ctx).await?;
    let pose = now.compose(status.odometry);
    let Some(est) = wall_from(&wall.segment_under(&now), &pose) else {
        return Err(OpError::failed("the wall record is degenerate"));
    };
    // progress along the wall, in the direction of travel
    let Some(dir) = (est.line.b - est.line.a).try_normalize(1e-9) else {
        return Err(OpError::failed("the wall record is degenerate"));
    };
    let travel = if params.speed < 0.0 { -1.0 } else { 1.0 };
    let end = if travel > 0.0 { est.line.b } else { est.line.a };
    let past_end = (pose.point() - end).dot(&(dir * travel));
    if past_end > WALL_END_MARGIN {
        return Err(OpError::failed(format!(
            "the wall ended {past_end:.1} m behind the cart at ({:.2}, {:.2})",
            end.x, end.y
        )));
    }
    let opposite = if params.mode == FollowMode::Corridor {
        newest(ctx, FEATURE, SEGMENTS).await?.and_then(|set| {
            sense_wall(
                &set.segments,
                &pose,
                &WallParams {
                    side: Some(est.side.opposite()),
                    ..WallParams::default()
                },
            )
        })
    } else {
        None
    };
    let cmd = follow_command(&est, opposite.as_ref(), params);
    cart(slot, ctx)?
        .drive(cmd.speed, cmd.steer)
        .map_err(cart_err)?;
    Ok((is_aligned(&est, opposite.as_ref(), params), pose))
}

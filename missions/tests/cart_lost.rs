//! A cart lost mid-call is told apart from one that runs and does not answer: the first is
//! [`CartError::Gone`], which an operation waits out (the cart's node cut off, its session
//! closed, the cart published again by the time the call's deadline ends), the second
//! [`CartError::Unreachable`], which fails the activation.
//! (Its own process: the cart publishes itself in the process-wide registry.)

use marie_missions::hardware::{spawn_cart, CartArgs, CartClient, CartError};
use marie_missions::sim::Simulation;
use marie_missions::world::World;
use marie_vocabulary::clock::RealClock;
use std::time::Duration;

#[tokio::test]
async fn a_stopped_carts_calls_and_commands_say_it_was_lost() {
    let world = World::builtin("lab").expect("the lab world");
    let (actor, handle) = spawn_cart(CartArgs {
        sim: Simulation::new(&world, 1),
        clock: RealClock::shared(),
        period: Duration::from_millis(20),
        poses: None,
    })
    .await
    .expect("cart");
    let cart = CartClient::new(actor.clone());
    assert!(cart.status().await.is_ok());

    actor.stop(None);
    handle.await.unwrap();
    assert_eq!(cart.status().await.unwrap_err(), CartError::Gone);
    assert_eq!(cart.scan().await.unwrap_err(), CartError::Gone);
    assert_eq!(cart.drive(0.2, 0.0).unwrap_err(), CartError::Gone);
    assert_eq!(
        CartError::Gone.to_string(),
        "the virtual cart was lost before it answered"
    );
}

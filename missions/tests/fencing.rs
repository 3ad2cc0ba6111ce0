//! The cart obeys only the newest incarnation of each operation: a command carrying an older
//! epoch than one it has obeyed for the same operation — a woken or reconnected original
//! after its stand-in took over — is refused and changes nothing.
//! (Its own process: the cart publishes itself in the process-wide registry.)

use marie_missions::hardware::{spawn_cart, CartArgs, CartClient};
use marie_missions::sim::Simulation;
use marie_missions::world::World;
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::fence::Fence;
use std::time::Duration;

fn fenced(cart: &CartClient, op: &str, epoch: u64) -> CartClient {
    let mut c = cart.clone();
    c.set_fence(Fence::new(op, epoch));
    c
}

/// A cart in the lab world, with a client that carries no fence.
async fn lab_cart() -> (
    ractor::ActorRef<marie_missions::hardware::CartMsg>,
    tokio::task::JoinHandle<()>,
    CartClient,
) {
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
    (actor, handle, cart)
}

#[tokio::test]
async fn a_replaced_incarnations_commands_are_refused_and_change_nothing() {
    let (actor, handle, cart) = lab_cart().await;
    let stand_in = fenced(&cart, "wall-follower", 8);
    let original = fenced(&cart, "wall-follower", 7);

    stand_in.drive(0.3, 0.1).unwrap();
    original.drive(-0.5, -0.2).unwrap();
    original.emergency_stop(true).unwrap();
    original.speed_cap(Some(0.0)).unwrap();
    // a call after the casts: the cart has handled them (one mailbox, in order)
    let status = cart.status().await.unwrap();
    assert_eq!(status.commanded, (0.3, 0.1));
    assert!(!status.emergency_stop);
    assert_eq!(status.speed_cap, None);
    assert_eq!(status.refused, 3);

    // another operation, and the stand-in's next epoch, are obeyed
    fenced(&cart, "collision-avoidance", 2)
        .speed_cap(Some(0.2))
        .unwrap();
    fenced(&cart, "wall-follower", 9).drive(0.1, 0.0).unwrap();
    stand_in.drive(0.4, 0.0).unwrap(); // now replaced itself
    let status = cart.status().await.unwrap();
    assert_eq!(status.commanded, (0.1, 0.0));
    assert_eq!(status.speed_cap, Some(0.2));
    assert_eq!(status.refused, 4);
    assert_eq!(
        status.refused_by.into_iter().collect::<Vec<_>>(),
        [("wall-follower".to_string(), 4)]
    );

    actor.stop(None);
    handle.await.unwrap();
}

#[tokio::test]
async fn a_halt_stops_the_cart_and_leaves_another_operations_emergency_stop_engaged() {
    let (actor, handle, cart) = lab_cart().await;
    let avoidance = fenced(&cart, "collision-avoidance", 3);
    let follower = fenced(&cart, "wall-follower", 3);
    follower.drive(0.3, 0.1).unwrap();
    avoidance.emergency_stop(true).unwrap();
    // the wall follower's clearance guard brakes while avoidance holds the cart
    follower.halt().unwrap();
    let status = cart.status().await.unwrap();
    assert_eq!(status.commanded, (0.0, 0.0));
    assert!(status.emergency_stop, "avoidance's hold was lifted");
    // a replaced incarnation's halt is refused like any command
    avoidance.emergency_stop(false).unwrap();
    follower.drive(0.2, 0.0).unwrap();
    fenced(&cart, "wall-follower", 2).halt().unwrap();
    let status = cart.status().await.unwrap();
    assert_eq!(status.commanded, (0.2, 0.0));
    assert_eq!(status.refused, 1);
    actor.stop(None);
    handle.await.unwrap();
}

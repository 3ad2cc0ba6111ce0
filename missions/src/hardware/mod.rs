//! Virtual hardware as actors: the cart (drive, steering, emergency stop, odometry, ultrasonic
//! sensors) over the [`crate::sim`] simulation.
//!
//! Hardware-bound modules stay on the robot's node (thesis 8.7.1); operations find them in the
//! registry under [`ModuleKind::Hardware`](marie_vocabulary::registry::ModuleKind::Hardware) and
//! talk to them with [`CartClient`].

mod cart;

pub use cart::{
    spawn_cart, spawn_cart_linked, CartArgs, CartClient, CartError, CartMsg, CartStatus, SonarScan,
    VirtualCart, CART_ID, CART_NAME,
};

//! Worlds: the walls the simulated cart drives between, its start pose and footprint, its
//! sonar ring, and the goal area that judges a run.
//!
//! A world is a TOML file (`missions/worlds/*.toml`), loaded by [`World::load`] or
//! [`World::parse`] into a checked [`World`]. Every problem — a syntax error, an unknown key
//! (the message lists the accepted ones), a wrong type, a value out of range, a start pose that
//! touches a wall, a goal outside the walls — is a [`Diagnostic`] at its `file:line:column`.
//!
//! # Format
//!
//! All lengths are metres, all angles degrees (counter-clockwise; 0° = +x). Frames: the world
//! frame is the file's x/y; the cart frame has its origin at the **centre of the rear axle**,
//! x forward, y to the left (see [`CartSpec`]).
//!
//! | table | key | meaning |
//! |---|---|---|
//! | `[world]` | `name` (required), `description` | |
//! | `[[wall]]` (one or more) | `points = [[x, y], ...]` | an open polyline, ≥ 2 points |
//! | `[[obstacle]]` | `points = [[x, y], ...]` | a closed polygon, ≥ 3 points |
//! | `[cart]` (required) | `start = { x, y, heading_deg }` | start pose of the rear-axle centre |
//! | | `length` 1.0, `width` 0.6, `wheelbase` 0.7 | footprint and axles |
//! | | `rear_overhang` (length − wheelbase) / 2 | footprint behind the rear axle |
//! | | `max_speed` 0.5, `max_steer_deg` 35, `max_steer_rate_deg` 90 | limits |
//! | | `speed_time_constant` 0.2 | first-order lag of the drive, seconds |
//! | `[[sonar]]` | `x`, `y`, `angle_deg`, `beam = "narrow" \| "wide"`, `range` (4 / 3) | a sensor in the cart frame; none listed: [`SonarMount::default_ring`] |
//! | `[goal]` | `center = { x, y }`, `length`, `width`, `heading_deg` 0 | the rectangle the whole footprint must end in; `length` runs along `heading_deg` |
//! | | `heading_tolerance_deg` 10, `either_way` false | heading the cart must end with; `either_way`: modulo 180° |
//! | `[dock]` | `opening = [[x, y], [x, y]]`, `breadth`, `depth` | ground truth: the recess lies left of the opening's first → second point |
//! | `[sim]` | `sonar_sigma` 0.01, `sonar_dropout` 0.01, `incidence_limit_deg` 65, `rays_per_beam` 7, `narrow_half_angle_deg` 8, `wide_half_angle_deg` 25, `odometry_distance_sigma` 0.01, `odometry_heading_sigma_deg` 0.5, `odometry_heading_walk_deg` 0.1 | sensor and odometry model ([`SimSettings`]); odometry errors are 1σ: a distance scale error (fraction of the distance) and a heading drift rate (degrees per metre driven), both drawn once per run from the seed, and a heading random walk (degrees per √metre); 0 turns one off |
//!
//! A world without `[goal]` can never be judged a success (the `nodock` world).
//!
//! # The docking spot
//!
//! The thesis' lab had a docking spot of 80 cm by 280 cm, made of wooden segments along a
//! wall. Here it is a **recess in the wall, 2.80 m along the wall (breadth) and 0.80 m deep**:
//! the 1.0 m × 0.6 m cart parks in it parallel to the wall, as a car parks in a bay along the
//! kerb, with 0.1 m to spare on each side and 1.8 m lengthwise. This is the reading that fits
//! the mission (follow the wall until the spot, park in it) and the cart (0.8 m would not hold
//! it lengthwise). The goal area is the recess itself, with `either_way = true`.
//!
//! # Example
//!
//! ```
//! use marie_missions::world::World;
//!
//! let src = r#"
//! [world]
//! name = "bay"
//! description = "one wall with a docking recess"
//!
//! [[wall]]
//! points = [[0, 0], [4, 0], [4, -0.8], [6.8, -0.8], [6.8, 0], [10, 0]]
//!
//! [cart]
//! start = { x = 8.5, y = 1.5, heading_deg = 180 }
//!
//! [goal]
//! center = { x = 5.4, y = -0.4 }
//! length = 2.8
//! width = 0.8
//! either_way = true
//!
//! [dock]
//! opening = [[6.8, 0], [4, 0]]
//! breadth = 2.8
//! depth = 0.8
//! "#;
//! let world = World::parse(src, None).unwrap();
//! assert_eq!(world.sonars.len(), 10); // the default ring
//! let parked = marie_missions::geom::Pose::new(4.9, -0.4, 0.0);
//! assert!(world.judge(parked, 0).success);
//!
//! let bad = World::parse("[world]\nname = \"x\"\ncolour = 3\n", None).unwrap_err();
//! assert!(bad.to_string().contains("<world>:3:1: unknown key `colour` in [world]"));
//! ```
//!
//! [`Diagnostic`]: marie_vocabulary::diagnostic::Diagnostic

mod load;
mod model;

pub use model::{
    Beam, CartSpec, Dock, GoalArea, Judgement, RayHit, Rect, SimSettings, SonarMount, World,
    WorldGeometry, DEFAULT_ODOMETRY_DISTANCE_SIGMA, DEFAULT_ODOMETRY_HEADING_SIGMA_DEG,
    DEFAULT_ODOMETRY_HEADING_WALK_DEG,
};

use marie_vocabulary::diagnostic::{Diagnostic, Diagnostics};
use std::path::{Path, PathBuf};

/// The worlds shipped in `missions/worlds/`, by name, with their text.
const BUILTIN: &[(&str, &str)] = &[
    ("lab", include_str!("../../worlds/lab.toml")),
    ("corridor", include_str!("../../worlds/corridor.toml")),
    ("lshape", include_str!("../../worlds/lshape.toml")),
    ("corner", include_str!("../../worlds/corner.toml")),
    ("nodock", include_str!("../../worlds/nodock.toml")),
    ("deadend", include_str!("../../worlds/deadend.toml")),
];

/// The names of the shipped worlds (`lab`, `corridor`, `lshape`, `corner`, `nodock`,
/// `deadend`).
pub fn builtin_names() -> Vec<&'static str> {
    BUILTIN.iter().map(|(n, _)| *n).collect()
}

/// The directory holding the shipped world files (`missions/worlds` in the source tree).
pub fn worlds_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds")
}

impl World {
    /// Read, parse and check a world file.
    pub fn load(path: impl AsRef<Path>) -> Result<World, Diagnostics> {
        load::load(path.as_ref())
    }

    /// Parse and check world text. `path` names the text in diagnostics (`<world>` without
    /// one).
    pub fn parse(src: &str, path: Option<&Path>) -> Result<World, Diagnostics> {
        load::parse(src, path)
    }

    /// A shipped world by name (see [`builtin_names`]), compiled into the binary. An unknown
    /// name is one diagnostic listing the known ones.
    pub fn builtin(name: &str) -> Result<World, Diagnostics> {
        match BUILTIN.iter().find(|(n, _)| *n == name) {
            Some((n, src)) => {
                let path = PathBuf::from(format!("missions/worlds/{n}.toml"));
                World::parse(src, Some(&path))
            }
            None => Err(Diagnostic::new(
                "<builtin>",
                1,
                1,
                format!(
                    "unknown world `{}` (expected one of: {})",
                    name.escape_debug(),
                    builtin_names().join(", ")
                ),
            )
            .into()),
        }
    }
}

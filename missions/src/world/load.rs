//! World files: TOML text → a validated [`World`], every problem reported at its
//! `file:line:column`.
//!
//! The text is parsed by toml's span-keeping parser ([`DeTable`]) and walked by hand, so one
//! pass reports every unknown key, wrong type and bad value. Checks that need several parts of
//! the world (the start pose against the walls, the goal against the bounds) run only when
//! the parts themselves are sound, so one mistake does not cascade.

use super::model::{Beam, CartSpec, Dock, GoalArea, Rect, SimSettings, SonarMount, World};
use crate::geom::{Point, Pose};
use marie_vocabulary::diagnostic::toml::{literal, Reader, Rule, Span, Tbl, Val};
use marie_vocabulary::diagnostic::{read_source, Diagnostics};
use std::path::Path;
use toml::de::DeValue;

const TOP_KEYS: &[&str] = &[
    "world", "wall", "obstacle", "cart", "sonar", "goal", "dock", "sim",
];
const WORLD_KEYS: &[&str] = &["name", "description"];
const POINTS_KEYS: &[&str] = &["points"];
const CART_KEYS: &[&str] = &[
    "start",
    "length",
    "width",
    "wheelbase",
    "rear_overhang",
    "max_speed",
    "max_steer_deg",
    "max_steer_rate_deg",
    "speed_time_constant",
];
const START_KEYS: &[&str] = &["x", "y", "heading_deg"];
const XY_KEYS: &[&str] = &["x", "y"];
const SONAR_KEYS: &[&str] = &["x", "y", "angle_deg", "beam", "range"];
const GOAL_KEYS: &[&str] = &[
    "center",
    "length",
    "width",
    "heading_deg",
    "heading_tolerance_deg",
    "either_way",
];
const DOCK_KEYS: &[&str] = &["opening", "breadth", "depth"];
const SIM_KEYS: &[&str] = &[
    "sonar_sigma",
    "sonar_dropout",
    "incidence_limit_deg",
    "rays_per_beam",
    "narrow_half_angle_deg",
    "wide_half_angle_deg",
    "odometry_distance_sigma",
    "odometry_heading_sigma_deg",
    "odometry_heading_walk_deg",
];

/// Largest coordinate magnitude, metres: a world is at most 2 km across (the simulation's
/// grid planner and pictures are sized by it, so a typo like `1e300` must not reach them).
const MAX_COORD: f64 = 1000.0;
/// Coordinates: within ±[`MAX_COORD`].
const COORD: Rule = Rule::Within(-MAX_COORD, MAX_COORD);
/// Headings in degrees: one turn either way.
const HEADING: Rule = Rule::Within(-360.0, 360.0);
/// A part of the cart (length, width, wheelbase), metres.
const CART_SIZE: Rule = Rule::AboveUpTo(0.0, 10.0);

/// Shortest wall or obstacle edge, metres.
const MIN_EDGE: f64 = 1e-3;
/// How far a dock's `breadth` may differ from its opening's length, metres.
const DOCK_BREADTH_TOLERANCE: f64 = 0.01;

/// The name a path is shown under in diagnostics (`<world>` without one).
pub(crate) fn display_path(path: Option<&Path>) -> String {
    path.map_or_else(|| "<world>".to_string(), |p| p.display().to_string())
}

/// Read and parse a world file (refused unread when it is not a regular file or is huge).
pub(crate) fn load(path: &Path) -> Result<World, Diagnostics> {
    let src = read_source(path, "world")?;
    parse(&src, Some(path))
}

/// A point written `[x, y]`.
fn xy(ctx: &mut Reader<'_>, v: &Val<'_>, field: &str) -> Option<Point> {
    let items = ctx.array(v, format_args!("a point `[x, y]` in `{field}`"))?;
    if items.len() != 2 {
        ctx.err(
            &v.span(),
            format!(
                "expected a point `[x, y]` in `{field}`, found {} number(s)",
                items.len()
            ),
        );
        return None;
    }
    let x = coordinate(ctx, &items[0], field);
    let y = coordinate(ctx, &items[1], field);
    Some(Point::new(x?, y?))
}

/// A coordinate within ±[`MAX_COORD`], or a diagnostic.
fn coordinate(ctx: &mut Reader<'_>, v: &Val<'_>, field: &str) -> Option<f64> {
    let x = ctx.number(v, field)?;
    if let Err(want) = COORD.check(x) {
        ctx.err(
            &v.span(),
            format!(
                "coordinates in `{field}` must be {want} metres, found {}",
                literal(v)
            ),
        );
        return None;
    }
    Some(x)
}

/// A point written `{ x = .., y = .. }` (or `[x, y]`).
fn point(ctx: &mut Reader<'_>, v: &Val<'_>, field: &str) -> Option<Point> {
    if let DeValue::Array(_) = v.get_ref() {
        return xy(ctx, v, field);
    }
    let tbl = ctx.table(v, &format!("`{field}` (a point `{{ x = .., y = .. }}`)"))?;
    ctx.unknown_keys(&tbl, XY_KEYS);
    let x = ctx.num(&tbl, "x", None, COORD);
    let y = ctx.num(&tbl, "y", None, COORD);
    Some(Point::new(x?, y?))
}

/// `points = [[x, y], ...]` of `tbl`: at least `min` points, no edge shorter than a
/// millimetre.
fn points(ctx: &mut Reader<'_>, tbl: &Tbl<'_, '_>, min: usize, closed: bool) -> Option<Vec<Point>> {
    let Some(v) = tbl.get("points") else {
        ctx.err(
            &tbl.span,
            format!(
                "missing `points` in {} (expected at least {min} points `[x, y]`)",
                tbl.place
            ),
        );
        return None;
    };
    let items = ctx.array(v, "an array of points `[[x, y], ...]` for `points`")?;
    let mut out: Vec<Point> = Vec::new();
    let mut ok = true;
    for item in items.iter() {
        match xy(ctx, item, "points") {
            Some(p) => {
                if let Some(prev) = out.last() {
                    if (p - *prev).norm() < MIN_EDGE {
                        ctx.err(
                            &item.span(),
                            "this point repeats the previous one (edges must be at least 1 mm long)",
                        );
                        ok = false;
                    }
                }
                out.push(p);
            }
            None => ok = false,
        }
    }
    if items.len() < min {
        ctx.err(
            &v.span(),
            format!(
                "{} needs at least {min} points, found {}",
                tbl.place,
                items.len()
            ),
        );
        return None;
    }
    if !ok {
        return None;
    }
    if closed {
        let area2: f64 = (0..out.len())
            .map(|i| {
                let (a, b) = (out[i], out[(i + 1) % out.len()]);
                a.x * b.y - b.x * a.y
            })
            .sum();
        if area2.abs() < MIN_EDGE * MIN_EDGE {
            ctx.err(&v.span(), format!("{} has no area", tbl.place));
            return None;
        }
    }
    Some(out)
}

/// Parse and validate a world: the file's tables in turn, then the checks across them.
///
/// The order of the steps is the order of the diagnostics, which the tests pin.
pub(crate) fn parse(src: &str, path: Option<&Path>) -> Result<World, Diagnostics> {
    let mut ctx = Reader::new(src, display_path(path));
    let Some(doc) = ctx.parse() else {
        return finish(ctx, None);
    };
    let top = ctx.top(&doc, "the world file");
    ctx.unknown_keys(&top, TOP_KEYS);

    let (name, description) = world_table(&mut ctx, &top);
    let walls = wall_tables(&mut ctx, &top);
    let obstacles = obstacle_tables(&mut ctx, &top);
    let (cart, start, start_span) = cart_table(&mut ctx, &top);
    let sonars = sonar_tables(&mut ctx, &top, &cart);
    let (goal, goal_span) = goal_table(&mut ctx, &top).unzip();
    let (dock, dock_span) = dock_table(&mut ctx, &top).unzip();
    let sim = sim_table(&mut ctx, &top);

    let world = World {
        name,
        description,
        walls,
        obstacles,
        cart,
        start,
        sonars,
        goal,
        dock,
        sim,
    };
    if ctx.has_errors() {
        return finish(ctx, None);
    }
    let spans = PartSpans {
        start: start_span,
        goal: goal_span,
        dock: dock_span,
    };
    check_across_parts(&mut ctx, &world, &spans);
    finish(ctx, Some(world))
}

/// `[world]`: its `name` (required, not blank) and `description` (empty when absent).
fn world_table(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> (String, String) {
    let Some(v) = top.get("world") else {
        ctx.err(
            &(0..0),
            "missing table `[world]` (expected `name = \"...\"`)",
        );
        return (String::new(), String::new());
    };
    let Some(t) = ctx.table(v, "[world]") else {
        return (String::new(), String::new());
    };
    ctx.unknown_keys(&t, WORLD_KEYS);
    let mut name = String::new();
    match ctx.string(&t, "name") {
        Some(n) if !n.trim().is_empty() => name = n,
        Some(_) => {
            if let Some(v) = t.get("name") {
                ctx.err(&v.span(), "`name` must not be empty");
            }
        }
        None => {
            // a `name` of the wrong type was reported by `string`
            if t.get("name").is_none() {
                ctx.err(&t.span, "missing `name` in [world]");
            }
        }
    }
    let description = ctx.string(&t, "description").unwrap_or_default();
    (name, description)
}

/// `[[wall]]`: at least one, each an open polyline of two points or more.
fn wall_tables(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> Vec<Vec<Point>> {
    let Some(v) = top.get("wall") else {
        ctx.err(
            &(0..0),
            "the world has no walls (expected at least one `[[wall]]` with `points`)",
        );
        return Vec::new();
    };
    let mut walls = Vec::new();
    for t in ctx.table_array(v, "wall").into_iter().flatten() {
        ctx.unknown_keys(&t, POINTS_KEYS);
        if let Some(p) = points(ctx, &t, 2, false) {
            walls.push(p);
        }
    }
    walls
}

/// `[[obstacle]]`: optional, each a closed polygon of three points or more with an area.
fn obstacle_tables(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> Vec<Vec<Point>> {
    let mut obstacles = Vec::new();
    if let Some(v) = top.get("obstacle") {
        for t in ctx.table_array(v, "obstacle").into_iter().flatten() {
            ctx.unknown_keys(&t, POINTS_KEYS);
            if let Some(p) = points(ctx, &t, 3, true) {
                obstacles.push(p);
            }
        }
    }
    obstacles
}

/// `[cart]`: the cart's build and its start pose, with where the start was written (the
/// span the start-pose check points at).
fn cart_table(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> (CartSpec, Pose, Span) {
    let Some(v) = top.get("cart") else {
        ctx.err(
            &(0..0),
            "missing table `[cart]` (expected at least `start = { x = .., y = .., heading_deg = .. }`)",
        );
        return (CartSpec::default(), Pose::default(), 0..0);
    };
    let Some(t) = ctx.table(v, "[cart]") else {
        return (CartSpec::default(), Pose::default(), 0..0);
    };
    ctx.unknown_keys(&t, CART_KEYS);
    let start = start_pose(ctx, &t).unwrap_or_default();
    let start_span = t.get("start").map_or(t.span.clone(), |v| v.span());
    (cart_spec(ctx, &t), start, start_span)
}

/// `[[sonar]]`: the mounted sonars, or the default ring around `cart` when there is none.
fn sonar_tables(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>, cart: &CartSpec) -> Vec<SonarMount> {
    match top.get("sonar") {
        None => SonarMount::default_ring(cart),
        Some(v) => ctx
            .table_array(v, "sonar")
            .into_iter()
            .flatten()
            .filter_map(|t| sonar(ctx, &t))
            .collect(),
    }
}

/// `[goal]` (optional), with its table's span for the bounds check.
fn goal_table(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> Option<(GoalArea, Span)> {
    let t = ctx.table(top.get("goal")?, "[goal]")?;
    goal(ctx, &t).map(|g| (g, t.span.clone()))
}

/// `[dock]` (optional), with its table's span for the bounds check.
fn dock_table(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> Option<(Dock, Span)> {
    let t = ctx.table(top.get("dock")?, "[dock]")?;
    dock(ctx, &t).map(|d| (d, t.span.clone()))
}

/// `[sim]` (optional): the simulation's noise and sonar model, defaults where unwritten.
fn sim_table(ctx: &mut Reader<'_>, top: &Tbl<'_, '_>) -> SimSettings {
    match top.get("sim").and_then(|v| ctx.table(v, "[sim]")) {
        Some(t) => sim_settings(ctx, &t),
        None => SimSettings::default(),
    }
}

/// Where the parts the checks across the world blame were written.
struct PartSpans {
    /// The cart's `start` (or `[cart]` without one).
    start: Span,
    /// The `[goal]` table, when there is a goal.
    goal: Option<Span>,
    /// The `[dock]` table, when there is a dock.
    dock: Option<Span>,
}

/// The checks that need several parts of the world, run only on a world whose parts are
/// sound (so one mistake does not cascade): the cart starts clear of the walls and
/// obstacles, and the goal and the dock lie within the walls.
fn check_across_parts(ctx: &mut Reader<'_>, world: &World, spans: &PartSpans) {
    if world.footprint_collides(&world.start) {
        ctx.err(
            &spans.start,
            "the cart's footprint at its start pose touches a wall or an obstacle",
        );
    }
    let bounds = world.bounds();
    if let (Some(g), Some(span)) = (&world.goal, &spans.goal) {
        check_within_walls(ctx, bounds, &g.area, span, "the goal area");
    }
    if let (Some(d), Some(span)) = (&world.dock, &spans.dock) {
        check_within_walls(ctx, bounds, &d.rect(), span, "the dock");
    }
}

/// `what` (a rectangle written at `span`) must lie within the walls' `bounds` (a world
/// without bounds has room for nothing).
fn check_within_walls(
    ctx: &mut Reader<'_>,
    bounds: Option<(Point, Point)>,
    r: &Rect,
    span: &Span,
    what: &str,
) {
    let outside = bounds.is_none_or(|(lo, hi)| {
        r.corners().iter().any(|c| {
            c.x < lo.x - 1e-9 || c.y < lo.y - 1e-9 || c.x > hi.x + 1e-9 || c.y > hi.y + 1e-9
        })
    });
    if outside {
        let bounds_text = bounds.map_or(String::new(), |(lo, hi)| {
            format!(" (x {:.3}..{:.3}, y {:.3}..{:.3})", lo.x, hi.x, lo.y, hi.y)
        });
        ctx.err(
            span,
            format!("{what} reaches outside the world's walls{bounds_text}"),
        );
    }
}

fn finish(ctx: Reader<'_>, world: Option<World>) -> Result<World, Diagnostics> {
    ctx.finish(world, "the world file is not valid")
}

fn start_pose(ctx: &mut Reader<'_>, cart: &Tbl<'_, '_>) -> Option<Pose> {
    let Some(v) = cart.get("start") else {
        ctx.err(
            &cart.span,
            "missing `start` in [cart] (expected `start = { x = .., y = .., heading_deg = .. }`)",
        );
        return None;
    };
    let t = ctx.table(v, "`start` (`{ x = .., y = .., heading_deg = .. }`)")?;
    ctx.unknown_keys(&t, START_KEYS);
    let x = ctx.num(&t, "x", None, COORD);
    let y = ctx.num(&t, "y", None, COORD);
    let heading = ctx.num(&t, "heading_deg", Some(0.0), HEADING);
    Some(Pose::new(x?, y?, heading?.to_radians()))
}

fn cart_spec(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> CartSpec {
    let d = CartSpec::default();
    let length = ctx.num(t, "length", Some(d.length), CART_SIZE);
    let width = ctx.num(t, "width", Some(d.width), CART_SIZE);
    let wheelbase = ctx.num(t, "wheelbase", Some(d.wheelbase), CART_SIZE);
    let overhang_default = match (length, wheelbase) {
        (Some(l), Some(w)) => ((l - w) / 2.0).max(0.0),
        _ => d.rear_overhang,
    };
    let rear_overhang = ctx.num(
        t,
        "rear_overhang",
        Some(overhang_default),
        Rule::NonNegative,
    );
    // a cart, not a car: at most 5 m/s (the thesis' cart did 0.5)
    let max_speed = ctx.num(t, "max_speed", Some(d.max_speed), Rule::AboveUpTo(0.0, 5.0));
    let max_steer = ctx.num(
        t,
        "max_steer_deg",
        Some(d.max_steer.to_degrees()),
        Rule::AboveUpTo(0.0, 80.0),
    );
    let max_steer_rate = ctx.num(
        t,
        "max_steer_rate_deg",
        Some(d.max_steer_rate.to_degrees()),
        Rule::Positive,
    );
    let speed_time_constant = ctx.num(
        t,
        "speed_time_constant",
        Some(d.speed_time_constant),
        Rule::NonNegative,
    );
    if let (Some(l), Some(w), Some(r)) = (length, wheelbase, rear_overhang) {
        if w + r > l + 1e-12 {
            let span = t
                .get("wheelbase")
                .or_else(|| t.get("rear_overhang"))
                .or_else(|| t.get("length"))
                .map_or(t.span.clone(), |v| v.span());
            ctx.err(
                &span,
                format!(
                    "the axles must lie within the footprint: wheelbase ({w}) + rear_overhang ({r}) must not exceed length ({l})"
                ),
            );
        }
    }
    CartSpec {
        length: length.unwrap_or(d.length),
        width: width.unwrap_or(d.width),
        wheelbase: wheelbase.unwrap_or(d.wheelbase),
        rear_overhang: rear_overhang.unwrap_or(d.rear_overhang),
        max_speed: max_speed.unwrap_or(d.max_speed),
        max_steer: max_steer.map_or(d.max_steer, f64::to_radians),
        max_steer_rate: max_steer_rate.map_or(d.max_steer_rate, f64::to_radians),
        speed_time_constant: speed_time_constant.unwrap_or(d.speed_time_constant),
    }
}

fn sonar(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> Option<SonarMount> {
    ctx.unknown_keys(t, SONAR_KEYS);
    let x = ctx.num(t, "x", None, Rule::Within(-10.0, 10.0));
    let y = ctx.num(t, "y", None, Rule::Within(-10.0, 10.0));
    let angle = ctx.num(t, "angle_deg", None, HEADING);
    let beam = match t.get("beam") {
        None => {
            ctx.err(
                &t.span,
                format!(
                    "missing `beam` in {} (expected \"narrow\" or \"wide\")",
                    t.place
                ),
            );
            None
        }
        Some(v) => match v.get_ref() {
            DeValue::String(s) if s == "narrow" => Some(Beam::Narrow),
            DeValue::String(s) if s == "wide" => Some(Beam::Wide),
            DeValue::String(s) => {
                ctx.err(
                    &v.span(),
                    format!(
                        "unknown beam `{}` (expected \"narrow\" or \"wide\")",
                        s.escape_debug()
                    ),
                );
                None
            }
            _ => ctx.expected(v, "\"narrow\" or \"wide\" for `beam`"),
        },
    };
    let default_range = match beam {
        Some(Beam::Wide) => 3.0,
        _ => 4.0,
    };
    let range = ctx.num(t, "range", Some(default_range), Rule::AboveUpTo(0.0, 100.0));
    Some(SonarMount {
        x: x?,
        y: y?,
        angle: crate::geom::wrap_angle(angle?.to_radians()),
        beam: beam?,
        range: range?,
    })
}

fn goal(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> Option<GoalArea> {
    ctx.unknown_keys(t, GOAL_KEYS);
    let center = match t.get("center") {
        None => {
            ctx.err(
                &t.span,
                "missing `center` in [goal] (expected `center = { x = .., y = .. }`)",
            );
            None
        }
        Some(v) => point(ctx, v, "center"),
    };
    let length = ctx.num(t, "length", None, Rule::AboveUpTo(0.0, 2.0 * MAX_COORD));
    let width = ctx.num(t, "width", None, Rule::AboveUpTo(0.0, 2.0 * MAX_COORD));
    let heading = ctx.num(t, "heading_deg", Some(0.0), HEADING);
    let tolerance = ctx.num(
        t,
        "heading_tolerance_deg",
        Some(10.0),
        Rule::AboveUpTo(0.0, 180.0),
    );
    let either_way = ctx.boolean(t, "either_way", false);
    let heading = crate::geom::wrap_angle(heading?.to_radians());
    Some(GoalArea {
        area: Rect {
            center: center?,
            heading,
            length: length?,
            width: width?,
        },
        heading,
        heading_tolerance: tolerance?.to_radians(),
        either_way,
    })
}

fn dock(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> Option<Dock> {
    ctx.unknown_keys(t, DOCK_KEYS);
    let opening = match t.get("opening") {
        None => {
            ctx.err(
                &t.span,
                "missing `opening` in [dock] (expected `opening = [[x, y], [x, y]]`)",
            );
            None
        }
        Some(v) => match v.get_ref() {
            DeValue::Array(items) if items.len() == 2 => {
                let a = xy(ctx, &items[0], "opening");
                let b = xy(ctx, &items[1], "opening");
                match (a, b) {
                    (Some(a), Some(b)) if (b - a).norm() < MIN_EDGE => {
                        ctx.err(&v.span(), "the dock's opening has no length");
                        None
                    }
                    (Some(a), Some(b)) => Some((a, b, v.span())),
                    _ => None,
                }
            }
            _ => {
                ctx.err(
                    &v.span(),
                    "expected `opening = [[x, y], [x, y]]` (the two ends of the opening)",
                );
                None
            }
        },
    };
    let breadth = ctx.num(t, "breadth", None, Rule::AboveUpTo(0.0, 2.0 * MAX_COORD));
    let depth = ctx.num(t, "depth", None, Rule::AboveUpTo(0.0, 2.0 * MAX_COORD));
    let (a, b, _) = opening?;
    let breadth = breadth?;
    let length = (b - a).norm();
    if (length - breadth).abs() > DOCK_BREADTH_TOLERANCE {
        let span = t.get("breadth").map_or(t.span.clone(), |v| v.span());
        ctx.err(
            &span,
            format!(
                "`breadth` ({breadth}) must equal the opening's length ({length:.3}) within {DOCK_BREADTH_TOLERANCE} m"
            ),
        );
        return None;
    }
    Some(Dock {
        a,
        b,
        breadth,
        depth: depth?,
    })
}

fn sim_settings(ctx: &mut Reader<'_>, t: &Tbl<'_, '_>) -> SimSettings {
    ctx.unknown_keys(t, SIM_KEYS);
    let d = SimSettings::default();
    let deg = |x: Option<f64>, default: f64| x.map_or(default, f64::to_radians);
    let sonar_sigma = ctx.num(
        t,
        "sonar_sigma",
        Some(d.sonar_sigma),
        Rule::Within(0.0, 1.0),
    );
    let sonar_dropout = ctx.num(
        t,
        "sonar_dropout",
        Some(d.sonar_dropout),
        Rule::Within(0.0, 1.0),
    );
    let incidence = ctx.num(
        t,
        "incidence_limit_deg",
        Some(d.incidence_limit.to_degrees()),
        Rule::AboveUpTo(0.0, 90.0),
    );
    let rays = match t.get("rays_per_beam") {
        None => d.rays_per_beam,
        Some(v) => match v.get_ref() {
            DeValue::Integer(i) => match i64::from_str_radix(i.as_str(), i.radix()) {
                Ok(n) if (1..=64).contains(&n) => n as u32,
                _ => {
                    ctx.err(&v.span(), "`rays_per_beam` must be an integer in 1..=64");
                    d.rays_per_beam
                }
            },
            _ => ctx
                .expected(v, "an integer for `rays_per_beam`")
                .unwrap_or(d.rays_per_beam),
        },
    };
    let narrow = ctx.num(
        t,
        "narrow_half_angle_deg",
        Some(d.narrow_half_angle.to_degrees()),
        Rule::Between(0.0, 90.0),
    );
    let wide = ctx.num(
        t,
        "wide_half_angle_deg",
        Some(d.wide_half_angle.to_degrees()),
        Rule::Between(0.0, 90.0),
    );
    let odo_d = ctx.num(
        t,
        "odometry_distance_sigma",
        Some(d.odometry_distance_sigma),
        Rule::Within(0.0, 1.0),
    );
    let odo_h = ctx.num(
        t,
        "odometry_heading_sigma_deg",
        Some(d.odometry_heading_sigma.to_degrees()),
        Rule::Within(0.0, 45.0),
    );
    let odo_walk = ctx.num(
        t,
        "odometry_heading_walk_deg",
        Some(d.odometry_heading_walk.to_degrees()),
        Rule::Within(0.0, 45.0),
    );
    SimSettings {
        sonar_sigma: sonar_sigma.unwrap_or(d.sonar_sigma),
        sonar_dropout: sonar_dropout.unwrap_or(d.sonar_dropout),
        incidence_limit: deg(incidence, d.incidence_limit),
        rays_per_beam: rays,
        narrow_half_angle: deg(narrow, d.narrow_half_angle),
        wide_half_angle: deg(wide, d.wide_half_angle),
        odometry_distance_sigma: odo_d.unwrap_or(d.odometry_distance_sigma),
        odometry_heading_sigma: deg(odo_h, d.odometry_heading_sigma),
        odometry_heading_walk: deg(odo_walk, d.odometry_heading_walk),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINI: &str = r#"
[world]
name = "mini"

[[wall]]
points = [[0, 0], [4, 0]]

[cart]
start = { x = 1, y = 1, heading_deg = 0 }
"#;

    #[test]
    fn a_minimal_world_takes_the_defaults() {
        let w = parse(MINI, None).unwrap();
        assert_eq!(w.name, "mini");
        assert_eq!(w.cart, CartSpec::default());
        assert_eq!(w.sonars.len(), 10);
        assert_eq!(w.sim, SimSettings::default());
        assert!(w.goal.is_none() && w.dock.is_none());
    }

    #[test]
    fn syntax_errors_have_positions() {
        let e = parse("[world]\nname = = 1\n", Some(Path::new("w.toml"))).unwrap_err();
        assert!(e.to_string().starts_with("w.toml:2:8: syntax error"), "{e}");
    }

    #[test]
    fn missing_tables_are_reported_at_the_start() {
        let e = parse("", None).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("<world>:1:1: missing table `[world]`"),
            "{text}"
        );
        assert!(text.contains("no walls"), "{text}");
        assert!(text.contains("missing table `[cart]`"), "{text}");
    }
}

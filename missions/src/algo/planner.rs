//! Path planning on a map of wall segments (the path planner's algorithm).
//!
//! 1. **Grid.** The bounds are rasterised at [`PlannerParams::resolution`]; a cell is blocked
//!    when its centre is closer than `inflation + resolution·√2/2` to a wall segment. The extra
//!    half-diagonal guarantees that every straight step between free cell centres keeps the
//!    full inflation from every wall.
//! 2. **Approach.** The path ends with a straight leg of [`PlannerParams::approach_distance`]
//!    along the goal heading (from a pre-goal point behind the goal, or in front of it when
//!    [`PlannerParams::reverse`] backs the cart in), so the cart arrives aligned. When that leg
//!    is obstructed, shorter ones (¾, ½, ¼) are tried, then none.
//! 3. **Search.** A* over the 8-connected grid (octile heuristic, no cutting of blocked
//!    corners) from the start to the pre-goal.
//! 4. **Shortcut.** Greedy line-of-sight smoothing: from each waypoint, jump to the farthest
//!    later one whose straight connection keeps `inflation` from all walls (exact
//!    segment-to-segment distance).
//!
//! The result's legs all keep at least `inflation` from every wall, except a start that
//! already lies closer (it may escape to the nearest free cell within
//! [`PlannerParams::start_escape`]).

use crate::geom::{Point, Pose, Segment};
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::fmt;

/// A path: a polyline of waypoints, first the start, last the goal.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Path {
    /// Waypoints, world frame, metres.
    pub waypoints: Vec<Point>,
    /// Heading the cart should have at the last waypoint, radians, if any.
    pub goal_heading: Option<f64>,
}

impl Path {
    /// A path through `waypoints` with no required final heading.
    pub fn new(waypoints: Vec<Point>) -> Self {
        Path {
            waypoints,
            goal_heading: None,
        }
    }

    /// The same path, requiring `heading` at the end.
    pub fn with_heading(mut self, heading: f64) -> Self {
        self.goal_heading = Some(heading);
        self
    }

    /// Total length, metres.
    pub fn length(&self) -> f64 {
        self.waypoints
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum()
    }

    /// True without waypoints.
    pub fn is_empty(&self) -> bool {
        self.waypoints.is_empty()
    }

    /// The legs between consecutive waypoints.
    pub fn legs(&self) -> impl Iterator<Item = Segment> + '_ {
        self.waypoints.windows(2).map(|w| Segment::new(w[0], w[1]))
    }

    /// The length of the straight run the path ends on, metres: back from the last
    /// waypoint for as long as each leg keeps the last leg's direction (within
    /// [`STRAIGHT_TOLERANCE`]). A parking manoeuvre's tail, whatever its planner was told.
    pub fn straight_end(&self) -> f64 {
        let mut legs = self.waypoints.windows(2).rev().map(|w| w[1] - w[0]);
        let Some(last) = legs.find(|v| v.norm() > 1e-9) else {
            return 0.0;
        };
        let direction = last.y.atan2(last.x);
        let mut length = last.norm();
        for v in legs {
            if v.norm() <= 1e-9 {
                continue;
            }
            let turn = crate::geom::wrap_angle(v.y.atan2(v.x) - direction).abs();
            if turn > STRAIGHT_TOLERANCE {
                break;
            }
            length += v.norm();
        }
        length
    }
}

/// How far a leg's direction may stray from the path's last one and still count as the
/// same straight run ([`Path::straight_end`]), radians: 1°.
pub const STRAIGHT_TOLERANCE: f64 = std::f64::consts::PI / 180.0;

/// The planning area, an axis-aligned rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Lower-left corner.
    pub min: Point,
    /// Upper-right corner.
    pub max: Point,
}

impl Bounds {
    /// The rectangle spanned by two corners (in any order).
    pub fn new(a: Point, b: Point) -> Self {
        Bounds {
            min: Point::new(a.x.min(b.x), a.y.min(b.y)),
            max: Point::new(a.x.max(b.x), a.y.max(b.y)),
        }
    }

    /// The bounding box of `segments`, grown by `margin` on every side; `None` without
    /// segments.
    pub fn around(segments: &[Segment], margin: f64) -> Option<Self> {
        let mut it = segments.iter().flat_map(|s| [s.a, s.b]);
        let first = it.next()?;
        let (mut lo, mut hi) = (first, first);
        for p in it {
            lo = Point::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        let m = margin.max(0.0);
        Some(Bounds::new(
            Point::new(lo.x - m, lo.y - m),
            Point::new(hi.x + m, hi.y + m),
        ))
    }

    /// True when `p` lies inside (borders included).
    pub fn contains(&self, p: Point) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }
}

/// Parameters of the path planner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannerParams {
    /// Grid cell size, metres. Default 0.05.
    pub resolution: f64,
    /// Clearance every leg keeps from the walls: the cart's radius plus a margin, metres.
    /// Default 0.40 (half the cart's 0.6 m width plus 0.1 m).
    pub inflation: f64,
    /// Length of the straight final approach along the goal heading, metres. Default 1.0.
    pub approach_distance: f64,
    /// Approach backwards (the cart backs into the goal): the pre-goal point lies in front of
    /// the goal. Default false.
    pub reverse: bool,
    /// A start inside the inflated walls may escape to a free cell this close, metres.
    /// Default 0.5.
    pub start_escape: f64,
    /// Largest grid, in cells. Default 4 000 000.
    pub max_cells: usize,
}

impl Default for PlannerParams {
    fn default() -> Self {
        PlannerParams {
            resolution: 0.05,
            inflation: 0.40,
            approach_distance: 1.0,
            reverse: false,
            start_escape: 0.5,
            max_cells: 4_000_000,
        }
    }
}

/// Why no path exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NoPathReason {
    /// The start is outside the bounds.
    StartOutOfBounds,
    /// The goal is outside the bounds.
    GoalOutOfBounds,
    /// The start is inside the inflated walls with no free cell within reach.
    StartBlocked,
    /// The goal is inside the inflated walls.
    GoalBlocked,
    /// Start and goal are in different free regions.
    Unreachable,
}

impl fmt::Display for NoPathReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NoPathReason::StartOutOfBounds => "the start is outside the planning bounds",
            NoPathReason::GoalOutOfBounds => "the goal is outside the planning bounds",
            NoPathReason::StartBlocked => "the start is inside an (inflated) obstacle",
            NoPathReason::GoalBlocked => "the goal is inside an (inflated) obstacle",
            NoPathReason::Unreachable => "the goal cannot be reached from the start",
        })
    }
}

/// A planning failure.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// There is no collision-free path.
    #[error("no path: {reason}")]
    NoPath {
        /// Why.
        reason: NoPathReason,
    },
    /// The inputs cannot be planned with (non-finite numbers, bad resolution, grid too big).
    #[error("invalid planner input: {0}")]
    InvalidInput(String),
}

fn no_path(reason: NoPathReason) -> PlanError {
    PlanError::NoPath { reason }
}

/// Distance between two segments (0 when they intersect).
pub fn segment_distance(s: &Segment, t: &Segment) -> f64 {
    if segments_intersect(s, t) {
        return 0.0;
    }
    s.distance_to(t.a)
        .min(s.distance_to(t.b))
        .min(t.distance_to(s.a))
        .min(t.distance_to(s.b))
}

fn segments_intersect(s: &Segment, t: &Segment) -> bool {
    let d1 = s.b - s.a;
    let d2 = t.b - t.a;
    let denom = d1.perp(&d2);
    if denom.abs() < 1e-15 {
        return false; // parallel: the end-point distances decide
    }
    let w = t.a - s.a;
    let u = w.perp(&d2) / denom;
    let v = w.perp(&d1) / denom;
    (0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)
}

/// Smallest distance between `point` and the `obstacles` (∞ without obstacles).
pub fn point_clearance(point: Point, obstacles: &[Segment]) -> f64 {
    obstacles
        .iter()
        .map(|o| o.distance_to(point))
        .fold(f64::INFINITY, f64::min)
}

/// Smallest distance between any leg of `path` (or its only waypoint) and the `obstacles`
/// (∞ for an empty path or no obstacles).
pub fn path_clearance(path: &Path, obstacles: &[Segment]) -> f64 {
    if path.waypoints.len() == 1 {
        return point_clearance(path.waypoints[0], obstacles);
    }
    path.legs()
        .flat_map(|leg| obstacles.iter().map(move |o| segment_distance(&leg, o)))
        .fold(f64::INFINITY, f64::min)
}

fn leg_clear(a: Point, b: Point, obstacles: &[Segment], clearance: f64) -> bool {
    let leg = Segment::new(a, b);
    obstacles
        .iter()
        .all(|o| segment_distance(&leg, o) >= clearance)
}

struct Grid {
    origin: Point,
    res: f64,
    w: usize,
    h: usize,
    blocked: Vec<bool>,
}

impl Grid {
    fn build(obstacles: &[Segment], bounds: &Bounds, res: f64, radius: f64) -> Self {
        let w = (((bounds.max.x - bounds.min.x) / res).ceil() as usize).max(1);
        let h = (((bounds.max.y - bounds.min.y) / res).ceil() as usize).max(1);
        let mut grid = Grid {
            origin: bounds.min,
            res,
            w,
            h,
            blocked: vec![false; w * h],
        };
        for o in obstacles {
            let (x0, x1) = (o.a.x.min(o.b.x) - radius, o.a.x.max(o.b.x) + radius);
            let (y0, y1) = (o.a.y.min(o.b.y) - radius, o.a.y.max(o.b.y) + radius);
            let (i0, j0) = grid.cell_floor(Point::new(x0, y0));
            let (i1, j1) = grid.cell_floor(Point::new(x1, y1));
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = j * w + i;
                    if !grid.blocked[k] && o.distance_to(grid.centre(i, j)) < radius {
                        grid.blocked[k] = true;
                    }
                }
            }
        }
        grid
    }

    /// The cell containing `p`, clamped into the grid.
    fn cell_floor(&self, p: Point) -> (usize, usize) {
        let fx = ((p.x - self.origin.x) / self.res).floor();
        let fy = ((p.y - self.origin.y) / self.res).floor();
        let i = fx.clamp(0.0, (self.w - 1) as f64) as usize;
        let j = fy.clamp(0.0, (self.h - 1) as f64) as usize;
        (i, j)
    }

    fn centre(&self, i: usize, j: usize) -> Point {
        Point::new(
            self.origin.x + (i as f64 + 0.5) * self.res,
            self.origin.y + (j as f64 + 0.5) * self.res,
        )
    }

    fn free(&self, i: usize, j: usize) -> bool {
        !self.blocked[j * self.w + i]
    }

    /// Free cells within `radius` of `p`, nearest first.
    fn free_cells_near(&self, p: Point, radius: f64) -> Vec<(usize, usize)> {
        let r = (radius / self.res).ceil() as i64 + 1;
        let (ci, cj) = self.cell_floor(p);
        let mut out: Vec<(f64, usize, usize)> = Vec::new();
        for dj in -r..=r {
            for di in -r..=r {
                let (i, j) = (ci as i64 + di, cj as i64 + dj);
                if i < 0 || j < 0 || i >= self.w as i64 || j >= self.h as i64 {
                    continue;
                }
                let (i, j) = (i as usize, j as usize);
                let d = (self.centre(i, j) - p).norm();
                if d <= radius.max(self.res) && self.free(i, j) {
                    out.push((d, i, j));
                }
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        out.into_iter().map(|(_, i, j)| (i, j)).collect()
    }
}

#[derive(Clone, Copy, PartialEq)]
struct Open {
    f: f64,
    g: f64,
    k: usize,
}

impl Eq for Open {}

impl Ord for Open {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on f, then prefer larger g (deeper), then index for determinism.
        other
            .f
            .total_cmp(&self.f)
            .then(self.g.total_cmp(&other.g))
            .then(other.k.cmp(&self.k))
    }
}

impl PartialOrd for Open {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

fn astar(grid: &Grid, start: (usize, usize), goal: (usize, usize)) -> Option<Vec<(usize, usize)>> {
    let (w, h) = (grid.w, grid.h);
    let idx = |i: usize, j: usize| j * w + i;
    let heur = |i: usize, j: usize| {
        let dx = (i as f64 - goal.0 as f64).abs();
        let dy = (j as f64 - goal.1 as f64).abs();
        (dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy)) * grid.res
    };
    let mut g = vec![f64::INFINITY; w * h];
    let mut came: Vec<usize> = vec![usize::MAX; w * h];
    let mut closed = vec![false; w * h];
    let mut open = BinaryHeap::new();
    let s = idx(start.0, start.1);
    g[s] = 0.0;
    open.push(Open {
        f: heur(start.0, start.1),
        g: 0.0,
        k: s,
    });
    let target = idx(goal.0, goal.1);
    while let Some(Open { g: gk, k, .. }) = open.pop() {
        if closed[k] {
            continue;
        }
        closed[k] = true;
        if k == target {
            let mut cells = vec![(k % w, k / w)];
            let mut c = k;
            while came[c] != usize::MAX {
                c = came[c];
                cells.push((c % w, c / w));
            }
            cells.reverse();
            return Some(cells);
        }
        let (i, j) = ((k % w) as i64, (k / w) as i64);
        for (di, dj) in [
            (1, 0),
            (-1, 0),
            (0, 1),
            (0, -1),
            (1, 1),
            (1, -1),
            (-1, 1),
            (-1, -1),
        ] {
            let (ni, nj) = (i + di, j + dj);
            if ni < 0 || nj < 0 || ni >= w as i64 || nj >= h as i64 {
                continue;
            }
            let (ni, nj) = (ni as usize, nj as usize);
            if !grid.free(ni, nj) {
                continue;
            }
            if di != 0 && dj != 0 {
                // No squeezing diagonally past a blocked corner.
                if !grid.free(ni, j as usize) || !grid.free(i as usize, nj) {
                    continue;
                }
            }
            let step = if di != 0 && dj != 0 {
                std::f64::consts::SQRT_2
            } else {
                1.0
            } * grid.res;
            let nk = idx(ni, nj);
            let ng = gk + step;
            if ng < g[nk] {
                g[nk] = ng;
                came[nk] = k;
                open.push(Open {
                    f: ng + heur(ni, nj),
                    g: ng,
                    k: nk,
                });
            }
        }
    }
    None
}

/// Plan a path from `start` to `goal` among the wall `obstacles` inside `bounds`.
///
/// The path starts at the start's position, ends at the goal's position with
/// `goal_heading = Some(goal.theta)`, and (when it fits) its last leg is a straight approach
/// along the goal heading. Errors: [`PlanError::NoPath`] with the reason, or
/// [`PlanError::InvalidInput`].
///
/// The steps: check the inputs and both ends, pick the pre-goal the final approach starts
/// from, enter the inflated grid near the start and the pre-goal, search it with A*, then
/// straighten the route by line of sight.
pub fn plan(
    obstacles: &[Segment],
    start: &Pose,
    goal: &Pose,
    bounds: &Bounds,
    params: &PlannerParams,
) -> Result<Path, PlanError> {
    let terrain = Terrain::checked(obstacles, start, goal, bounds, params)?;
    terrain.check_ends(start, goal, bounds)?;
    let grid = terrain.grid(bounds);
    let pre_goal = terrain.pre_goal(goal, bounds, params);
    let start_cell = terrain.start_cell(&grid, start.point(), params.start_escape)?;
    let goal_cell = terrain.goal_cell(&grid, pre_goal)?;
    let cells = astar(&grid, start_cell, goal_cell).ok_or(no_path(NoPathReason::Unreachable))?;
    let route = grid_route(&grid, &cells, start.point(), pre_goal);
    let mut waypoints = terrain.shortcut(&route);
    let goal_p = goal.point();
    if (pre_goal - goal_p).norm() > 1e-12 {
        waypoints.push(goal_p);
    }
    Ok(Path {
        waypoints,
        goal_heading: Some(goal.theta),
    })
}

/// What every step of [`plan`] plans among, once the inputs are checked.
struct Terrain {
    /// The obstacles with finite ends (the others are dropped).
    obstacles: Vec<Segment>,
    /// Grid cell size, metres.
    res: f64,
    /// Clearance every leg keeps from the obstacles, metres (never negative).
    inflation: f64,
}

/// True when both coordinates of `p` are finite.
fn finite(p: Point) -> bool {
    p.x.is_finite() && p.y.is_finite()
}

impl Terrain {
    /// Check the numbers planning needs ([`PlanError::InvalidInput`] otherwise: non-finite
    /// start, goal or bounds, a bad resolution or inflation, a grid over the size limit).
    fn checked(
        obstacles: &[Segment],
        start: &Pose,
        goal: &Pose,
        bounds: &Bounds,
        params: &PlannerParams,
    ) -> Result<Terrain, PlanError> {
        if !finite(start.point()) || !finite(goal.point()) || !goal.theta.is_finite() {
            return Err(PlanError::InvalidInput("non-finite start or goal".into()));
        }
        if !finite(bounds.min) || !finite(bounds.max) {
            return Err(PlanError::InvalidInput("non-finite bounds".into()));
        }
        let res = params.resolution;
        if !(res.is_finite() && res > 1e-4) {
            return Err(PlanError::InvalidInput(format!(
                "resolution {res} must be a positive number of metres"
            )));
        }
        let inflation = if params.inflation.is_finite() {
            params.inflation.max(0.0)
        } else {
            return Err(PlanError::InvalidInput("non-finite inflation".into()));
        };
        let cells = ((bounds.max.x - bounds.min.x) / res).ceil()
            * ((bounds.max.y - bounds.min.y) / res).ceil();
        if cells.is_nan() || cells > params.max_cells as f64 {
            return Err(PlanError::InvalidInput(format!(
                "{cells} grid cells exceed the limit of {}",
                params.max_cells
            )));
        }
        let obstacles = obstacles
            .iter()
            .copied()
            .filter(|o| finite(o.a) && finite(o.b))
            .collect();
        Ok(Terrain {
            obstacles,
            res,
            inflation,
        })
    }

    /// Both ends lie within `bounds` and the goal is clear of the obstacles (the start may
    /// escape from the inflated zone, see [`Terrain::start_cell`]).
    fn check_ends(&self, start: &Pose, goal: &Pose, bounds: &Bounds) -> Result<(), PlanError> {
        if !bounds.contains(start.point()) {
            return Err(no_path(NoPathReason::StartOutOfBounds));
        }
        if !bounds.contains(goal.point()) {
            return Err(no_path(NoPathReason::GoalOutOfBounds));
        }
        if point_clearance(goal.point(), &self.obstacles) < self.inflation {
            return Err(no_path(NoPathReason::GoalBlocked));
        }
        Ok(())
    }

    /// The grid over `bounds` with every cell whose centre is closer than the inflation
    /// (plus half a cell's diagonal, so a free cell is free all over) blocked.
    fn grid(&self, bounds: &Bounds) -> Grid {
        let grid_radius = self.inflation + self.res * std::f64::consts::FRAC_1_SQRT_2;
        Grid::build(&self.obstacles, bounds, self.res, grid_radius)
    }

    /// Where the straight final approach starts: the goal backed off along its heading
    /// (ahead of it when reversing) by the approach distance, or by ¾, ½ or ¼ of it, the
    /// first that is in bounds with a clear approach; the goal itself when none is (or the
    /// distance is under a cell).
    fn pre_goal(&self, goal: &Pose, bounds: &Bounds, params: &PlannerParams) -> Point {
        let goal_p = goal.point();
        let sign = if params.reverse { -1.0 } else { 1.0 };
        let approach = params.approach_distance.max(0.0);
        for frac in [1.0, 0.75, 0.5, 0.25] {
            let d = approach * frac;
            if d < self.res {
                break;
            }
            let p = goal_p - goal.heading() * (sign * d);
            if bounds.contains(p) && self.clear(p, goal_p) {
                return p;
            }
        }
        goal_p
    }

    /// The grid cell the route enters from `start`: the nearest free cell with a clear
    /// straight connection. A start inside the inflated zone may escape to a free cell
    /// within `start_escape`, by a leg half as clear as the start itself.
    fn start_cell(
        &self,
        grid: &Grid,
        start: Point,
        start_escape: f64,
    ) -> Result<(usize, usize), PlanError> {
        let start_clear = point_clearance(start, &self.obstacles);
        if start_clear >= self.inflation {
            grid.free_cells_near(start, self.res * 2.0)
                .into_iter()
                .find(|&(i, j)| self.clear(start, grid.centre(i, j)))
        } else {
            let escape = start_escape.max(0.0);
            grid.free_cells_near(start, escape)
                .into_iter()
                .find(|&(i, j)| {
                    leg_clear(start, grid.centre(i, j), &self.obstacles, 0.5 * start_clear)
                })
        }
        .ok_or(no_path(NoPathReason::StartBlocked))
    }

    /// The grid cell the route leaves for the `pre_goal`: the nearest free cell with a clear
    /// straight connection.
    fn goal_cell(&self, grid: &Grid, pre_goal: Point) -> Result<(usize, usize), PlanError> {
        grid.free_cells_near(pre_goal, self.res * 2.0)
            .into_iter()
            .find(|&(i, j)| self.clear(grid.centre(i, j), pre_goal))
            .ok_or(no_path(NoPathReason::GoalBlocked))
    }

    /// Line-of-sight shortcutting of `route` up to the pre-goal (the approach leg stays as it
    /// is): from each anchor, jump to the farthest point reached by a clear leg. The route's
    /// legs are clear by construction (the first may only be as clear as the start), so each
    /// anchor always reaches at least its successor.
    fn shortcut(&self, route: &[Point]) -> Vec<Point> {
        let mut waypoints = vec![route[0]];
        let mut i = 0;
        while i + 1 < route.len() {
            let mut next = i + 1;
            for j in (i + 2..route.len()).rev() {
                if self.clear(route[i], route[j]) {
                    next = j;
                    break;
                }
            }
            waypoints.push(route[next]);
            i = next;
        }
        waypoints
    }

    /// True when the leg from `a` to `b` keeps the inflation clearance from every obstacle.
    fn clear(&self, a: Point, b: Point) -> bool {
        leg_clear(a, b, &self.obstacles, self.inflation)
    }
}

/// The A* route as points: the start, the centres of the `cells`, the pre-goal, without
/// repeats.
fn grid_route(grid: &Grid, cells: &[(usize, usize)], start: Point, pre_goal: Point) -> Vec<Point> {
    let mut route: Vec<Point> = Vec::with_capacity(cells.len() + 2);
    route.push(start);
    route.extend(cells.iter().map(|&(i, j)| grid.centre(i, j)));
    route.push(pre_goal);
    route.dedup_by(|a, b| (*a - *b).norm() < 1e-12);
    route
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_straight_end_is_the_run_the_path_ends_on() {
        // a quarter arc of radius 1 in 5° steps, then 0.5 m straight on in 0.1 m steps
        let mut points: Vec<Point> = (0..=18)
            .map(|k| {
                let a = (k as f64 * 5.0).to_radians();
                Point::new(a.sin(), 1.0 - a.cos())
            })
            .collect();
        let end = *points.last().unwrap();
        points.extend((1..=5).map(|k| end + crate::geom::Vector::new(0.0, 0.1 * k as f64)));
        let path = Path::new(points);
        assert!(
            (path.straight_end() - 0.5).abs() < 1e-9,
            "{}",
            path.straight_end()
        );
        // all straight: the whole path; a point or nothing: none
        let line = Path::new(vec![
            Point::new(0.0, 0.0),
            Point::new(1.0, 0.0),
            Point::new(3.0, 0.0),
        ]);
        assert!((line.straight_end() - 3.0).abs() < 1e-9);
        assert_eq!(Path::new(vec![Point::new(1.0, 1.0)]).straight_end(), 0.0);
        assert_eq!(Path::new(vec![]).straight_end(), 0.0);
        // a repeated last waypoint does not hide the direction
        let repeated = Path::new(vec![
            Point::new(0.0, 0.0),
            Point::new(0.0, 2.0),
            Point::new(0.0, 2.0),
        ]);
        assert!((repeated.straight_end() - 2.0).abs() < 1e-9);
    }

    fn seg(ax: f64, ay: f64, bx: f64, by: f64) -> Segment {
        Segment::new(Point::new(ax, ay), Point::new(bx, by))
    }

    fn room() -> Vec<Segment> {
        vec![
            seg(0.0, 0.0, 8.0, 0.0),
            seg(8.0, 0.0, 8.0, 6.0),
            seg(8.0, 6.0, 0.0, 6.0),
            seg(0.0, 6.0, 0.0, 0.0),
        ]
    }

    #[test]
    fn segment_distances() {
        let a = seg(0.0, 0.0, 2.0, 0.0);
        assert_eq!(segment_distance(&a, &seg(1.0, -1.0, 1.0, 1.0)), 0.0);
        assert!((segment_distance(&a, &seg(3.0, 1.0, 3.0, 2.0)) - 2f64.sqrt()).abs() < 1e-12);
        assert!((segment_distance(&a, &seg(0.0, 0.5, 2.0, 0.5)) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn straight_line_when_free() {
        let p = plan(
            &room(),
            &Pose::new(1.0, 3.0, 0.0),
            &Pose::new(7.0, 3.0, 0.0),
            &Bounds::new(Point::new(0.0, 0.0), Point::new(8.0, 6.0)),
            &PlannerParams::default(),
        )
        .unwrap();
        assert!(p.waypoints.len() <= 3, "{p:?}");
        assert!((p.length() - 6.0).abs() < 1e-6);
        assert_eq!(p.goal_heading, Some(0.0));
    }

    #[test]
    fn clean_errors() {
        let b = Bounds::new(Point::new(0.0, 0.0), Point::new(8.0, 6.0));
        let pp = PlannerParams::default();
        let start = Pose::new(1.0, 3.0, 0.0);
        let e = plan(&room(), &start, &Pose::new(7.0, 0.1, 0.0), &b, &pp).unwrap_err();
        assert_eq!(
            e,
            PlanError::NoPath {
                reason: NoPathReason::GoalBlocked
            }
        );
        let e = plan(&room(), &start, &Pose::new(9.0, 3.0, 0.0), &b, &pp).unwrap_err();
        assert!(e.to_string().contains("outside"));
        let bad = PlannerParams {
            resolution: 0.0,
            ..pp
        };
        assert!(matches!(
            plan(&room(), &start, &Pose::new(7.0, 3.0, 0.0), &b, &bad),
            Err(PlanError::InvalidInput(_))
        ));
        let tiny = PlannerParams {
            resolution: 1e-3,
            max_cells: 1000,
            ..pp
        };
        assert!(matches!(
            plan(&room(), &start, &Pose::new(7.0, 3.0, 0.0), &b, &tiny),
            Err(PlanError::InvalidInput(_))
        ));
    }

    #[test]
    fn start_escapes_from_the_inflated_zone() {
        let b = Bounds::new(Point::new(0.0, 0.0), Point::new(8.0, 6.0));
        let p = plan(
            &room(),
            &Pose::new(1.0, 0.3, 0.0),
            &Pose::new(6.0, 3.0, 0.0),
            &b,
            &PlannerParams::default(),
        )
        .unwrap();
        assert_eq!(p.waypoints[0], Point::new(1.0, 0.3));
        // Everything after the escape leg keeps the inflation.
        let rest = Path::new(p.waypoints[1..].to_vec());
        assert!(path_clearance(&rest, &room()) >= 0.4 - 1e-9);
    }
}

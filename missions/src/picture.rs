//! An SVG picture of a run: walls and obstacles, the goal area, the driven path, sonar hits,
//! extracted segments, the detected dock and the final footprint.
//!
//! Written by hand (SVG is text) rather than with a drawing crate: the picture needs lines,
//! polygons and circles, nothing more.

use crate::geom::{Point, Segment};
use crate::world::World;
use std::fmt::Write;

/// What to draw besides the world.
#[derive(Clone, Debug, Default)]
pub struct Picture {
    /// The driven path (true poses).
    pub path: Vec<Point>,
    /// Sonar echo points (as the robot believed them).
    pub sonar: Vec<Point>,
    /// Extracted line segments.
    pub segments: Vec<Segment>,
    /// The followed wall.
    pub wall: Option<Segment>,
    /// The detected dock's corners.
    pub dock: Option<[Point; 4]>,
    /// The planned path.
    pub planned: Vec<Point>,
    /// The cart's final footprint.
    pub footprint: Option<[Point; 4]>,
    /// A caption.
    pub caption: String,
}

fn points_attr(points: &[Point], tf: &impl Fn(Point) -> (f64, f64)) -> String {
    let mut s = String::new();
    for p in points {
        let (x, y) = tf(*p);
        let _ = write!(s, "{x:.3},{y:.3} ");
    }
    s.trim_end().to_string()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

impl Picture {
    /// Render the picture over `world` as an SVG document, 1 m = `scale` px.
    pub fn render(&self, world: &World, scale: f64) -> String {
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            50.0
        };
        let mut all: Vec<Point> = world.walls.iter().flatten().copied().collect();
        all.extend(world.obstacles.iter().flatten());
        all.extend(&self.path);
        all.push(world.start.point());
        let (mut min_x, mut min_y, mut max_x, mut max_y) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in all.iter().filter(|p| p.x.is_finite() && p.y.is_finite()) {
            min_x = min_x.min(p.x);
            min_y = min_y.min(p.y);
            max_x = max_x.max(p.x);
            max_y = max_y.max(p.y);
        }
        if min_x > max_x {
            (min_x, min_y, max_x, max_y) = (0.0, 0.0, 1.0, 1.0);
        }
        let margin = 0.5;
        let (w, h) = (
            (max_x - min_x + 2.0 * margin) * scale,
            (max_y - min_y + 2.0 * margin) * scale + 24.0,
        );
        // world y points up, SVG y points down
        let tf = |p: Point| {
            (
                (p.x - min_x + margin) * scale,
                (max_y - p.y + margin) * scale + 24.0,
            )
        };
        let mut svg = String::new();
        let _ = writeln!(
            svg,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.1} {h:.1}">"#
        );
        let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            svg,
            r#"<text x="8" y="17" font-family="sans-serif" font-size="14">{}</text>"#,
            escape(&self.caption)
        );
        if let Some(goal) = &world.goal {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="#c8f0c8" stroke="#3a3" stroke-dasharray="4 3"><title>goal area</title></polygon>"##,
                points_attr(&goal.area.corners(), &tf)
            );
        }
        for wall in &world.walls {
            let _ = writeln!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#222" stroke-width="4" stroke-linecap="round"/>"##,
                points_attr(wall, &tf)
            );
        }
        for ob in &world.obstacles {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="#888" stroke="#222"/>"##,
                points_attr(ob, &tf)
            );
        }
        if !self.planned.is_empty() {
            let _ = writeln!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#e69500" stroke-width="2" stroke-dasharray="6 4"><title>planned path</title></polyline>"##,
                points_attr(&self.planned, &tf)
            );
        }
        for p in &self.sonar {
            let (x, y) = tf(*p);
            let _ = writeln!(
                svg,
                r##"<circle cx="{x:.2}" cy="{y:.2}" r="1.6" fill="#d33" fill-opacity="0.6"/>"##
            );
        }
        for s in &self.segments {
            let (x1, y1) = tf(s.a);
            let (x2, y2) = tf(s.b);
            let _ = writeln!(
                svg,
                r##"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="#1f6fd1" stroke-width="2.5"/>"##
            );
        }
        if let Some(s) = &self.wall {
            let (x1, y1) = tf(s.a);
            let (x2, y2) = tf(s.b);
            let _ = writeln!(
                svg,
                r##"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="#7b2cbf" stroke-width="5" stroke-opacity="0.5"><title>followed wall</title></line>"##
            );
        }
        if let Some(d) = &self.dock {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="none" stroke="#7b2cbf" stroke-width="2"><title>detected dock</title></polygon>"##,
                points_attr(d, &tf)
            );
        }
        if !self.path.is_empty() {
            let _ = writeln!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#0a8" stroke-width="2"><title>driven path</title></polyline>"##,
                points_attr(&self.path, &tf)
            );
        }
        let start = world.cart.footprint(&world.start);
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="none" stroke="#999" stroke-dasharray="3 3"><title>start</title></polygon>"##,
            points_attr(&start, &tf)
        );
        if let Some(f) = &self.footprint {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="#0a8" fill-opacity="0.35" stroke="#064"><title>final footprint</title></polygon>"##,
                points_attr(f, &tf)
            );
        }
        svg.push_str("</svg>\n");
        svg
    }
}

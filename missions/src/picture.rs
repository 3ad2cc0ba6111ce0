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

/// Where the picture's points land: world metres to SVG pixels, fitted around what is drawn
/// with a margin and a strip on top for the caption.
struct Frame {
    /// Pixels per metre.
    scale: f64,
    /// The smallest x drawn, metres.
    min_x: f64,
    /// The largest y drawn, metres (SVG y points down).
    max_y: f64,
    /// The picture's width and height, pixels.
    size: (f64, f64),
}

/// Room around the drawing, metres.
const MARGIN: f64 = 0.5;
/// Height of the caption strip on top, pixels.
const CAPTION_STRIP: f64 = 24.0;
/// Pixels per metre when the asked scale is unusable.
const DEFAULT_SCALE: f64 = 50.0;

impl Frame {
    /// The frame around the walls, obstacles, the start and the driven `path` (the planned
    /// path and the echoes may fall outside it), 1 m = `scale` px.
    fn around(world: &World, path: &[Point], scale: f64) -> Frame {
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            DEFAULT_SCALE
        };
        let mut all: Vec<Point> = world.walls.iter().flatten().copied().collect();
        all.extend(world.obstacles.iter().flatten());
        all.extend(path);
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
        let size = (
            (max_x - min_x + 2.0 * MARGIN) * scale,
            (max_y - min_y + 2.0 * MARGIN) * scale + CAPTION_STRIP,
        );
        Frame {
            scale,
            min_x,
            max_y,
            size,
        }
    }

    /// Where `p` lands, pixels: world y points up, SVG y points down.
    fn at(&self, p: Point) -> (f64, f64) {
        (
            (p.x - self.min_x + MARGIN) * self.scale,
            (self.max_y - p.y + MARGIN) * self.scale + CAPTION_STRIP,
        )
    }

    /// `points` as an SVG `points` attribute: `x,y x,y ...`.
    fn points(&self, points: &[Point]) -> String {
        let mut s = String::new();
        for p in points {
            let (x, y) = self.at(*p);
            let _ = write!(s, "{x:.3},{y:.3} ");
        }
        s.trim_end().to_string()
    }

    /// A line from `s.a` to `s.b` with the given `style` attributes (and children).
    fn line(&self, svg: &mut String, s: &Segment, style: &str) {
        let (x1, y1) = self.at(s.a);
        let (x2, y2) = self.at(s.b);
        let _ = writeln!(
            svg,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" {style}"#
        );
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

impl Picture {
    /// Render the picture over `world` as an SVG document, 1 m = `scale` px.
    ///
    /// Layers are drawn bottom to top: the world, the plan, what the robot perceived, the
    /// driven path, then the cart.
    pub fn render(&self, world: &World, scale: f64) -> String {
        let frame = Frame::around(world, &self.path, scale);
        let mut svg = String::new();
        self.open(&mut svg, &frame);
        draw_world(&mut svg, world, &frame);
        self.draw_plan(&mut svg, &frame);
        self.draw_perception(&mut svg, &frame);
        self.draw_driven_path(&mut svg, &frame);
        self.draw_cart(&mut svg, world, &frame);
        svg.push_str("</svg>\n");
        svg
    }

    /// The document's head, its white background and the caption.
    fn open(&self, svg: &mut String, frame: &Frame) {
        let (w, h) = frame.size;
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
    }

    /// The planned path, dashed.
    fn draw_plan(&self, svg: &mut String, frame: &Frame) {
        if !self.planned.is_empty() {
            let _ = writeln!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#e69500" stroke-width="2" stroke-dasharray="6 4"><title>planned path</title></polyline>"##,
                frame.points(&self.planned)
            );
        }
    }

    /// What the robot perceived: the sonar echoes, the extracted segments, the followed wall
    /// and the detected dock.
    fn draw_perception(&self, svg: &mut String, frame: &Frame) {
        for p in &self.sonar {
            let (x, y) = frame.at(*p);
            let _ = writeln!(
                svg,
                r##"<circle cx="{x:.2}" cy="{y:.2}" r="1.6" fill="#d33" fill-opacity="0.6"/>"##
            );
        }
        for s in &self.segments {
            frame.line(svg, s, r##"stroke="#1f6fd1" stroke-width="2.5"/>"##);
        }
        if let Some(s) = &self.wall {
            frame.line(
                svg,
                s,
                r##"stroke="#7b2cbf" stroke-width="5" stroke-opacity="0.5"><title>followed wall</title></line>"##,
            );
        }
        if let Some(d) = &self.dock {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="none" stroke="#7b2cbf" stroke-width="2"><title>detected dock</title></polygon>"##,
                frame.points(d)
            );
        }
    }

    /// The path the cart drove (its true poses).
    fn draw_driven_path(&self, svg: &mut String, frame: &Frame) {
        if !self.path.is_empty() {
            let _ = writeln!(
                svg,
                r##"<polyline points="{}" fill="none" stroke="#0a8" stroke-width="2"><title>driven path</title></polyline>"##,
                frame.points(&self.path)
            );
        }
    }

    /// The cart: its footprint at the start (dashed) and at the end (filled).
    fn draw_cart(&self, svg: &mut String, world: &World, frame: &Frame) {
        let start = world.cart.footprint(&world.start);
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="none" stroke="#999" stroke-dasharray="3 3"><title>start</title></polygon>"##,
            frame.points(&start)
        );
        if let Some(f) = &self.footprint {
            let _ = writeln!(
                svg,
                r##"<polygon points="{}" fill="#0a8" fill-opacity="0.35" stroke="#064"><title>final footprint</title></polygon>"##,
                frame.points(f)
            );
        }
    }
}

/// The world itself: the goal area under the walls and the obstacles.
fn draw_world(svg: &mut String, world: &World, frame: &Frame) {
    if let Some(goal) = &world.goal {
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="#c8f0c8" stroke="#3a3" stroke-dasharray="4 3"><title>goal area</title></polygon>"##,
            frame.points(&goal.area.corners())
        );
    }
    for wall in &world.walls {
        let _ = writeln!(
            svg,
            r##"<polyline points="{}" fill="none" stroke="#222" stroke-width="4" stroke-linecap="round"/>"##,
            frame.points(wall)
        );
    }
    for ob in &world.obstacles {
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="#888" stroke="#222"/>"##,
            frame.points(ob)
        );
    }
}

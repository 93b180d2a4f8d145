//! Figures for report pages as inline SVG: a map (a grid image placed by its origin and
//! resolution, as ROS map_server places it) with paths drawn on it, and a chart of values over
//! time. The browser draws the text, so no font file is needed (unlike [`crate::plot`]'s PNGs),
//! lines stay sharp at any zoom, and a map can be zoomed and panned ([`ZOOM_SCRIPT`]).
//!
//! ```
//! use slamkit_eval::report_svg::{map_view, Polyline};
//!
//! let path = [[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]];
//! let svg = map_view(None, &[Polyline { label: "estimate", colour: "#d62728", points: &path }]);
//! assert!(svg.contains("class=\"zoomable\"") && svg.contains("points=\"0.000,-0.000 1.000,-0.000 1.000,-2.000\""));
//! ```

use crate::report_html::base64;
use std::fmt::Write as _;

/// A grid image and where it lies in the map frame (a `map.png` with its `map.yaml`).
#[derive(Debug, Clone, Copy)]
pub struct GridImage<'a> {
    /// The PNG file's bytes; its first row is the grid's top (largest y), as in map_server.
    pub png: &'a [u8],
    /// Width in cells.
    pub width_px: u32,
    /// Height in cells.
    pub height_px: u32,
    /// Map-frame position of the lower-left corner \[m\].
    pub origin_m: [f64; 2],
    /// Cell size \[m\].
    pub resolution_m: f64,
}

impl GridImage<'_> {
    /// `[x_min, y_min, x_max, y_max]` of the image in the map frame \[m\].
    fn bounds(&self) -> [f64; 4] {
        let [x, y] = self.origin_m;
        let r = self.resolution_m;
        [
            x,
            y,
            x + f64::from(self.width_px) * r,
            y + f64::from(self.height_px) * r,
        ]
    }
}

/// A named line: a path on a map (x, y in metres) or a series on a chart (time, value).
#[derive(Debug, Clone, Copy)]
pub struct Polyline<'a> {
    /// Legend text (HTML).
    pub label: &'a str,
    /// CSS colour.
    pub colour: &'a str,
    /// The points, in order.
    pub points: &'a [[f64; 2]],
}

/// Most points drawn per line; longer lines are thinned evenly (first and last kept).
pub const MAX_POINTS: usize = 4000;

/// The map frame seen from above: the grid image under the paths, a start dot and an end
/// ring on each path, a scale bar, and the legend below. The figure fills the page width and
/// zooms with the mouse wheel, pans by dragging, and resets on a double click once the page
/// holds [`ZOOM_SCRIPT`].
pub fn map_view(grid: Option<&GridImage>, paths: &[Polyline]) -> String {
    let mut bounds = grid.map(GridImage::bounds);
    for p in paths.iter().flat_map(|p| p.points) {
        if !(p[0].is_finite() && p[1].is_finite()) {
            continue;
        }
        let b = bounds.get_or_insert([p[0], p[1], p[0], p[1]]);
        *b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    let [x0, y0, x1, y1] = bounds.unwrap_or([-1.0, -1.0, 1.0, 1.0]);
    // a margin, and no side under a quarter of the other (a straight path stays readable)
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let least = (0.25 * (x1 - x0).max(y1 - y0) / 2.0).max(0.05);
    let half_w = ((x1 - x0) / 2.0).max(least) * 1.04;
    let half_h = ((y1 - y0) / 2.0).max(least) * 1.04;
    let (left, top, width, height) = (cx - half_w, -(cy + half_h), 2.0 * half_w, 2.0 * half_h);
    let mut svg = String::new();
    // y is drawn as -y: SVG's y axis points down, the map's up
    let _ = writeln!(
        svg,
        "<svg class=\"zoomable\" xmlns=\"http://www.w3.org/2000/svg\" \
         viewBox=\"{left:.3} {top:.3} {width:.3} {height:.3}\" \
         style=\"width:100%;max-height:85vh;border:1px solid #ccc;background:#fff;cursor:grab\">"
    );
    if let Some(g) = grid {
        let [gx0, _, _, gy1] = g.bounds();
        let _ = writeln!(
            svg,
            "<image x=\"{gx0:.3}\" y=\"{:.3}\" width=\"{:.3}\" height=\"{:.3}\" \
             preserveAspectRatio=\"none\" style=\"image-rendering:pixelated\" \
             href=\"data:image/png;base64,{}\"/>",
            -gy1,
            f64::from(g.width_px) * g.resolution_m,
            f64::from(g.height_px) * g.resolution_m,
            base64(g.png)
        );
    }
    for p in paths {
        let points = thinned(p.points);
        let _ = writeln!(
            svg,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" \
             vector-effect=\"non-scaling-stroke\" stroke-linejoin=\"round\" points=\"{}\"/>",
            p.colour,
            svg_points(&points, |q| [q[0], -q[1]])
        );
        let dot = width.max(height) * 0.006;
        if let (Some(a), Some(b)) = (points.first(), points.last()) {
            let _ = writeln!(
                svg,
                "<circle cx=\"{:.3}\" cy=\"{:.3}\" r=\"{dot:.3}\" fill=\"{c}\"/>\
                 <circle cx=\"{:.3}\" cy=\"{:.3}\" r=\"{dot:.3}\" fill=\"none\" stroke=\"{c}\" \
                 stroke-width=\"1.5\" vector-effect=\"non-scaling-stroke\"/>",
                a[0],
                -a[1],
                b[0],
                -b[1],
                c = p.colour
            );
        }
    }
    // scale bar in the lower left, a round length near a fifth of the width
    let bar = nice_step(width / 5.0);
    let (bx, by) = (left + width * 0.03, top + height * 0.96);
    let font = height * 0.03;
    let _ = writeln!(
        svg,
        "<line x1=\"{bx:.3}\" y1=\"{by:.3}\" x2=\"{:.3}\" y2=\"{by:.3}\" stroke=\"#000\" \
         stroke-width=\"3\" vector-effect=\"non-scaling-stroke\"/>\
         <text x=\"{bx:.3}\" y=\"{:.3}\" font-size=\"{font:.3}\" font-family=\"sans-serif\">{} m</text>",
        bx + bar,
        by - font * 0.5,
        trim_number(bar)
    );
    svg.push_str("</svg>\n");
    svg.push_str(&legend(
        paths,
        "start ●, end ○; wheel: zoom, drag: pan, double click: reset",
    ));
    svg
}

/// Values over time as lines on shared axes: `x_label` under the time axis, `y_label` beside
/// the value axis (which starts at zero when every value is positive).
///
/// ```
/// use slamkit_eval::report_svg::{line_chart, Polyline};
///
/// let errors = [[0.0, 0.01], [1.0, 0.03], [2.0, 0.02]];
/// let svg = line_chart("time [s]", "error [m]", &[Polyline { label: "ATE", colour: "#1f77b4", points: &errors }]);
/// assert!(svg.contains("error [m]") && svg.contains("<polyline"));
/// ```
pub fn line_chart(x_label: &str, y_label: &str, series: &[Polyline]) -> String {
    const W: f64 = 960.0;
    const H: f64 = 300.0;
    const LEFT: f64 = 70.0;
    const RIGHT: f64 = 20.0;
    const TOP: f64 = 15.0;
    const BOTTOM: f64 = 45.0;
    let finite = series
        .iter()
        .flat_map(|s| s.points)
        .filter(|p| p[0].is_finite() && p[1].is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, 0.0_f64, f64::MIN);
    for p in finite {
        (x0, x1) = (x0.min(p[0]), x1.max(p[0]));
        (y0, y1) = (y0.min(p[1]), y1.max(p[1]));
    }
    if x0 > x1 {
        (x0, x1, y1) = (0.0, 1.0, 1.0);
    }
    if x1 - x0 < 1e-9 {
        x1 = x0 + 1.0;
    }
    if y1 - y0 < 1e-12 {
        y1 = y0 + 1.0;
    }
    y1 += (y1 - y0) * 0.05;
    let px = |x: f64| LEFT + (x - x0) / (x1 - x0) * (W - LEFT - RIGHT);
    let py = |y: f64| H - BOTTOM - (y - y0) / (y1 - y0) * (H - TOP - BOTTOM);
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {W} {H}\" \
         style=\"width:100%;max-width:{W}px\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    for (v, horizontal) in ticks(x0, x1)
        .into_iter()
        .map(|v| (v, false))
        .chain(ticks(y0, y1).into_iter().map(|v| (v, true)))
    {
        let (a, b, text) = if horizontal {
            let y = py(v);
            (
                [LEFT, y],
                [W - RIGHT, y],
                format!(
                    "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                    LEFT - 6.0,
                    y + 4.0,
                    trim_number(v)
                ),
            )
        } else {
            let x = px(v);
            (
                [x, TOP],
                [x, H - BOTTOM],
                format!(
                    "<text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
                    H - BOTTOM + 16.0,
                    trim_number(v)
                ),
            )
        };
        let _ = writeln!(
            svg,
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/>{text}",
            a[0], a[1], b[0], b[1]
        );
    }
    let _ = writeln!(
        svg,
        "<rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"#888\"/>\
         <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{x_label}</text>\
         <text transform=\"translate(16 {:.1}) rotate(-90)\" text-anchor=\"middle\">{y_label}</text>",
        W - LEFT - RIGHT,
        H - TOP - BOTTOM,
        (LEFT + W - RIGHT) / 2.0,
        H - 8.0,
        (TOP + H - BOTTOM) / 2.0
    );
    for s in series {
        let _ = writeln!(
            svg,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.2\" points=\"{}\"/>",
            s.colour,
            svg_points(&thinned(s.points), |p| [px(p[0]), py(p[1])])
        );
    }
    svg.push_str("</svg>\n");
    svg.push_str(&legend(series, ""));
    svg
}

/// The script that makes every `svg.zoomable` of a page zoom (wheel, about the pointer), pan
/// (drag) and reset (double click), by changing its `viewBox`. Add it once, at the end.
pub const ZOOM_SCRIPT: &str = r#"<script>
document.querySelectorAll("svg.zoomable").forEach(function (svg) {
  var home = svg.getAttribute("viewBox").split(" ").map(Number), v = home.slice(), drag = null;
  function set() { svg.setAttribute("viewBox", v.join(" ")); }
  function at(e) {
    var r = svg.getBoundingClientRect(), s = Math.max(v[2] / r.width, v[3] / r.height);
    return [v[0] + (e.clientX - r.left - (r.width - v[2] / s) / 2) * s,
            v[1] + (e.clientY - r.top - (r.height - v[3] / s) / 2) * s];
  }
  svg.addEventListener("wheel", function (e) {
    e.preventDefault();
    var p = at(e), k = e.deltaY < 0 ? 0.8 : 1.25;
    v = [p[0] - (p[0] - v[0]) * k, p[1] - (p[1] - v[1]) * k, v[2] * k, v[3] * k];
    set();
  }, { passive: false });
  svg.addEventListener("mousedown", function (e) { e.preventDefault(); drag = at(e); });
  window.addEventListener("mouseup", function () { drag = null; });
  svg.addEventListener("mousemove", function (e) {
    if (!drag) return;
    var p = at(e);
    v[0] += drag[0] - p[0]; v[1] += drag[1] - p[1];
    set();
  });
  svg.addEventListener("dblclick", function () { v = home.slice(); set(); });
});
</script>
"#;

/// The legend under a figure: a coloured swatch and the label of each line, then `note`.
fn legend(lines: &[Polyline], note: &str) -> String {
    let mut html = String::from("<p class=\"legend\">");
    for l in lines {
        let _ = write!(
            html,
            "<span style=\"color:{}\">&#9644;</span> {} &nbsp; ",
            l.colour, l.label
        );
    }
    let _ = writeln!(html, "<small>{note}</small></p>");
    html
}

/// `points`, thinned evenly to at most [`MAX_POINTS`] (first and last kept), non-finite ones
/// left out.
fn thinned(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let finite: Vec<[f64; 2]> = points
        .iter()
        .copied()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect();
    if finite.len() <= MAX_POINTS {
        return finite;
    }
    let last = finite.len() - 1;
    (0..MAX_POINTS)
        .map(|i| finite[i * last / (MAX_POINTS - 1)])
        .collect()
}

/// An SVG `points` attribute of `points` mapped by `to`.
fn svg_points(points: &[[f64; 2]], to: impl Fn([f64; 2]) -> [f64; 2]) -> String {
    let mut text = String::with_capacity(points.len() * 16);
    for (i, p) in points.iter().enumerate() {
        let q = to(*p);
        let sep = if i == 0 { "" } else { " " };
        let _ = write!(text, "{sep}{:.3},{:.3}", q[0], q[1]);
    }
    text
}

/// 1, 2 or 5 times a power of ten, the largest not above `span` (1 for a span that is not a
/// positive number).
fn nice_step(span: f64) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let power = 10f64.powf(span.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * power)
        .find(|s| *s <= span)
        .unwrap_or(power)
}

/// Round tick values inside `[lo, hi]`: about five of them.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step = nice_step((hi - lo) / 5.0);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick value without trailing zeros (`0.05`, `2`, `1.5`).
fn trim_number(v: f64) -> String {
    let text = format!("{v:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_steps_are_one_two_five() {
        assert_eq!(nice_step(7.3), 5.0);
        assert_eq!(nice_step(0.31), 0.2);
        assert_eq!(nice_step(1.0), 1.0);
        assert_eq!(nice_step(0.0), 1.0);
        assert_eq!(
            ticks(0.0, 1.0),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        assert_eq!(trim_number(0.6000000000000001), "0.6");
        assert_eq!(trim_number(-0.0), "0");
    }

    #[test]
    fn long_lines_are_thinned_keeping_the_ends() {
        let line: Vec<[f64; 2]> = (0..10_000).map(|i| [f64::from(i), 0.0]).collect();
        let t = thinned(&line);
        assert_eq!(t.len(), MAX_POINTS);
        assert_eq!((t[0], t[MAX_POINTS - 1]), (line[0], line[9999]));
        assert_eq!(thinned(&[[f64::NAN, 0.0], [1.0, 2.0]]), vec![[1.0, 2.0]]);
    }

    #[test]
    fn the_grid_image_is_placed_by_its_origin_with_y_up() {
        let grid = GridImage {
            png: b"png",
            width_px: 200,
            height_px: 100,
            origin_m: [-5.0, -2.0],
            resolution_m: 0.05,
        };
        let svg = map_view(Some(&grid), &[]);
        // 10 m x 5 m, its top edge (y = 3 m) at SVG y = -3
        assert!(svg.contains("<image x=\"-5.000\" y=\"-3.000\" width=\"10.000\" height=\"5.000\""));
        // the view holds the image with a 4 % margin: 5.2 x 2.6 m half sizes around (0, 0.5)
        assert!(
            svg.contains("viewBox=\"-5.200 -3.100 10.400 5.200\""),
            "{svg}"
        );
    }

    #[test]
    fn charts_survive_empty_and_flat_series() {
        for points in [
            &[][..],
            &[[1.0, 0.0], [1.0, 0.0]][..],
            &[[f64::NAN, 1.0]][..],
        ] {
            let svg = line_chart(
                "t",
                "e",
                &[Polyline {
                    label: "x",
                    colour: "red",
                    points,
                }],
            );
            assert!(svg.starts_with("<svg") && !svg.contains("NaN") && !svg.contains("inf"));
        }
    }
}

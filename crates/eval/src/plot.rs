//! Figures of an evaluation: the top view (x–y) of the reference and the aligned estimate, and
//! the error over time, side by side, written as PNG or SVG by the file extension.
//!
//! Text needs a font. The bitmap and SVG backends both measure text with a TrueType font, which
//! is loaded once at run time from `SLAMKIT_FONT` or a common system path (DejaVu, Liberation,
//! Arial). When no font is found the figure is drawn without any text (no title, ticks or
//! legend) rather than failing.

use crate::EvalError;
use nalgebra::Point3;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use slamkit_core::Trajectory;
use slamkit_io::output_folder::write_via_temp;
use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

/// The paths to draw in the top view, in the reference frame \[m\].
#[derive(Debug, Clone, Copy)]
pub struct TopView<'a> {
    /// Ground-truth positions.
    pub reference: &'a [Point3<f64>],
    /// Estimated positions, aligned onto the reference.
    pub estimate: &'a [Point3<f64>],
}

/// The errors to draw over time.
#[derive(Debug, Clone, Copy)]
pub struct ErrorSeries<'a> {
    /// Figure title, e.g. `"ATE (se3)"`.
    pub title: &'a str,
    /// Axis label of the error, e.g. `"error [m]"`.
    pub label: &'a str,
    /// Time of each error \[s\].
    pub timestamps: &'a [f64],
    /// The errors.
    pub errors: &'a [f64],
}

/// Figure size in pixels (two panels).
const SIZE: (u32, u32) = (1400, 620);

/// Writes the top view and the error series to `path` (`.png` or `.svg`).
///
/// # Errors
/// [`EvalError::UnsupportedPlotFormat`] for another extension, [`EvalError::Plot`] when drawing
/// or writing fails.
pub fn plot_errors(path: &Path, view: &TopView, series: &ErrorSeries) -> Result<(), EvalError> {
    // Drawn into a temporary file, then renamed: a reader never sees half a figure.
    write_via_temp(path, |tmp| plot_with(tmp, view, series, font_available())).map_err(
        |e| match e {
            EvalError::Plot { message, .. } => EvalError::Plot {
                path: path.to_path_buf(),
                message,
            },
            EvalError::UnsupportedPlotFormat { .. } => EvalError::UnsupportedPlotFormat {
                path: path.to_path_buf(),
            },
            other => other,
        },
    )
}

/// Writes a position-error figure (error label `position error [m]`): the reference and the
/// estimate seen from above beside `errors` over `timestamps`.
///
/// # Errors
/// As [`plot_errors`].
pub fn plot_position_errors(
    path: &Path,
    title: &str,
    view: &TopView,
    timestamps: &[f64],
    errors: &[f64],
) -> Result<(), EvalError> {
    let series = ErrorSeries {
        title,
        label: "position error [m]",
        timestamps,
        errors,
    };
    plot_errors(path, view, &series)
}

/// The positions of a trajectory's poses, in order: what a [`TopView`] draws.
pub fn positions(trajectory: &Trajectory) -> Vec<Point3<f64>> {
    trajectory
        .poses
        .iter()
        .map(|p| Point3::from(p.pose.translation.vector))
        .collect()
}

fn plot_with(
    path: &Path,
    view: &TopView,
    series: &ErrorSeries,
    text: bool,
) -> Result<(), EvalError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let result = match ext.as_deref() {
        Some("png") => draw(
            BitMapBackend::new(path, SIZE).into_drawing_area(),
            view,
            series,
            text,
        ),
        Some("svg") => draw(
            SVGBackend::new(path, SIZE).into_drawing_area(),
            view,
            series,
            text,
        ),
        _ => {
            return Err(EvalError::UnsupportedPlotFormat {
                path: path.to_path_buf(),
            })
        }
    };
    result.map_err(|message| EvalError::Plot {
        path: path.to_path_buf(),
        message,
    })
}

/// Registers a system font for plotters once; true when text can be drawn.
fn font_available() -> bool {
    static FONT: OnceLock<bool> = OnceLock::new();
    *FONT.get_or_init(|| {
        let env = std::env::var_os("SLAMKIT_FONT").map(std::path::PathBuf::from);
        let candidates = [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
            "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
            "/System/Library/Fonts/Supplemental/Arial.ttf",
            "/Library/Fonts/Arial.ttf",
            "C:\\Windows\\Fonts\\arial.ttf",
        ];
        env.into_iter()
            .chain(candidates.iter().map(std::path::PathBuf::from))
            .filter_map(|p| std::fs::read(p).ok())
            .any(|bytes| {
                // plotters keeps fonts for the whole process: leak the one font we load.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
            })
    })
}

type DrawResult = Result<(), String>;

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    view: &TopView,
    series: &ErrorSeries,
    text: bool,
) -> DrawResult {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let root = if text {
        root.titled(series.title, ("sans-serif", 24))
            .map_err(|e| e.to_string())?
    } else {
        root
    };
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    draw_top_view(&left, view, text)?;
    draw_error_series(&right, series, text)?;
    root.present().map_err(|e| e.to_string())
}

fn draw_top_view<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    view: &TopView,
    text: bool,
) -> DrawResult {
    let xy = |pts: &[Point3<f64>]| -> Vec<(f64, f64)> {
        pts.iter()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .map(|p| (p.x, p.y))
            .collect()
    };
    let (reference, estimate) = (xy(view.reference), xy(view.estimate));
    let all = reference.iter().chain(&estimate);
    let x = padded_range(all.clone().map(|p| p.0));
    let y = padded_range(all.map(|p| p.1));
    // same metres per pixel on both axes
    let half = 0.5 * (x.end - x.start).max(y.end - y.start);
    let (cx, cy) = (0.5 * (x.start + x.end), 0.5 * (y.start + y.end));
    let mut chart = chart_builder(area, text)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)
        .map_err(|e| e.to_string())?;
    configure_mesh(&mut chart, "x [m]", "y [m]", text)?;
    let paths = [
        (reference, BLACK, "ground truth"),
        (estimate, RED, "estimate"),
    ];
    for (points, color, name) in paths {
        let drawn = chart
            .draw_series(LineSeries::new(points, color.stroke_width(2)))
            .map_err(|e| e.to_string())?;
        if text {
            drawn
                .label(name)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
        }
    }
    if text {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn draw_error_series<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    series: &ErrorSeries,
    text: bool,
) -> DrawResult {
    let t0 = series
        .timestamps
        .iter()
        .copied()
        .find(|t| t.is_finite())
        .unwrap_or(0.0);
    let points: Vec<(f64, f64)> = series
        .timestamps
        .iter()
        .zip(series.errors)
        .map(|(t, e)| (t - t0, *e))
        .filter(|(t, e)| t.is_finite() && e.is_finite())
        .collect();
    let x = padded_range(points.iter().map(|p| p.0));
    let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
    let y = 0.0..if top > 0.0 { top * 1.05 } else { 1.0 };
    let mut chart = chart_builder(area, text)
        .build_cartesian_2d(x, y)
        .map_err(|e| e.to_string())?;
    configure_mesh(&mut chart, "time from start [s]", series.label, text)?;
    chart
        .draw_series(LineSeries::new(points, BLUE.stroke_width(1)))
        .map_err(|e| e.to_string())?;
    Ok(())
}

fn chart_builder<'a, 'b, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    text: bool,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(area);
    builder.margin(15);
    if text {
        builder.x_label_area_size(45).y_label_area_size(70);
    }
    builder
}

fn configure_mesh<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    x_desc: &str,
    y_desc: &str,
    text: bool,
) -> DrawResult {
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc(x_desc).y_desc(y_desc);
    } else {
        mesh.x_labels(0).y_labels(0);
    }
    mesh.draw().map_err(|e| e.to_string())
}

/// The span of `values` with 5 % margins; `0..1` when there is none.
fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
    lo - pad..hi + pad
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, r: f64) -> Vec<Point3<f64>> {
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.1;
                Point3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn writes_png_and_svg_with_and_without_text() {
        let dir = tempfile::tempdir().unwrap();
        let (gt, est) = (circle(60, 2.0), circle(60, 2.1));
        let view = TopView {
            reference: &gt,
            estimate: &est,
        };
        let times: Vec<f64> = (0..60).map(|i| 100.0 + i as f64 * 0.1).collect();
        let errors = vec![0.1; 60];
        let series = ErrorSeries {
            title: "ATE (se3)",
            label: "error [m]",
            timestamps: &times,
            errors: &errors,
        };
        for (name, text) in [
            ("a.png", true),
            ("b.png", false),
            ("c.svg", true),
            ("d.svg", false),
        ] {
            let path = dir.path().join(name);
            let text = text && font_available();
            plot_with(&path, &view, &series, text).unwrap();
            let len = std::fs::metadata(&path).unwrap().len();
            assert!(len > 1000, "{name}: {len} bytes");
        }
    }

    #[test]
    fn position_errors_are_drawn_from_trajectories_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let mut t = Trajectory::new();
        for i in 0..30 {
            let p = slamkit_core::Pose3::translation(i as f64 * 0.1, 1.0, 2.0);
            t.push(i as f64, p);
        }
        let points = positions(&t);
        assert_eq!(points.len(), 30);
        assert_eq!(points[3], Point3::new(0.30000000000000004, 1.0, 2.0));
        let view = TopView {
            reference: &points,
            estimate: &points,
        };
        let times: Vec<f64> = (0..30).map(f64::from).collect();
        let path = dir.path().join("errors.png");
        plot_position_errors(&path, "test", &view, &times, &[0.0; 30]).unwrap();
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "no temporary file is left");
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
    }

    #[test]
    fn degenerate_input_and_bad_names_do_not_panic() {
        let dir = tempfile::tempdir().unwrap();
        let nan = [Point3::new(f64::NAN, 0.0, 0.0)];
        let view = TopView {
            reference: &nan,
            estimate: &[],
        };
        let series = ErrorSeries {
            title: "empty",
            label: "m",
            timestamps: &[],
            errors: &[],
        };
        plot_errors(&dir.path().join("e.svg"), &view, &series).unwrap();
        assert!(matches!(
            plot_errors(&dir.path().join("e.jpg"), &view, &series),
            Err(EvalError::UnsupportedPlotFormat { .. })
        ));
        assert!(matches!(
            plot_errors(&dir.path().join("missing/dir/e.png"), &view, &series),
            Err(EvalError::Plot { .. })
        ));
    }
}

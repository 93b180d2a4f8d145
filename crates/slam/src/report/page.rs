//! `report.html` of a run, built from what the run wrote in its output folder and from its
//! `report.json`, the same for every command (`lidar`, `vo`, `nav`, `map merge`, `demo`, ...):
//! the run's own summary when its report has one (`summary`, the table `demo` prints), the
//! numbers that matter, the map with the trajectories (and the ground truth) drawn on it
//! (zoomable), the error over time against ground truth or the benchmark's relations, the
//! per-stage timings, and the other pictures of the folder.
//!
//! A part that cannot be drawn (a trajectory file the run did not write, a relations file
//! that is gone) is said on the page instead; only writing the page can fail.

use serde_json::Value;
use slamkit_core::Trajectory;
use slamkit_eval::report_html::HtmlReport;
use slamkit_eval::report_svg::{line_chart, map_view, GridImage, Polyline, ZOOM_SCRIPT};
use slamkit_eval::{ate, relation_errors, Alignment, Pairing, DEFAULT_MAX_DIFF_S};
use slamkit_io::trajectory_file::read_trajectory;
use std::path::{Path, PathBuf};

use crate::SlamError;

/// Colours of the lines, in order (matplotlib's default cycle, which people read easily).
const PALETTE: &[&str] = &[
    "#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

/// The ground-truth line's colour.
const TRUTH: &str = "#555555";

/// Writes `dir/report.html` for the run whose outputs are in `dir` and whose `report.json`
/// holds `report`; `title` heads the page (`"slamkit lidar"`).
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// std::fs::write(dir.path().join("trajectory.tum"), "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n").unwrap();
/// let report = serde_json::json!({
///     "input": "log.clf", "wall_seconds": 1.5,
///     "timings_ms": { "icp": { "count": 2, "median_ms": 0.5, "p95_ms": 0.9, "total_ms": 1200.0 } },
/// });
/// slamkit_slam::report::page::write_run_page(dir.path(), "slamkit lidar", &report).unwrap();
/// let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
/// assert!(html.contains("<td>icp</td><td>2</td><td>0.50</td><td>0.90</td><td>1.2</td>"));
/// assert!(html.contains("<polyline") && html.contains("trajectory"));
/// ```
///
/// # Errors
/// [`SlamError::Report`] when the page cannot be written.
pub fn write_run_page(dir: &Path, title: &str, report: &Value) -> Result<(), SlamError> {
    let mut page = HtmlReport::new(title);
    if let Some(input) = report.get("input").filter(|v| !v.is_null()) {
        let text = input
            .as_str()
            .map_or_else(|| input.to_string(), str::to_owned);
        page.paragraph(&format!("Input: <code>{}</code>", escape(&text)));
    }
    if let Some(summary) = report.get("summary").and_then(Value::as_str) {
        page.raw(&format!(
            "<pre style=\"white-space: pre-wrap\">{}</pre>",
            escape(summary)
        ));
    }
    let rows = summary_rows(report);
    if !rows.is_empty() {
        page.heading(2, "Summary");
        page.table(&["quantity", "value"], &rows);
    }
    let truth = read_if_present(&dir.join("groundtruth.tum"));
    let grid = read_grid(dir);
    map_section(&mut page, dir, grid.as_ref(), truth.as_ref());
    errors_section(&mut page, dir, report, truth.as_ref());
    let timings = timing_rows(report);
    if !timings.is_empty() {
        page.heading(2, "Time per stage");
        page.table(
            &["stage", "count", "median [ms]", "p95 [ms]", "total [s]"],
            &timings,
        );
    }
    let map_drawn = grid.is_some_and(|g| g.is_ok());
    pictures_section(&mut page, dir, map_drawn)?;
    page.raw(ZOOM_SCRIPT);
    Ok(page.write(&dir.join("report.html"))?)
}

/// The map (`map.png` placed by `map.yaml`) with every `trajectory*.tum` of `dir` on it; with
/// ground truth and no map, the truth and the estimate aligned onto it (as ATE aligns them).
fn map_section(
    page: &mut HtmlReport,
    dir: &Path,
    grid: Option<&Result<GridBytes, String>>,
    truth: Option<&Result<Trajectory, String>>,
) {
    let estimate = read_if_present(&dir.join("trajectory.tum"));
    let mut lines: Vec<(String, &str, Vec<[f64; 2]>)> = Vec::new();
    let mut notes = Vec::new();
    match (&grid, truth, &estimate) {
        (None, Some(Ok(truth)), Some(Ok(estimate))) => {
            match ate(truth, estimate, nearest(), Alignment::Se3) {
                Ok(a) => {
                    let xy = |p: &[nalgebra::Point3<f64>]| p.iter().map(|q| [q.x, q.y]).collect();
                    lines.push(("ground truth".into(), TRUTH, xy(&a.reference_positions)));
                    lines.push((
                        "estimate (aligned, SE(3))".into(),
                        PALETTE[0],
                        xy(&a.aligned_estimate_positions),
                    ));
                }
                Err(e) => notes.push(format!("the estimate cannot be aligned: {e}")),
            }
        }
        _ => {
            if let (Some(_), Some(Ok(truth))) = (&grid, truth) {
                lines.push(("ground truth".into(), TRUTH, xy_of(truth)));
            }
            for (i, (name, trajectory)) in trajectories(dir).into_iter().enumerate() {
                match trajectory {
                    Ok(t) => lines.push((name, PALETTE[i % PALETTE.len()], xy_of(&t))),
                    Err(e) => notes.push(e),
                }
            }
        }
    }
    if let Some(Err(e)) = &grid {
        notes.push(e.clone());
    }
    let grid_bytes = grid.and_then(|g| g.as_ref().ok());
    if lines.is_empty() && grid_bytes.is_none() {
        for note in notes {
            page.paragraph(&escape(&note));
        }
        return;
    }
    page.heading(
        2,
        if grid_bytes.is_some() {
            "Map"
        } else {
            "Trajectory from above"
        },
    );
    let polylines: Vec<Polyline> = lines
        .iter()
        .map(|(label, colour, points)| Polyline {
            label,
            colour,
            points,
        })
        .collect();
    let image = grid_bytes.map(|g| GridImage {
        png: &g.png,
        width_px: g.width_px,
        height_px: g.height_px,
        origin_m: g.origin_m,
        resolution_m: g.resolution_m,
    });
    page.raw(&map_view(image.as_ref(), &polylines));
    for note in notes {
        page.paragraph(&escape(&note));
    }
}

/// The error over time: ATE per pose against `groundtruth.tum`, or the relations' errors
/// against the benchmark's `.relations` file named in `report.json`.
fn errors_section(
    page: &mut HtmlReport,
    dir: &Path,
    report: &Value,
    truth: Option<&Result<Trajectory, String>>,
) {
    let estimate = || read_if_present(&dir.join("trajectory.tum"));
    if let (Some(Ok(truth)), Some(Ok(estimate))) = (truth, estimate()) {
        page.heading(2, "Position error over time (ATE, SE(3) alignment)");
        match ate(truth, &estimate, nearest(), Alignment::Se3) {
            Ok(a) => {
                let points = since_start(
                    a.timestamps
                        .iter()
                        .zip(&a.errors_m)
                        .map(|(t, e)| [*t, *e])
                        .collect(),
                );
                let label = format!("RMSE {:.4} m over {} poses", a.stats.rmse, a.stats.pairs);
                page.raw(&line_chart(
                    "time since the first pose [s]",
                    "position error [m]",
                    &[Polyline {
                        label: &label,
                        colour: PALETTE[0],
                        points: &points,
                    }],
                ));
            }
            Err(e) => page.paragraph(&escape(&format!("not scored: {e}"))),
        }
    }
    let Some(file) = report
        .pointer("/metrics/relations_file")
        .and_then(Value::as_str)
    else {
        return;
    };
    let Some(Ok(estimate)) = estimate() else {
        return;
    };
    page.heading(2, "Relations error over time");
    let scored = slamkit_io::relations::read_relations(Path::new(file))
        .map_err(|e| e.to_string())
        .and_then(|r| relation_errors(&r, &estimate).map_err(|e| e.to_string()));
    match scored {
        Ok(errors) => {
            let points = since_start(errors.iter().map(|e| [e.t1, e.trans_m]).collect());
            let label = format!(
                "translational error of each of {} relations, at its first time ({})",
                errors.len(),
                escape(file)
            );
            page.raw(&line_chart(
                "time since the first relation [s]",
                "error [m]",
                &[Polyline {
                    label: &label,
                    colour: PALETTE[1],
                    points: &points,
                }],
            ));
        }
        Err(e) => page.paragraph(&escape(&format!("not drawn: {e}"))),
    }
}

/// `points` sorted by time, with the first time subtracted (a log's stamps are seconds since
/// 1970, and a relations file is not in time order).
fn since_start(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let t0 = points.first().map_or(0.0, |p| p[0]);
    points.iter().map(|p| [p[0] - t0, p[1]]).collect()
}

/// Every PNG of `dir` but `map.png` when the map section drew it, and those of its
/// sub-folders one level down (the drone's layer maps), each under its name.
fn pictures_section(page: &mut HtmlReport, dir: &Path, map_drawn: bool) -> Result<(), SlamError> {
    let mut pngs: Vec<PathBuf> = Vec::new();
    for folder in std::iter::once(dir.to_path_buf()).chain(sub_folders(dir)) {
        pngs.extend(files_with_extension(&folder, "png"));
    }
    pngs.retain(|p| {
        !(map_drawn && p == &dir.join("map.png")) && p.file_name() != Some("report.png".as_ref())
    });
    if pngs.is_empty() {
        return Ok(());
    }
    page.heading(2, "Pictures");
    for png in pngs {
        let name = png.strip_prefix(dir).unwrap_or(&png).display().to_string();
        page.heading(3, &escape(&name));
        page.image(&escape(&name), &png, true)?;
    }
    Ok(())
}

/// The rows of the summary: wall time, peak memory, then the scalar fields of `frames`,
/// `stats` and (flattened) `metrics`.
fn summary_rows(report: &Value) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    if let Some(s) = report.get("wall_seconds").and_then(Value::as_f64) {
        rows.push(vec!["wall time".into(), format!("{s:.1} s")]);
    }
    if let Some(b) = report.get("peak_rss_bytes").and_then(Value::as_f64) {
        rows.push(vec![
            "peak memory".into(),
            format!("{:.0} MiB", b / 1048576.0),
        ]);
    }
    for section in ["frames", "stats"] {
        if let Some(object) = report.get(section).and_then(Value::as_object) {
            for (key, value) in object {
                if let Some(text) = scalar(value) {
                    let name = if key == section {
                        section.to_owned()
                    } else {
                        format!("{section} {}", key.replace('_', " "))
                    };
                    rows.push(vec![name, text]);
                }
            }
        }
    }
    if let Some(metrics) = report.get("metrics") {
        flatten(metrics, "", &mut |key, value| {
            if let Some(text) = scalar(value) {
                rows.push(vec![escape(&key.replace('_', " ")), escape(&text)]);
            }
        });
    }
    rows
}

/// A row per stage of every `timings_ms` object in `report` (its path before the stage's name
/// when nested, e.g. `vo.track`; a group of stages inside one, e.g. `timings_ms.icp`, the
/// same).
fn timing_rows(report: &Value) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    collect_timings(report, "", &mut rows);
    rows
}

fn collect_timings(value: &Value, prefix: &str, rows: &mut Vec<Vec<String>>) {
    let Some(object) = value.as_object() else {
        return;
    };
    for (key, child) in object {
        if key == "timings_ms" {
            timing_group(child, prefix, rows);
        } else if key != "config" {
            collect_timings(child, &format!("{prefix}{key}."), rows);
        }
    }
}

/// The stages of a `timings_ms` object, and of the groups of stages in it.
fn timing_group(value: &Value, prefix: &str, rows: &mut Vec<Vec<String>>) {
    for (stage, t) in value.as_object().into_iter().flatten() {
        let number = |k: &str| t.get(k).and_then(Value::as_f64);
        let (Some(count), Some(median), Some(p95), Some(total)) = (
            number("count"),
            number("median_ms"),
            number("p95_ms"),
            number("total_ms"),
        ) else {
            timing_group(t, &format!("{prefix}{stage}."), rows);
            continue;
        };
        rows.push(vec![
            escape(&format!("{prefix}{stage}")),
            format!("{count:.0}"),
            format!("{median:.2}"),
            format!("{p95:.2}"),
            format!("{:.1}", total / 1000.0),
        ]);
    }
}

/// Calls `visit` with the dotted path and value of every leaf of `value`.
fn flatten(value: &Value, prefix: &str, visit: &mut dyn FnMut(&str, &Value)) {
    match value {
        Value::Object(object) => {
            for (key, child) in object {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix} {key}")
                };
                flatten(child, &path, visit);
            }
        }
        Value::Array(_) => {}
        leaf => visit(prefix, leaf),
    }
}

/// A number (4 significant decimals at most) or a string, as a table cell; `None` for the rest.
fn scalar(value: &Value) -> Option<String> {
    match value {
        Value::Number(n) if n.is_u64() || n.is_i64() => Some(n.to_string()),
        Value::Number(n) => n.as_f64().map(|x| {
            if x != 0.0 && x.abs() < 0.01 {
                format!("{x:.3e}")
            } else {
                format!("{x:.4}")
            }
        }),
        Value::String(s) => Some(s.clone()),
        Value::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

/// `map.png` and where `map.yaml` puts it; `None` without them. The picture may be drawn
/// larger than the grid (`slamkit nav`'s is three pixels a cell): its pixel size is the
/// grid's scaled by the width of the YAML's image over the picture's.
fn read_grid(dir: &Path) -> Option<Result<GridBytes, String>> {
    let (png, yaml) = (dir.join("map.png"), dir.join("map.yaml"));
    if !(png.is_file() && yaml.is_file()) {
        return None;
    }
    let read = || -> Result<GridBytes, String> {
        let text =
            std::fs::read_to_string(&yaml).map_err(|e| format!("{}: {e}", yaml.display()))?;
        let meta = slamkit_map::grid_io::parse_map_yaml(&text, &yaml).map_err(|e| e.to_string())?;
        let (width_px, height_px) =
            image::image_dimensions(&png).map_err(|e| format!("{}: {e}", png.display()))?;
        let bytes = std::fs::read(&png).map_err(|e| format!("{}: {e}", png.display()))?;
        let grid_width = std::fs::read(dir.join(&meta.image))
            .ok()
            .and_then(|pgm| slamkit_map::grid_io::parse_pgm(&pgm).ok())
            .map_or(width_px as usize, |(width, _, _)| width);
        Ok(GridBytes {
            png: bytes,
            width_px,
            height_px,
            origin_m: [meta.origin[0], meta.origin[1]],
            resolution_m: meta.resolution_m * grid_width as f64 / f64::from(width_px.max(1)),
        })
    };
    Some(read())
}

/// A grid image read from the folder.
struct GridBytes {
    png: Vec<u8>,
    width_px: u32,
    height_px: u32,
    origin_m: [f64; 2],
    resolution_m: f64,
}

/// Every `trajectory*.tum` of `dir`, by name, read (or why not).
fn trajectories(dir: &Path) -> Vec<(String, Result<Trajectory, String>)> {
    files_with_extension(dir, "tum")
        .into_iter()
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("trajectory"))
        })
        .map(|p| {
            let name = p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            (escape(&name), read(&p))
        })
        .collect()
}

/// The trajectory at `path` if the file exists.
fn read_if_present(path: &Path) -> Option<Result<Trajectory, String>> {
    path.is_file().then(|| read(path))
}

fn read(path: &Path) -> Result<Trajectory, String> {
    read_trajectory(path)
        .map(|(t, _)| t)
        .map_err(|e| format!("{}: {e}", path.display()))
}

fn xy_of(trajectory: &Trajectory) -> Vec<[f64; 2]> {
    trajectory
        .poses
        .iter()
        .map(|p| [p.pose.translation.vector.x, p.pose.translation.vector.y])
        .collect()
}

/// Pairing by nearest time, as `slamkit eval ate` pairs TUM files.
fn nearest() -> Pairing {
    Pairing::NearestTime {
        max_diff_s: DEFAULT_MAX_DIFF_S,
    }
}

/// The files of `dir` ending in `.ext`, sorted by name.
fn files_with_extension(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    files
}

/// The sub-folders of `dir` (not hidden: a run's staging folder is), sorted by name.
fn sub_folders(dir: &Path) -> Vec<PathBuf> {
    let mut folders: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_dir()
                && !p
                    .file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .collect();
    folders.sort();
    folders
}

/// `text` with HTML's special characters escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn nested_timings_are_named_by_their_path() {
        let t = json!({ "count": 3, "median_ms": 1.0, "p95_ms": 2.0, "total_ms": 3500.0 });
        let report = json!({
            "timings_ms": { "a": t },
            "vo": { "timings_ms": { "track": t } },
            "config": { "timings_ms": { "ignored": t } },
        });
        let names: Vec<String> = timing_rows(&report)
            .into_iter()
            .map(|r| r[0].clone())
            .collect();
        assert_eq!(names, ["a", "vo.track"]);
        assert_eq!(timing_rows(&report)[0][4], "3.5");
    }

    #[test]
    fn the_summary_flattens_metrics_and_skips_lists() {
        let report = json!({
            "wall_seconds": 2.0,
            "frames": { "read": 10, "lost": 0, "log": [1, 2] },
            "metrics": { "ate": { "rmse": 0.0351, "min": 0.004 }, "relations_file": "x<y" },
        });
        let rows = summary_rows(&report);
        let text: Vec<String> = rows.iter().map(|r| r.join("=")).collect();
        assert_eq!(
            text,
            [
                "wall time=2.0 s",
                "frames lost=0",
                "frames read=10",
                "ate min=4.000e-3",
                "ate rmse=0.0351",
                "relations file=x&lt;y",
            ]
        );
    }

    #[test]
    fn relations_errors_are_drawn_in_time_order_from_the_first() {
        let dir = tempfile::tempdir().unwrap();
        // the estimate moves 1 m along x per second; the relations say 1 m, then 1.5 m
        let tum: String = (0..4)
            .map(|i| format!("{}.0 {i} 0 0 0 0 0 1\n", 100 + i))
            .collect();
        std::fs::write(dir.path().join("trajectory.tum"), tum).unwrap();
        let relations = dir.path().join("log.relations");
        std::fs::write(
            &relations,
            "102.0 103.0 1.5 0 0 0 0 0\n100.0 101.0 1.0 0 0 0 0 0\n",
        )
        .unwrap();
        let report = json!({ "metrics": { "relations_file": relations } });
        write_run_page(dir.path(), "t", &report).unwrap();
        let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        assert!(html.contains("Relations error over time"), "{html}");
        // t = 0 s: error 0 m; t = 2 s: error 0.5 m, on a chart whose axes run 0..2 s, 0..0.525 m
        assert!(
            html.contains("points=\"70.000,255.000 940.000,26.429\""),
            "{html}"
        );
    }

    #[test]
    fn a_broken_trajectory_is_said_not_fatal() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("trajectory.tum"), "not a trajectory\n").unwrap();
        write_run_page(dir.path(), "t", &json!({})).unwrap();
        let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        assert!(html.contains("trajectory.tum"), "{html}");
    }
}

//! Maps a robot can plan in, built from a visual run's keyframes at their final (loop-closed)
//! poses (issue 20, item 7).
//!
//! RGB-D: every `depth_step_px`-th depth pixel of each keyframe goes, as a ray from the
//! camera, into
//! * an occupancy octree with OctoMap's semantics ([`Octree`], 9 cm voxels; written as
//!   `octree.bt`), and
//! * a 2D floor grid ([`FloorGrid`], [`FloorGridMethod::PointCount`]: points 0.1–1.0 m above
//!   the floor counted per cell, a cell with `min_points` of them an obstacle, cells crossed by a
//!   Bresenham ray from the camera to a point at most 1 m high free; written as
//!   `floor.pgm/.yaml/.png`: not `map.*`, which a run's page draws the trajectories on, and
//!   this grid is in the floor-aligned frame, not the trajectory's).
//!
//! Both live in a floor-aligned frame found on the data, not from a known camera mount: planes
//! are taken out of the keyframes' points one after the other by RANSAC
//! ([`fit_floor_ransac`]); those whose normal lies within `max_floor_tilt_deg` of "up" (the
//! mean of the keyframe cameras' −y axes: a hand-held or robot camera is held roughly upright,
//! its image rows level) are horizontal, and the floor is the horizontal plane lowest under the
//! cameras (a table top or counter is horizontal too, but higher). The map frame has z up, the
//! floor at z = 0, and x, y on the floor; the grid's cell (i, j) is the map's (x, y).
//!
//! Stereo keyframes get no map yet (the report says so).

use nalgebra::{Point2, Point3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::Image;
use slamkit_core::Pose3;
use slamkit_io::{Dataset, IoError};
use slamkit_map::floor::{fit_floor_ransac, rotation_between, FloorConfig, Plane};
use slamkit_map::floor_grid::{depth_points, FloorGrid, FloorGridConfig, FloorGridMethod};
use slamkit_map::grid_io::{save_image_png, save_image_yaml, tri_grid_image};
use slamkit_map::octree::bt::write_bt;
use slamkit_map::{Occupancy, Octree, OctreeConfig, OctreeStats, TriGrid};
use std::collections::HashMap;
use std::path::Path;

use crate::ground_robot::map_from_world as zup_to_floor;
use crate::SlamError;

/// Settings of the maps built from the keyframes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlanningMapConfig {
    /// Every this-many-th depth pixel of a keyframe, in rows and columns, is mapped \[px\].
    pub depth_step_px: usize,
    /// Depth farther from the camera than this is left out of both maps \[m\] (depth noise
    /// grows with the square of the range; Kinect-class cameras are specified to about 4.5 m).
    pub max_range_m: f64,
    /// The octree (`resolution_m` 9 cm, OctoMap's sensor model).
    pub octree: OctreeConfig,
    /// The floor grid (cell size, obstacle band above the floor, points per obstacle cell).
    pub grid: FloorGridConfig,
    /// RANSAC plane fit of each plane taken out of the points.
    pub floor: FloorConfig,
    /// Planes taken out of the points in turn while looking for the floor.
    pub max_planes: usize,
    /// A plane whose normal is farther than this from the cameras' up is not horizontal \[deg\].
    pub max_floor_tilt_deg: f64,
    /// Points given to the plane fits, spread evenly over the keyframes' points.
    pub floor_sample_points: usize,
    /// Largest grid side \[cells\]: a longer one means the poses are broken.
    pub max_grid_cells: usize,
}

impl Default for PlanningMapConfig {
    fn default() -> Self {
        Self {
            depth_step_px: 4,
            max_range_m: 5.0,
            octree: OctreeConfig {
                resolution_m: 0.09,
                ..OctreeConfig::default()
            },
            grid: FloorGridConfig::default(),
            floor: FloorConfig {
                threshold_m: 0.03,
                min_inliers: 300,
                ..FloorConfig::default()
            },
            max_planes: 6,
            max_floor_tilt_deg: 30.0,
            floor_sample_points: 30_000,
            max_grid_cells: 4096,
        }
    }
}

/// The floor found on the data.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FoundFloor {
    /// The floor's upward unit normal in the world frame.
    pub normal_world: [f64; 3],
    /// Angle between that normal and the cameras' mean up \[deg\].
    pub tilt_from_camera_up_deg: f64,
    /// Height of the first keyframe's camera above the floor \[m\].
    pub first_camera_height_m: f64,
    /// Sampled points within the RANSAC threshold of the floor.
    pub inliers: usize,
    /// Planes taken out before (and including) the floor.
    pub planes_tried: usize,
}

/// What the RGB-D maps hold.
#[derive(Debug, Clone, Serialize)]
pub struct RgbdMapsSummary {
    /// Keyframes mapped.
    pub keyframes: usize,
    /// The floor; `None` when none was found (then only the octree is written, in the world
    /// frame).
    pub floor: Option<FoundFloor>,
    /// Why no floor was found.
    pub floor_error: Option<String>,
    /// `map_from_world` as `[tx, ty, tz, qx, qy, qz, qw]` (identity without a floor).
    pub map_from_world: [f64; 7],
    /// Octree size.
    pub octree: OctreeStats,
    /// Grid cells (width, height), free and occupied; `None` without a floor.
    pub grid: Option<GridSummary>,
}

/// Size and content of the floor grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GridSummary {
    /// Cells along x.
    pub width: usize,
    /// Cells along y.
    pub height: usize,
    /// Cell side \[m\].
    pub resolution_m: f64,
    /// Free cells.
    pub free: usize,
    /// Occupied cells.
    pub occupied: usize,
}

/// The RGB-D maps built from keyframes.
#[derive(Debug, Clone)]
pub struct RgbdMaps {
    /// The octree in the map frame.
    pub octree: Octree,
    /// The floor grid over the map's (x, y); `None` when no floor was found.
    pub grid: Option<TriGrid>,
    /// `map_from_world`: floor-aligned, z up (identity without a floor).
    pub map_from_world: Pose3,
    /// The counts.
    pub summary: RgbdMapsSummary,
}

/// One keyframe's depth image and where it was taken.
#[derive(Debug, Clone)]
pub struct DepthView {
    /// `world_from_camera` of the depth camera.
    pub world_from_camera: Pose3,
    /// Depth \[m\], 0 or NaN where unknown.
    pub depth_m: Image<f32>,
}

/// Builds the octree and the floor grid from `views` seen through `intrinsics`.
///
/// # Errors
/// [`SlamError::Config`] for bad settings or no view, [`SlamError::Grid`] when the octree
/// refuses a camera position, [`SlamError::Map`] for a grid wider than `max_grid_cells`.
pub fn build_rgbd_maps(
    views: &[DepthView],
    intrinsics: &Intrinsics,
    config: &PlanningMapConfig,
) -> Result<RgbdMaps, SlamError> {
    let Some(first) = views.first() else {
        return Err(SlamError::Config("no keyframe to map".into()));
    };
    if !(config.max_range_m.is_finite() && config.max_range_m > 0.0) {
        return Err(SlamError::Config("max_range_m must be positive".into()));
    }
    let clouds: Vec<Vec<Point3<f64>>> = views
        .iter()
        .map(|v| {
            let origin = Point3::from(v.world_from_camera.translation.vector);
            let mut points = depth_points(
                &v.depth_m,
                intrinsics,
                &v.world_from_camera,
                config.depth_step_px,
            );
            points.retain(|p| (p - origin).norm() <= config.max_range_m);
            points
        })
        .collect();
    let up = camera_up(views);
    let floor = find_floor(&clouds, views, &up, config);
    let map_from_world = match &floor {
        Ok((plane, _)) => zup_to_floor().inverse() * floor_from_world(plane),
        Err(_) => Pose3::identity(),
    };
    let mut octree = Octree::new(config.octree.clone())?;
    let mut map_clouds = Vec::with_capacity(views.len());
    for (view, mut points) in views.iter().zip(clouds) {
        let origin = map_from_world * Point3::from(view.world_from_camera.translation.vector);
        for p in &mut points {
            *p = map_from_world * *p;
        }
        octree.insert_cloud(&points, &origin)?;
        map_clouds.push((origin, points));
    }
    let grid = match &floor {
        Ok(_) => Some(floor_grid(&map_clouds, config)?),
        Err(_) => None,
    };
    let summary = RgbdMapsSummary {
        keyframes: views.len(),
        floor: floor.as_ref().ok().map(|(plane, found)| FoundFloor {
            first_camera_height_m: plane
                .signed_distance_m(&Point3::from(first.world_from_camera.translation.vector)),
            ..*found
        }),
        floor_error: floor.as_ref().err().cloned(),
        map_from_world: pose_array(&map_from_world),
        octree: octree.stats(),
        grid: grid.as_ref().map(|g| {
            let count = |s: Occupancy| g.cells().iter().filter(|&&c| c == s).count();
            GridSummary {
                width: g.width(),
                height: g.height(),
                resolution_m: g.resolution_m(),
                free: count(Occupancy::Free),
                occupied: count(Occupancy::Occupied),
            }
        }),
    };
    Ok(RgbdMaps {
        octree,
        grid,
        map_from_world,
        summary,
    })
}

/// The mean of the cameras' −y axes in the world: "up" for a camera held upright.
fn camera_up(views: &[DepthView]) -> Unit<Vector3<f64>> {
    let sum: Vector3<f64> = views
        .iter()
        .map(|v| v.world_from_camera.rotation * -Vector3::y())
        .sum();
    Unit::try_new(sum, 1e-9).unwrap_or(-Vector3::y_axis())
}

/// Takes planes out of an even sample of the points one by one; the floor is the horizontal
/// one (normal within the tilt limit of `up`) farthest below the cameras' mean position.
fn find_floor(
    clouds: &[Vec<Point3<f64>>],
    views: &[DepthView],
    up: &Unit<Vector3<f64>>,
    config: &PlanningMapConfig,
) -> Result<(Plane, FoundFloor), String> {
    let total: usize = clouds.iter().map(Vec::len).sum();
    let stride = total.div_ceil(config.floor_sample_points.max(1)).max(1);
    let mut points: Vec<Point3<f64>> = clouds.iter().flatten().step_by(stride).copied().collect();
    let cameras = views
        .iter()
        .map(|v| v.world_from_camera.translation.vector)
        .sum::<Vector3<f64>>()
        / views.len().max(1) as f64;
    let cameras = Point3::from(cameras);
    let min_cos = config.max_floor_tilt_deg.to_radians().cos();
    let mut best: Option<(f64, Plane, FoundFloor)> = None;
    let mut last_error = String::from("no plane tried");
    for tried in 1..=config.max_planes {
        let plane = match fit_floor_ransac(&points, &config.floor) {
            Ok(p) => p,
            Err(e) => {
                last_error = e.to_string();
                break;
            }
        };
        let inlier = |p: &Point3<f64>| plane.signed_distance_m(p).abs() <= config.floor.threshold_m;
        let inliers = points.iter().filter(|p| inlier(p)).count();
        points.retain(|p| !inlier(p));
        let cos = plane.normal.dot(up);
        if cos.abs() < min_cos {
            continue;
        }
        // The normal turned up; the cameras must be above the plane.
        let plane = if cos < 0.0 {
            Plane {
                normal: -plane.normal,
                offset_m: -plane.offset_m,
            }
        } else {
            plane
        };
        let below_cameras = plane.signed_distance_m(&cameras);
        if below_cameras <= 0.0 {
            continue;
        }
        if best.as_ref().map_or(true, |(h, _, _)| below_cameras > *h) {
            let found = FoundFloor {
                normal_world: plane.normal.into_inner().into(),
                tilt_from_camera_up_deg: cos.abs().min(1.0).acos().to_degrees(),
                first_camera_height_m: 0.0,
                inliers,
                planes_tried: tried,
            };
            best = Some((below_cameras, plane, found));
        }
    }
    best.map(|(_, plane, found)| (plane, found)).ok_or_else(|| {
        format!(
            "no horizontal plane below the cameras among {} sampled points ({last_error})",
            points.len()
        )
    })
}

/// `floor_from_world`: the floor's up normal onto −y, the floor at y = 0 (the frame of
/// [`FloorGrid`]: height `-y`, floor coordinates `(x, z)`).
fn floor_from_world(plane: &Plane) -> Pose3 {
    let rotation = rotation_between(&plane.normal, &-Vector3::y_axis());
    // a floor point p has n·p = −offset, so after the rotation its y is offset
    Pose3::from_parts(
        nalgebra::Translation3::new(0.0, -plane.offset_m, 0.0),
        rotation.into(),
    )
}

/// The point-count floor grid of map-frame clouds (z up), over the cameras and the points.
fn floor_grid(
    clouds: &[(Point3<f64>, Vec<Point3<f64>>)],
    config: &PlanningMapConfig,
) -> Result<TriGrid, SlamError> {
    let floor_from_map = zup_to_floor();
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (origin, points) in clouds {
        for p in std::iter::once(origin).chain(points) {
            lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
    }
    let resolution = config.grid.resolution_m;
    let cells = |span: f64| (span / resolution).floor() + 2.0;
    let (w, h) = (cells(hi.x - lo.x), cells(hi.y - lo.y));
    if !(w.is_finite() && h.is_finite() && w.max(h) <= config.max_grid_cells as f64) {
        return Err(SlamError::Map(format!(
            "the floor grid would be {w} × {h} cells of {resolution} m, more than {} a side",
            config.max_grid_cells
        )));
    }
    let origin = Point2::new(lo.x - resolution / 2.0, lo.y - resolution / 2.0);
    let grid_config = FloorGridConfig {
        max_range_m: f64::INFINITY,
        ..config.grid.clone()
    };
    let mut grid = FloorGrid::new(w as usize, h as usize, origin, grid_config)?;
    for (camera, points) in clouds {
        let points: Vec<Point3<f64>> = points.iter().map(|p| floor_from_map * p).collect();
        grid.insert_cloud(&points, &(floor_from_map * camera));
    }
    Ok(grid.to_tri_grid(FloorGridMethod::PointCount))
}

fn pose_array(pose: &Pose3) -> [f64; 7] {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w]
}

/// Writes `octree.bt` and, when a floor was found, `floor.pgm/.yaml/.png` into `dir`.
///
/// # Errors
/// The writers' errors.
pub fn write_rgbd_maps(maps: &RgbdMaps, dir: &Path) -> Result<Vec<&'static str>, SlamError> {
    write_bt(&maps.octree, &dir.join("octree.bt"))?;
    let mut files = vec!["octree.bt"];
    if let Some(grid) = &maps.grid {
        let image = tri_grid_image(grid);
        save_image_yaml(&image, grid.resolution_m(), &dir.join("floor.yaml"))?;
        save_image_png(image, &dir.join("floor.png"))?;
        files.extend(["floor.pgm", "floor.yaml", "floor.png"]);
    }
    Ok(files)
}

/// Builds and writes the maps of `dataset`'s keyframes (`(timestamp, world_from_camera)` of
/// the rig's reference camera, final poses) into `dir`: the octree and floor grid for RGB-D
/// (stereo: none yet). Keyframes whose timestamp is not one of the
/// dataset's frames (a map loaded from elsewhere) are left out. Returns the report's
/// `planning_map` field.
///
/// # Errors
/// A keyframe's images that cannot be read, and [`build_rgbd_maps`]' and the writers' errors.
pub fn write_planning_maps(
    dataset: &Dataset,
    keyframes: &[(f64, Pose3)],
    rig: &slamkit_vo::frame::Rig,
    config: &PlanningMapConfig,
    dir: &Path,
) -> Result<serde_json::Value, SlamError> {
    use slamkit_vo::frame::Rig;
    let index: HashMap<u64, usize> = dataset
        .timestamps()
        .iter()
        .enumerate()
        .map(|(i, t)| (t.to_bits(), i))
        .collect();
    let wanted: Vec<(usize, Pose3)> = keyframes
        .iter()
        .filter_map(|(t, pose)| index.get(&t.to_bits()).map(|&i| (i, *pose)))
        .collect();
    if wanted.is_empty() {
        return Ok(serde_json::json!({ "skipped": "no keyframe is a frame of this dataset" }));
    }
    match (dataset, rig) {
        (Dataset::Rgbd(seq), Rig::Rgbd { depth, .. }) => {
            let views = wanted
                .iter()
                .filter_map(|(i, pose)| seq.frames.get(*i).map(|f| (f, pose)))
                .map(|(frame, pose)| {
                    Ok(DepthView {
                        world_from_camera: *pose,
                        depth_m: seq.load_depth(frame)?,
                    })
                })
                .collect::<Result<Vec<_>, IoError>>()?;
            rgbd_files(&views, depth, config, dir)
        }
        (Dataset::RgbdBag(_), Rig::Rgbd { depth, .. }) => {
            // a bag is read once, front to back
            let poses: HashMap<u64, Pose3> =
                keyframes.iter().map(|(t, p)| (t.to_bits(), *p)).collect();
            let mut views = Vec::new();
            for observation in dataset.observations() {
                if let slamkit_core::Observation::Rgbd(frame) = observation? {
                    if let Some(pose) = poses.get(&frame.timestamp.to_bits()) {
                        views.push(DepthView {
                            world_from_camera: *pose,
                            depth_m: frame.depth_m,
                        });
                    }
                }
            }
            rgbd_files(&views, depth, config, dir)
        }
        (Dataset::Stereo(_), Rig::Stereo { .. }) => Ok(serde_json::json!({
            "skipped": "no map to plan in from stereo keyframes yet"
        })),
        _ => Ok(serde_json::json!({ "skipped": "the rig does not match the dataset" })),
    }
}

fn rgbd_files(
    views: &[DepthView],
    intrinsics: &Intrinsics,
    config: &PlanningMapConfig,
    dir: &Path,
) -> Result<serde_json::Value, SlamError> {
    let maps = build_rgbd_maps(views, intrinsics, config)?;
    let files = write_rgbd_maps(&maps, dir)?;
    let mut value = serde_json::to_value(&maps.summary)
        .map_err(|e| SlamError::Map(format!("planning map summary: {e}")))?;
    value["files"] = serde_json::json!(files);
    value["config"] = serde_json::json!(config);
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3, UnitQuaternion};

    /// A 4 × 4 × 2.5 m room (room frame: z up, floor z = 0, walls at x, y = ±2) with a box
    /// `[0.6, 1.0] × [-0.3, 0.3] × [0, 0.5]` m on the floor.
    const BOX: ([f64; 3], [f64; 3]) = ([0.6, -0.3, 0.0], [1.0, 0.3, 0.5]);

    /// Distance along the unit ray `o + t d` to the first surface: the room's inside or the box.
    fn ray_room(o: &Point3<f64>, d: &Vector3<f64>) -> f64 {
        let room = ([-2.0, -2.0, 0.0], [2.0, 2.0, 2.5]);
        // leaving the room: the nearest exit over the three axes
        let mut t = f64::INFINITY;
        for a in 0..3 {
            if d[a] > 1e-12 {
                t = t.min((room.1[a] - o[a]) / d[a]);
            } else if d[a] < -1e-12 {
                t = t.min((room.0[a] - o[a]) / d[a]);
            }
        }
        // entering the box (slab method)
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            if d[a].abs() < 1e-12 {
                if o[a] < BOX.0[a] || o[a] > BOX.1[a] {
                    return t;
                }
                continue;
            }
            let (u, v) = ((BOX.0[a] - o[a]) / d[a], (BOX.1[a] - o[a]) / d[a]);
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
        if t0 <= t1 {
            t = t.min(t0);
        }
        t
    }

    /// The depth image of a camera at `room_from_camera` (camera: x right, y down, z forward).
    fn render(room_from_camera: &Pose3, k: &Intrinsics) -> Image<f32> {
        let o = Point3::from(room_from_camera.translation.vector);
        let mut data = Vec::with_capacity(k.width * k.height);
        for v in 0..k.height {
            for u in 0..k.width {
                let ray = Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
                let d = room_from_camera.rotation * ray;
                let t = ray_room(&o, &d.normalize());
                // depth is the z of the hit in the camera frame: t along a ray of length |ray|
                data.push((t / ray.norm()) as f32);
            }
        }
        Image::from_vec(k.width, k.height, data).unwrap_or_else(|| unreachable!())
    }

    /// A camera 1.2 m above the floor at `(x, y)`, turned by `yaw` about z and pitched 25°
    /// down.
    fn camera(x: f64, y: f64, yaw: f64) -> Pose3 {
        // camera axes in the room: z forward (along +x at yaw 0), x right (−y), y down (−z)
        let level = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            0.0, 0.0, 1.0, //
            -1.0, 0.0, 0.0, //
            0.0, -1.0, 0.0,
        ));
        let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw)
            * level
            * Rotation3::from_axis_angle(&Vector3::x_axis(), -25f64.to_radians());
        Pose3::from_parts(
            Translation3::new(x, y, 1.2),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    }

    #[test]
    fn a_synthetic_room_gives_its_floor_box_and_free_space() {
        let k = Intrinsics::from_array([120.0, 120.0, 80.0, 60.0], 160, 120);
        let rooms: Vec<Pose3> = (0..8)
            .map(|i| {
                let yaw = f64::from(i) * std::f64::consts::FRAC_PI_4;
                camera(-1.0 + 0.1 * f64::from(i % 2), 0.0, yaw)
            })
            .collect();
        // the session's world is the first camera's frame, as a visual session starts
        let world_from_room = rooms[0].inverse();
        let views: Vec<DepthView> = rooms
            .iter()
            .map(|room_from_camera| DepthView {
                world_from_camera: world_from_room * room_from_camera,
                depth_m: render(room_from_camera, &k),
            })
            .collect();
        let config = PlanningMapConfig {
            depth_step_px: 2,
            ..PlanningMapConfig::default()
        };
        let maps = build_rgbd_maps(&views, &k, &config).unwrap();
        let floor = maps.summary.floor.unwrap();
        // the floor's up is the room's z, seen from the first camera; the camera 1.2 m above
        let up = world_from_room * Vector3::z();
        let normal = Vector3::from(floor.normal_world);
        assert!(normal.dot(&up) > 0.9999, "{normal} vs {up}");
        assert!(
            (floor.first_camera_height_m - 1.2).abs() < 0.01,
            "{floor:?}"
        );
        // the map frame is the room's up to a yaw and a shift in x, y
        let map_from_room = maps.map_from_world * world_from_room;
        let up_in_map = map_from_room.rotation * Vector3::z();
        assert!((up_in_map - Vector3::z()).norm() < 1e-3, "{up_in_map}");
        let at = |x: f64, y: f64, z: f64| map_from_room * Point3::new(x, y, z);
        assert!((at(0.3, 0.2, 0.0).z).abs() < 0.01);
        let grid = maps.grid.unwrap();
        let cell_of = |x: f64, y: f64| {
            let p = at(x, y, 0.0);
            grid.cell_at(&Point2::new(p.x, p.y)).unwrap()
        };
        let cell = |x: f64, y: f64| {
            let (i, j) = cell_of(x, y);
            grid.get(i, j).unwrap()
        };
        // a face's cell may lie either side of the grid line nearest it
        let wall = |x: f64, y: f64| {
            let (i, j) = cell_of(x, y);
            (i.saturating_sub(1)..=i + 1)
                .flat_map(|a| (j.saturating_sub(1)..=j + 1).map(move |b| (a, b)))
                .any(|(a, b)| grid.get(a, b) == Some(Occupancy::Occupied))
        };
        // the box and the walls (below 1 m) are obstacles; the floor between is free
        assert!(wall(0.6, 0.0) && wall(0.6, 0.2), "the box's front face");
        assert!(wall(1.99, 0.5) && wall(1.0, 1.99) && wall(-1.0, -1.99));
        assert_eq!(cell(0.3, 0.0), Occupancy::Free);
        assert_eq!(cell(-0.5, 1.0), Occupancy::Free);
        assert_eq!(cell(0.0, -1.2), Occupancy::Free);
        let summary = maps.summary.grid.unwrap();
        assert!(summary.free > 500 && summary.occupied > 50, "{summary:?}");
        // the octree: the box's top occupied, the air above it free, the room outside unknown
        let octree = &maps.octree;
        assert_eq!(
            octree.occupancy_at(&at(0.8, 0.0, 0.48)),
            Occupancy::Occupied
        );
        assert_eq!(octree.occupancy_at(&at(0.0, 0.0, 0.8)), Occupancy::Free);
        assert_eq!(octree.occupancy_at(&at(3.0, 0.0, 0.8)), Occupancy::Unknown);
        assert!((octree.resolution_m() - 0.09).abs() < 1e-12);
    }

    #[test]
    fn no_horizontal_plane_gives_the_octree_alone() {
        let k = Intrinsics::from_array([120.0, 120.0, 80.0, 60.0], 160, 120);
        // a wall 2 m ahead of a level camera fills the whole image
        let views = [DepthView {
            world_from_camera: Pose3::identity(),
            depth_m: Image::filled(160, 120, 2.0f32),
        }];
        let maps = build_rgbd_maps(&views, &k, &PlanningMapConfig::default()).unwrap();
        assert!(maps.grid.is_none());
        assert!(maps.summary.floor_error.is_some());
        assert!(maps.octree.stats().occupied_leaves > 0);
        assert!(build_rgbd_maps(&[], &k, &PlanningMapConfig::default()).is_err());
    }
}

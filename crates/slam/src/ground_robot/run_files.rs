//! What a closed-loop run leaves for people and scripts to read: its files (trajectories, the
//! map as an image and a map file, one CSV line per camera frame) and the metrics of
//! `report.json` (`slamkit nav` writes them all).

use super::closed_loop::{NavLoopConfig, NavOutcome};
use crate::SlamError;
use serde_json::{json, Value};
use slamkit_core::Pose2;
use slamkit_io::image_writer::save_rgb_png;
use slamkit_io::write_tum;
use slamkit_map::grid_io::{save_image_yaml, tri_grid_image};
use slamkit_vo::FrameStatus;
use std::path::Path;

impl NavOutcome {
    /// Writes the run's files into `out`: `trajectory.tum` (the camera session's estimate),
    /// `groundtruth.tum`, `map.png` (the floor grid with the path driven, [`Self::map_image`]),
    /// `map.pgm` + `map.yaml` (the floor grid as ROS `map_server` reads it; the page of the
    /// run places `map.png` by it), `map.skmap` (the map a later run can plan and localise
    /// in) and `frames.csv`
    /// ([`Self::frames_csv`]).
    pub fn write_run_files(&self, out: &Path, config: &NavLoopConfig) -> Result<(), SlamError> {
        write_tum(&out.join("trajectory.tum"), &self.estimate)?;
        write_tum(&out.join("groundtruth.tum"), &self.ground_truth)?;
        save_rgb_png(&out.join("map.png"), &self.map_image(config))?;
        let grid = &self.grid;
        save_image_yaml(
            &tri_grid_image(grid),
            grid.resolution_m(),
            &out.join("map.yaml"),
        )?;
        let map_path = out.join("map.skmap");
        self.map
            .save(&map_path)
            .map_err(|source| SlamError::MapFile {
                path: map_path.clone(),
                source,
            })?;
        let csv = out.join("frames.csv");
        std::fs::write(&csv, self.frames_csv())
            .map_err(|error| SlamError::Io(slamkit_io::IoError::Io { path: csv, error }))
    }

    /// `frames.csv`: one line per camera frame: time, true and estimated `x, y, yaw` (m,
    /// degrees; empty when VO failed), VO's status, inliers, correspondences and failure
    /// reason.
    pub fn frames_csv(&self) -> String {
        let mut text = String::from(
            "t_s,true_x_m,true_y_m,true_yaw_deg,est_x_m,est_y_m,est_yaw_deg,status,inliers,\
             correspondences,reason\n",
        );
        let pose = |p: &Pose2| {
            let t = p.translation.vector;
            let yaw = p.rotation.angle().to_degrees();
            format!("{:.4},{:.4},{yaw:.3}", t.x, t.y)
        };
        for f in &self.frames {
            let estimate = f.estimate.as_ref().map_or(",,".to_string(), pose);
            let status = match &f.status {
                FrameStatus::Initialised { features } => format!("initialised,{features},,"),
                FrameStatus::Tracked {
                    inliers,
                    correspondences,
                } => format!("tracked,{inliers},{correspondences},"),
                FrameStatus::Failed(reason) => {
                    format!("failed,,,\"{}\"", format!("{reason:?}").replace('"', "'"))
                }
            };
            text += &format!("{:.2},{},{estimate},{status}\n", f.t_s, pose(&f.truth));
        }
        text
    }

    /// `report.json`'s `metrics`: whether and when the goal was reached, the path driven
    /// against the shortest, how closely it was followed and how well the robot knew where it
    /// was.
    pub fn metrics_json(&self) -> Value {
        json!({
            "reached": self.reached,
            "time_s": self.time_s,
            "path_length_m": self.path_length_m,
            "optimal_length_m": self.optimal.length_m,
            "length_ratio": self.path_length_m / self.optimal.length_m.max(1e-9),
            "max_cross_track_m": self.max_cross_track_m,
            "final_distance_m": self.final_distance_m,
            "localisation_error_mean_m": self.localisation_error_mean_m,
            "localisation_error_max_m": self.localisation_error_max_m,
            "plans": self.plans.len(),
            "plan_failures": self.plan_failures,
            "blocked_steps": self.blocked_steps,
        })
    }

    /// One line for a person: reached or not, when, how far driven and how far from the goal.
    pub fn summary(&self) -> String {
        format!(
            "{} after {:.1} s: driven {:.2} m (shortest {:.2} m), max cross-track {:.3} m, {:.2} \
             m from the goal",
            if self.reached {
                "goal reached"
            } else {
                "goal NOT reached"
            },
            self.time_s,
            self.path_length_m,
            self.optimal.length_m,
            self.max_cross_track_m,
            self.final_distance_m,
        )
    }
}

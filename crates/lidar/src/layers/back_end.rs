//! The layered mapper's back end: every keyframe of every layer is a node of one pose graph,
//! tied to the keyframe before it by the front end's relative pose, and to old keyframes of
//! other heights by the matches [`mod@super::relocalise`] finds; each new tie is optimised in
//! ([`crate::pose_graph`]: sparse Gauss–Newton with a Cauchy kernel; Lu & Milios 1997, Grisetti
//! et al., "A tutorial on graph-based SLAM", 2010), and the keyframes, the layer maps and the
//! current pose move to the optimised poses.
//!
//! A sequential edge is as sure as the motion prior between two keyframes: its standard
//! deviation grows with the time between them (a few centimetres and milliradians per second,
//! the optical flow's and the gyro's drift in directions the scans leave free). A loop edge is
//! sure only along the directions its scan pins ([`super::degeneracy`]): there it holds the
//! match to `loop_sigma`, along the others it holds nothing. The optimiser then spreads each loop
//! correction over the keyframes of the drift in proportion to their motion's uncertainty, and
//! several weak ties to old walls pull together, where one re-localisation moved the pose alone.

use crate::error::check_fields;
use crate::pose_graph::{Edge, PoseGraph};
use crate::LidarError;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use slamkit_core::Pose2;

/// Pose-graph back-end parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackEndConfig {
    /// Correct re-localisations through the graph; when false each one moves the keyframes
    /// since its anchor by their share in time ([`super::relocalise::share`]).
    pub enabled: bool,
    /// Standard deviation of a sequential edge's translation, at no time between the keyframes
    /// \[m\].
    pub odometry_sigma_m: f64,
    /// Growth of that standard deviation with the time between the keyframes \[m/s\].
    pub odometry_drift_mps: f64,
    /// Standard deviation of a sequential edge's turn, at no time between the keyframes \[rad\].
    pub odometry_sigma_rad: f64,
    /// Growth of that standard deviation with the time between the keyframes \[rad/s\].
    pub odometry_drift_radps: f64,
    /// A loop edge's information is its scan's information matrix (about one unit per scan
    /// point pinning a direction) over the square of this, along the directions the scan pins:
    /// the residual of one scan point, widened for the errors of the old map and of the match
    /// that points do not show \[m\].
    pub loop_sigma_m: f64,
    /// Scale of the Cauchy kernel on a loop edge's Mahalanobis error.
    pub robust_scale: f64,
    /// Gauss–Newton iterations per optimisation.
    pub iterations: usize,
}

impl Default for BackEndConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            odometry_sigma_m: 0.01,
            odometry_drift_mps: 0.01,
            odometry_sigma_rad: 0.002,
            odometry_drift_radps: 0.001,
            loop_sigma_m: 0.1,
            robust_scale: 30.0,
            iterations: 10,
        }
    }
}

impl BackEndConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LidarError> {
        let positive = |field, value: f64| (field, value, value > 0.0);
        let non_negative = |field, value: f64| (field, value, value >= 0.0);
        check_fields(
            [
                positive("odometry_sigma_m", self.odometry_sigma_m),
                non_negative("odometry_drift_mps", self.odometry_drift_mps),
                positive("odometry_sigma_rad", self.odometry_sigma_rad),
                non_negative("odometry_drift_radps", self.odometry_drift_radps),
                positive("loop_sigma_m", self.loop_sigma_m),
                positive("robust_scale", self.robust_scale),
            ],
            "out of range",
        )
    }
}

/// The keyframes as a pose graph: node `i` is the `i`-th keyframe inserted (any layer).
#[derive(Debug, Clone, Default)]
pub struct KeyframeGraph {
    graph: PoseGraph,
    /// Time of each node's scan \[s\].
    times_s: Vec<f64>,
}

impl KeyframeGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of keyframes.
    pub fn len(&self) -> usize {
        self.times_s.len()
    }

    /// True before the first keyframe.
    pub fn is_empty(&self) -> bool {
        self.times_s.is_empty()
    }

    /// The node poses (optimised, once there are loops).
    pub fn poses(&self) -> &[Pose2] {
        self.graph.nodes()
    }

    /// Adds the keyframe at `pose`, taken at `time_s`, tied to the one before it by their
    /// relative pose; returns its node.
    pub fn add_keyframe(&mut self, pose: Pose2, time_s: f64, config: &BackEndConfig) -> usize {
        let node = self.graph.add_node(pose);
        let previous = node.checked_sub(1).and_then(|p| {
            let from = self.graph.nodes().get(p)?;
            Some((p, *from, *self.times_s.get(p)?))
        });
        self.times_s.push(time_s);
        if let Some((p, from, from_s)) = previous {
            let dt = (time_s - from_s).max(0.0);
            let sigma_m = config.odometry_sigma_m + config.odometry_drift_mps * dt;
            let sigma_rad = config.odometry_sigma_rad + config.odometry_drift_radps * dt;
            let information = Matrix3::from_diagonal(&nalgebra::Vector3::new(
                sigma_m.powi(-2),
                sigma_m.powi(-2),
                sigma_rad.powi(-2),
            ));
            self.graph.add_edge(Edge {
                from: p,
                to: node,
                from_from_to: from.inverse() * pose,
                information,
                robust_scale: None,
            });
        }
        node
    }

    /// Ties keyframe `to` to the old keyframe `from`: a match put `to` at `world_from_to` on the
    /// old map around `from`; `pinned` is the information matrix of `to`'s scan
    /// ([`super::degeneracy::scan_information`]), of which only the directions with eigenvalue
    /// at least `min_constraint` are kept. Returns false when nothing was added.
    pub fn add_loop(
        &mut self,
        from: usize,
        to: usize,
        world_from_to: &Pose2,
        pinned: &Matrix3<f64>,
        min_constraint: f64,
        config: &BackEndConfig,
    ) -> bool {
        let Some(anchor) = self.graph.nodes().get(from).copied() else {
            return false;
        };
        let eigen = pinned.symmetric_eigen();
        let information = eigen
            .eigenvalues
            .iter()
            .zip(eigen.eigenvectors.column_iter())
            .filter(|(value, _)| **value >= min_constraint)
            .fold(Matrix3::zeros(), |acc, (value, v)| {
                acc + v * v.transpose() * *value
            })
            / config.loop_sigma_m.powi(2);
        information != Matrix3::zeros()
            && self.graph.add_edge(Edge {
                from,
                to,
                from_from_to: anchor.inverse() * world_from_to,
                information,
                robust_scale: Some(config.robust_scale),
            })
    }

    /// Optimises the graph (the first keyframe stays put).
    pub fn optimise(&mut self, config: &BackEndConfig) {
        self.graph.optimize(config.iterations, 1e-6);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    /// A drone flies along x for 20 keyframes, 1 s apart, while its heading estimate drifts by
    /// 0.005 rad per keyframe; the last keyframe's scan is matched on an old map at the start
    /// (seen from a layer above), pinning every direction: the optimised last pose is near the
    /// match, the middle keyframe takes part of the correction, and the first stays put.
    #[test]
    fn a_loop_spreads_the_drift_over_the_chain_and_moves_the_new_pose_onto_the_old_map() {
        let config = BackEndConfig::default();
        let truth: Vec<Pose2> = (0..21)
            .map(|k| Pose2::new(Vector2::new(0.2 * f64::from(k), 0.0), 0.0))
            .collect();
        let mut graph = KeyframeGraph::new();
        let mut estimate = Pose2::identity();
        for (k, pair) in truth.windows(2).enumerate() {
            if k == 0 {
                graph.add_keyframe(estimate, 0.0, &config);
            }
            let step = pair[0].inverse() * pair[1];
            estimate = estimate * Pose2::new(Vector2::zeros(), 0.005) * step;
            graph.add_keyframe(estimate, (k + 1) as f64, &config);
        }
        let last = truth.len() - 1;
        let drifted = truth[last].inverse() * graph.poses()[last];
        let before = drifted.translation.vector.norm();
        assert!(before > 0.15 && (drifted.rotation.angle() - 0.1).abs() < 1e-9);
        let pinned = Matrix3::from_diagonal(&nalgebra::Vector3::new(200.0, 150.0, 300.0));
        assert!(graph.add_loop(1, last, &truth[last], &pinned, 20.0, &config));
        // a scan that pins nothing adds no tie
        assert!(!graph.add_loop(1, last, &truth[last], &(pinned * 0.01), 20.0, &config));
        graph.optimise(&config);
        let poses = graph.poses();
        // most of the drift is gone (the chain's steady turn resists a little)
        let error = truth[last].inverse() * poses[last];
        assert!(error.translation.vector.norm() < 0.2 * before, "{error}");
        assert!(error.rotation.angle().abs() < 0.02, "{error}");
        assert!(poses[0].translation.vector.norm() < 1e-9);
        let middle_error = (poses[10].translation.vector - truth[10].translation.vector).norm();
        let middle_before = 0.2 * (1..=10).map(|k| (0.005 * f64::from(k)).sin()).sum::<f64>();
        assert!(
            middle_error < 0.6 * middle_before,
            "{middle_error} {middle_before}"
        );
    }

    #[test]
    fn a_loop_along_a_wall_keeps_the_chain_along_it() {
        // the loop scan sees one wall across x: it pins y and the heading only
        let config = BackEndConfig::default();
        let mut graph = KeyframeGraph::new();
        for k in 0..10 {
            let pose = Pose2::new(Vector2::new(0.3 * f64::from(k), 0.0), 0.0);
            graph.add_keyframe(pose, f64::from(k), &config);
        }
        let pinned = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.5, 200.0, 300.0));
        let matched = Pose2::new(Vector2::new(2.2, 0.1), 0.0);
        assert!(graph.add_loop(0, 9, &matched, &pinned, 20.0, &config));
        graph.optimise(&config);
        let last = graph.poses()[9];
        assert!((last.translation.y - 0.1).abs() < 0.01, "{last}");
        assert!((last.translation.x - 2.7).abs() < 1e-3, "{last}");
    }

    #[test]
    fn bad_config_is_an_error() {
        let config = BackEndConfig {
            loop_sigma_m: 0.0,
            ..BackEndConfig::default()
        };
        assert!(config.validate().is_err());
        assert!(BackEndConfig::default().validate().is_ok());
    }
}

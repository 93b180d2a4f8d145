//! slamkit-eval: accuracy of an estimated trajectory against ground truth, with the metrics the
//! field reports, computed so that they match the reference tools to rounding.
//!
//! * [`mod@ate`]: [`ate()`] — absolute trajectory error after SE(3) / Sim(3) / no alignment
//!   (Sturm et al., IROS 2012; alignment by Umeyama, TPAMI 1991), as `evo_ape` with
//!   `--pose_relation trans_part`.
//! * [`mod@rpe`]: [`rpe()`] — relative pose error over a delta in frames or metres (Sturm et al.
//!   2012), as `evo_rpe`.
//! * [`relations`]: [`relations_error`] — the relations metric of Kümmerle et al., Autonomous
//!   Robots 2009, used by the 2D lidar benchmark logs.
//! * [`association`] — pairing poses by nearest timestamp exactly as evo 1.38, or by index.
//! * [`stats`] — [`ErrorStats`]: RMSE, mean, median, std, min, max and count, as evo and numpy
//!   compute them.
//! * [`plot`] — top view and error-over-time figures (PNG or SVG), written atomically.
//! * [`report_html`] — self-contained HTML report pages, images embedded.
//! * [`report_svg`] — zoomable maps with paths, and charts over time, as inline SVG for them.
//!
//! Poses are `world_from_body` ([`slamkit_core::Pose3`]); errors are in metres and degrees.
//! Relations and trajectory formats are [`slamkit_io`]'s types, so what it reads is scored as
//! read. Nothing here prints or reads input files; the `slamkit eval` command does ([`plot`] and
//! [`report_html`] write the figures and pages they are asked for).

pub mod association;
pub mod ate;
pub mod plot;
pub mod relations;
pub mod report_html;
pub mod report_svg;
pub mod rpe;
pub mod stats;

pub use association::{associate, Pairing, PosePair, DEFAULT_MAX_DIFF_S};
pub use ate::{ate, Alignment, AteResult};
pub use relations::{
    relation_errors, relations_error, GroundTruthRelation, RelationError, RelationsStats,
};
pub use rpe::{rpe, DeltaUnit, RpeConfig, RpeResult};
pub use stats::ErrorStats;

use std::path::PathBuf;

/// What can go wrong while evaluating a trajectory.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// No pose of the estimate could be paired with one of the reference.
    #[error(
        "no pose pairs: none of the {estimate} estimated poses is within the time tolerance of \
         one of the {reference} reference poses"
    )]
    NoPairs {
        /// Poses in the reference.
        reference: usize,
        /// Poses in the estimate.
        estimate: usize,
    },
    /// Pairing by index (KITTI) needs equally long trajectories.
    #[error("pairing by index needs equal lengths: reference has {reference} poses, estimate {estimate}")]
    LengthMismatch {
        /// Poses in the reference.
        reference: usize,
        /// Poses in the estimate.
        estimate: usize,
    },
    /// A timestamp is NaN or infinite.
    #[error("{which} pose {index} has a non-finite timestamp")]
    NonFiniteTimestamp {
        /// `"reference"` or `"estimate"`.
        which: &'static str,
        /// Index of the pose.
        index: usize,
    },
    /// There was nothing to summarise.
    #[error("no errors to summarise")]
    NoErrors,
    /// An error value is NaN or infinite: a pose is broken.
    #[error("error {index} is not finite (a pose holds NaN or infinity)")]
    NonFiniteError {
        /// Index of the error (pair, or relation for the relations metric).
        index: usize,
    },
    /// The estimate could not be aligned onto the reference.
    #[error("aligning the estimate onto the reference")]
    Alignment(#[from] slamkit_core::GeometryError),
    /// An alignment name other than se3, sim3 or none.
    #[error("unknown alignment '{name}' (expected se3, sim3 or none)")]
    UnknownAlignment {
        /// The name given.
        name: String,
    },
    /// The RPE delta is not usable.
    #[error("invalid RPE delta {delta} {unit}: {}", match unit {
        DeltaUnit::Frames => "use a whole number of frames, 1 or more",
        DeltaUnit::Metres => "use a finite distance above 0 m",
    })]
    InvalidDelta {
        /// The delta given.
        delta: f64,
        /// Its unit.
        unit: DeltaUnit,
    },
    /// No pair of poses is `delta` apart.
    #[error("no pose pairs {delta} {unit} apart among {poses} associated poses")]
    NoDeltaPairs {
        /// The delta given.
        delta: f64,
        /// Its unit.
        unit: DeltaUnit,
        /// Number of associated poses.
        poses: usize,
    },
    /// No relation had estimated poses at both its ends.
    #[error("none of the {relations} relations has estimated poses at both its times")]
    NoRelations {
        /// Number of relations given.
        relations: usize,
    },
    /// A plot file name without a `.png` or `.svg` extension.
    #[error("plot {path}: unsupported format (use .png or .svg)")]
    UnsupportedPlotFormat {
        /// The plot file.
        path: PathBuf,
    },
    /// A written figure could not be put in place.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Drawing or writing a plot failed.
    #[error("plot {path}: {message}")]
    Plot {
        /// The plot file.
        path: PathBuf,
        /// What the plotting library reported.
        message: String,
    },
}

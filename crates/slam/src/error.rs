//! Errors of the sessions and the map file.

/// What can go wrong in a session or with a map file.
#[derive(Debug, thiserror::Error)]
pub enum SlamError {
    /// The configuration is not usable.
    #[error("configuration: {0}")]
    Config(String),
    /// The map file could not be read or written.
    #[error("map file {path}")]
    MapFile {
        /// The file.
        path: std::path::PathBuf,
        /// What was wrong.
        source: crate::map_file::MapFileError,
    },
    /// The map does not suit the session (another rig, no keyframes).
    #[error("map: {0}")]
    Map(String),
    /// A 2D lidar algorithm refused its input or configuration.
    #[error(transparent)]
    Lidar(#[from] slamkit_lidar::LidarError),
    /// A map algorithm refused its input or configuration.
    #[error(transparent)]
    Grid(#[from] slamkit_map::MapError),
    /// A grid file (`map_server` YAML and image, PNG) could not be read or written.
    #[error(transparent)]
    GridFile(#[from] slamkit_map::MapFileError),
    /// Visual odometry refused its configuration.
    #[error(transparent)]
    Vo(#[from] slamkit_vo::VoError),
    /// A planner, tracker or gate refused its input or configuration.
    #[error(transparent)]
    Nav(#[from] slamkit_nav::NavError),
    /// The simulator refused its world or configuration.
    #[error(transparent)]
    Sim(#[from] slamkit_sim::SimError),
    /// A navigation goal that cannot be reached.
    #[error("goal {0}")]
    Goal(String),
    /// A dataset or recording could not be read or written.
    #[error(transparent)]
    Io(#[from] slamkit_io::IoError),
    /// A recording (`--record FILE.mcap`) could not be written.
    #[error("recording {}: {message}", path.display())]
    Recording {
        /// The recording's file.
        path: std::path::PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A run's HTML report could not be written.
    #[error(transparent)]
    Report(#[from] slamkit_eval::report_html::ReportError),
    /// A run could not be scored against its ground truth.
    #[error(transparent)]
    Eval(#[from] slamkit_eval::EvalError),
    /// A simulated run cannot be scored (no scan, no ground truth).
    #[error("scoring: {0}")]
    Scoring(String),
    /// No scan of a log can be matched (a dead sensor): the run would give nothing.
    #[error("no usable scan: {0}")]
    NoUsableScan(String),
    /// A worker thread could not start, or died.
    #[error("thread: {0}")]
    Thread(String),
}

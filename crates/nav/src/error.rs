//! Errors of the navigation crate.

/// Why a plan or a tracker step failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NavError {
    /// A configuration value is out of its valid range.
    #[error("invalid navigation configuration: {message}")]
    InvalidConfig {
        /// Which value and why.
        message: String,
    },
    /// The start or goal lies outside the map (or is NaN).
    #[error("{what} ({x_m}, {y_m}, {z_m}) is outside the map")]
    OutsideMap {
        /// "start" or "goal".
        what: &'static str,
        /// x \[m\].
        x_m: f64,
        /// y \[m\].
        y_m: f64,
        /// z \[m\] (0 for 2D maps).
        z_m: f64,
    },
    /// The start or goal cell is an obstacle (after inflation).
    #[error("{what} ({x_m}, {y_m}, {z_m}) lies in an obstacle or within the robot radius of one")]
    Blocked {
        /// "start" or "goal".
        what: &'static str,
        /// x \[m\].
        x_m: f64,
        /// y \[m\].
        y_m: f64,
        /// z \[m\] (0 for 2D maps).
        z_m: f64,
    },
    /// No path joins start and goal, even through unknown cells.
    #[error("goal unreachable: no path through free or unknown cells ({expanded} cells searched)")]
    Unreachable {
        /// Cells expanded by the last search.
        expanded: usize,
    },
    /// The search gave up after its expansion budget.
    #[error("search stopped after {expanded} expansions without reaching the goal")]
    SearchLimit {
        /// Cells expanded.
        expanded: usize,
    },
}

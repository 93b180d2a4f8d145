//! Summary statistics of a list of per-pair errors, computed the way evo (and numpy) does:
//! RMSE `sqrt(mean(e²))`, mean, median (mean of the two middle values for an even count),
//! population standard deviation (numpy's default `ddof = 0`), min, max and the pair count.

use crate::EvalError;
use serde::{Deserialize, Serialize};

/// Statistics of per-pair errors, in the unit of the errors (m for translation).
///
/// The field names are the `--json` keys of `slamkit eval ate|rpe` (DESIGN.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Root mean square error.
    pub rmse: f64,
    /// Mean error.
    pub mean: f64,
    /// Median error.
    pub median: f64,
    /// Population standard deviation (divides by n, as `numpy.std`).
    pub std: f64,
    /// Smallest error.
    pub min: f64,
    /// Largest error.
    pub max: f64,
    /// Number of errors summarised.
    pub pairs: usize,
}

/// The statistics as a table, one line each, in metres:
/// `  rmse      0.013473 m` and so on (`slamkit eval ate` prints it).
impl std::fmt::Display for ErrorStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (name, value) in [
            ("rmse", self.rmse),
            ("mean", self.mean),
            ("median", self.median),
            ("std", self.std),
            ("min", self.min),
            ("max", self.max),
        ] {
            writeln!(f, "  {name:<7}{value:>12.6} m")?;
        }
        Ok(())
    }
}

impl ErrorStats {
    /// Summarises `errors`.
    ///
    /// # Errors
    /// [`EvalError::NoErrors`] when `errors` is empty, [`EvalError::NonFiniteError`] when one is
    /// NaN or infinite (a broken pose, not a large error).
    pub fn from_errors(errors: &[f64]) -> Result<Self, EvalError> {
        if errors.is_empty() {
            return Err(EvalError::NoErrors);
        }
        if let Some(index) = errors.iter().position(|e| !e.is_finite()) {
            return Err(EvalError::NonFiniteError { index });
        }
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let mean_sq = errors.iter().map(|e| e * e).sum::<f64>() / n;
        let var = errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let mid = sorted.len() / 2;
        let median = if sorted.len() % 2 == 1 {
            sorted[mid]
        } else {
            0.5 * (sorted[mid - 1] + sorted[mid])
        };
        Ok(Self {
            rmse: mean_sq.sqrt(),
            mean,
            median,
            std: var.sqrt(),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            pairs: errors.len(),
        })
    }
}

/// Mean and population standard deviation of `values`; `None` when empty.
pub fn mean_std(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    Some((mean, var.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prints_one_line_a_statistic() {
        let stats = ErrorStats::from_errors(&[1.0, 2.0, 3.0]).unwrap();
        let text = stats.to_string();
        assert_eq!(text.lines().count(), 6);
        assert!(
            text.starts_with("  rmse       2.160247 m\n  mean       2.000000 m\n"),
            "{text}"
        );
        assert!(text.ends_with("  max        3.000000 m\n"), "{text}");
    }

    #[test]
    fn known_values() {
        // errors 1..=4: mean 2.5, median 2.5, var = (2.25+0.25+0.25+2.25)/4 = 1.25
        let s = ErrorStats::from_errors(&[4.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(s.mean, 2.5);
        assert_eq!(s.median, 2.5);
        assert!((s.std - 1.25f64.sqrt()).abs() < 1e-15);
        assert!((s.rmse - 7.5f64.sqrt()).abs() < 1e-15);
        assert_eq!((s.min, s.max, s.pairs), (1.0, 4.0, 4));
        let odd = ErrorStats::from_errors(&[5.0, 1.0, 3.0]).unwrap();
        assert_eq!(odd.median, 3.0);
    }

    #[test]
    fn serialises_with_the_cli_keys() {
        let s = ErrorStats::from_errors(&[1.0]).unwrap();
        let json = serde_json::to_value(s).unwrap();
        let mut keys: Vec<_> = json.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        assert_eq!(
            keys,
            ["max", "mean", "median", "min", "pairs", "rmse", "std"]
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            ErrorStats::from_errors(&[]),
            Err(EvalError::NoErrors)
        ));
        assert!(matches!(
            ErrorStats::from_errors(&[1.0, f64::NAN]),
            Err(EvalError::NonFiniteError { index: 1 })
        ));
        assert_eq!(mean_std(&[]), None);
        assert_eq!(mean_std(&[1.0, 3.0]), Some((2.0, 1.0)));
    }
}

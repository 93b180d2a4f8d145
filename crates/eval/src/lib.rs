//! slamkit-eval: accuracy metrics against ground truth (ATE, RPE, the relations metric).

//! Pieces of the JSON reports that every shell (the CLI, the ROS 2 node, the fleet, Python)
//! assembles from a session's parts, and the run's `report.html` ([`page`]).

pub mod page;

use serde_json::Value;

/// Adds the fields of the JSON object `more` to the object `report` (those of `more` win);
/// anything that is not an object on either side is left as it is.
///
/// ```
/// use serde_json::json;
/// let mut report = json!({ "a": 1, "b": 2 });
/// slamkit_slam::report::merge_json(&mut report, json!({ "b": 3, "c": 4 }));
/// assert_eq!(report, json!({ "a": 1, "b": 3, "c": 4 }));
/// ```
pub fn merge_json(report: &mut Value, more: Value) {
    if let (Some(report), Value::Object(more)) = (report.as_object_mut(), more) {
        report.extend(more);
    }
}

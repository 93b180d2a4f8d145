//! What a merge found, as JSON for `report.json` (`slamkit map merge`): each input and where
//! it went, every closure and what became of it, the counters and the joint optimisation.

use super::{ClosureStatus, MergeOutcome};
use serde_json::{json, Value};
use slamkit_core::Pose2;

/// A pose as `{x_m, y_m, theta_rad}`.
pub fn pose_json(pose: &Pose2) -> Value {
    json!({
        "x_m": pose.translation.vector.x,
        "y_m": pose.translation.vector.y,
        "theta_rad": pose.rotation.angle(),
    })
}

impl MergeOutcome {
    /// The merge as JSON; `names[i]` names input `i` (a robot, a file), `keyframe_times[i][k]`
    /// is the time of keyframe `k` of input `i` (so a reader can find each closure's scans).
    pub fn report(&self, names: &[String], keyframe_times: &[Vec<f64>]) -> Value {
        let name = |i: usize| {
            names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("input {i}"))
        };
        let time = |i: usize, k: usize| keyframe_times.get(i).and_then(|t| t.get(k)).copied();
        let inputs: Vec<Value> = self
            .inputs
            .iter()
            .enumerate()
            .map(|(i, input)| {
                json!({
                    "name": name(i),
                    "merged": input.merged_from_input.is_some(),
                    "merged_from_input": input.merged_from_input.as_ref().map(pose_json),
                    "keyframe_offset": input.keyframe_offset,
                    "scans": input.trajectory.as_ref().map(|t| t.len()),
                })
            })
            .collect();
        let closures: Vec<Value> = self
            .closures
            .iter()
            .map(|c| {
                json!({
                    "from": name(c.from_map),
                    "from_keyframe": c.from_keyframe,
                    "from_time_s": time(c.from_map, c.from_keyframe),
                    "to": name(c.to_map),
                    "to_keyframe": c.to_keyframe,
                    "to_time_s": time(c.to_map, c.to_keyframe),
                    "from_from_to": pose_json(&c.from_from_to),
                    "goodness": c.goodness,
                    "reverse_goodness": c.reverse_goodness,
                    "free_space_conflict": c.free_space_conflict,
                    "status": c.status,
                })
            })
            .collect();
        let rejected = self
            .closures
            .iter()
            .filter(|c| c.status != ClosureStatus::Accepted)
            .count();
        json!({
            "inputs": inputs,
            "unmerged": self.unmerged().into_iter().map(name).collect::<Vec<_>>(),
            "closures_found": self.closures.len(),
            "closures_accepted": self.stats.accepted,
            "closures_rejected": rejected,
            "stats": self.stats,
            "optimisation": self.optimisation.map(|o| json!({
                "iterations": o.iterations,
                "initial_cost": o.initial_cost,
                "final_cost": o.final_cost,
            })),
            "closures": closures,
            "merged_keyframes": self.map.keyframes.len(),
        })
    }
}

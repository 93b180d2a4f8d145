//! Reading back a `--record` MCAP file in the CLI's tests.

use std::collections::BTreeMap;
use std::path::Path;

/// What a recording holds: messages per topic, each topic's schema name, and each topic's
/// last message (JSON).
pub struct Recording {
    pub counts: BTreeMap<String, u64>,
    pub schemas: BTreeMap<String, String>,
    pub last: BTreeMap<String, serde_json::Value>,
}

/// Reads `path` whole, checking that every message is JSON and that log times never go back.
pub fn read(path: &Path) -> Recording {
    let bytes = std::fs::read(path).unwrap();
    let mut recording = Recording {
        counts: BTreeMap::new(),
        schemas: BTreeMap::new(),
        last: BTreeMap::new(),
    };
    let mut log_time = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        assert!(message.log_time >= log_time, "log times go back");
        log_time = message.log_time;
        let topic = message.channel.topic.clone();
        *recording.counts.entry(topic.clone()).or_default() += 1;
        let schema = message.channel.schema.as_ref().map(|s| s.name.clone());
        recording
            .schemas
            .insert(topic.clone(), schema.unwrap_or_default());
        recording
            .last
            .insert(topic, serde_json::from_slice(&message.data).unwrap());
    }
    recording
}

/// The `recording.messages` of a run's report.
pub fn reported_counts(report: &serde_json::Value) -> BTreeMap<String, u64> {
    serde_json::from_value(report["recording"]["messages"].clone()).unwrap()
}

//! Connections: each topic of a bag with the message type recorded on it, that type's md5sum
//! (ROS 1), its serialisation and its full message definition (the `.msg` text with every nested type), as the recording
//! node published them.

use super::record::{Fields, RecordError};
use super::wire::Serialization;

/// One connection of a bag (a topic as recorded from one publisher).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Connection {
    /// The id the bag's message records refer to.
    pub id: u32,
    /// Topic name (`/scan`).
    pub topic: String,
    /// Message type (`sensor_msgs/LaserScan`).
    pub message_type: String,
    /// md5sum of the message definition, as ROS 1 computes it (32 hex digits; empty in a
    /// ROS 2 bag).
    pub md5sum: String,
    /// The message definition text stored in the bag (empty when it stores none).
    #[serde(skip)]
    pub message_definition: String,
    /// How its messages are serialised.
    pub serialization: Serialization,
    /// The publishing node, when recorded.
    pub callerid: Option<String>,
    /// True for a latched topic (`/tf_static`, `/map`).
    pub latching: bool,
}

impl Connection {
    /// A connection from a connection record's header and data.
    pub(crate) fn parse(header: &Fields, data: &[u8]) -> Result<Self, RecordError> {
        let id = header.u32("conn")?;
        let fields = Fields::parse(data)?;
        let text = |name: &str| fields.string(name).map(str::to_string);
        Ok(Self {
            id,
            topic: header.string("topic")?.to_string(),
            message_type: text("type")?,
            md5sum: text("md5sum")?,
            message_definition: text("message_definition")?,
            serialization: Serialization::Ros1,
            callerid: fields.string("callerid").ok().map(str::to_string),
            latching: fields.get("latching") == Some(b"1"),
        })
    }
}

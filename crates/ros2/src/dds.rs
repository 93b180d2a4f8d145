//! What every slamkit node does with DDS, whichever sensors it reads: starting the participant
//! (ROS 2's default discovery, or this machine only), making topics with ROS 2's QoS profiles,
//! taking samples off readers on a poll thread, and publishing a pose as `/tf`, `/pose` and a
//! `nav_msgs/Path`.

use crate::msgs::{self, Header, PoseWithCovariance, PoseWithCovarianceStamped, Time};
use crate::Ros2Error;
use crossbeam_channel::Sender;
use ros2_client::dds::rustdds::{DomainParticipant, DomainParticipantBuilder};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};
use slamkit_core::Pose3;
use std::net::{IpAddr, Ipv4Addr};
use std::time::SystemTime;

/// Where a node looks for its peers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Discovery {
    /// DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// Only peers on this machine, over `127.0.0.1` (ROS 2's `ROS_LOCALHOST_ONLY=1`, Jazzy's
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`): no interface but loopback is joined,
    /// advertised or sent to, and peers are found by unicast announcements to the well-known
    /// discovery ports on `127.0.0.1` (loopback carries no multicast unless it is switched
    /// on). Off, discovery is ROS 2's default: multicast on every interface.
    pub localhost_only: bool,
}

impl Discovery {
    /// The discovery the environment of a ROS 2 process asks for: `ROS_DOMAIN_ID`,
    /// `ROS_LOCALHOST_ONLY` (`1`) and `ROS_AUTOMATIC_DISCOVERY_RANGE` (`LOCALHOST`), each as
    /// read by the caller (a library does not read the process's environment).
    ///
    /// ```
    /// use slamkit_ros2::dds::Discovery;
    /// let d = Discovery::from_env(Some("7"), Some("1"), None).unwrap();
    /// assert_eq!((d.domain_id, d.localhost_only), (7, true));
    /// let d = Discovery::from_env(None, None, Some("SUBNET")).unwrap();
    /// assert_eq!((d.domain_id, d.localhost_only), (0, false));
    /// assert!(Discovery::from_env(Some("lab"), None, None).is_err());
    /// ```
    ///
    /// # Errors
    /// [`Ros2Error::Config`] for a domain that is not a number.
    pub fn from_env(
        domain_id: Option<&str>,
        localhost_only: Option<&str>,
        range: Option<&str>,
    ) -> Result<Self, Ros2Error> {
        let domain_id = match domain_id {
            Some(text) => text.parse().map_err(|_| {
                Ros2Error::Config(format!("ROS_DOMAIN_ID={text} is not a domain number"))
            })?,
            None => 0,
        };
        Ok(Self {
            domain_id,
            localhost_only: localhost_only == Some("1") || range == Some("LOCALHOST"),
        })
    }

    /// The DDS participant of this discovery (for plain DDS readers and writers; a ROS 2
    /// node is [`Self::node`]).
    ///
    /// # Errors
    /// [`Ros2Error::Dds`] when DDS cannot start.
    pub fn participant(&self) -> Result<DomainParticipant, Ros2Error> {
        let mut builder = DomainParticipantBuilder::new(self.domain_id);
        if self.localhost_only {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        builder.build().map_err(dds("starting DDS"))
    }

    /// A ROS 2 node named `name` on this discovery (no `/rosout`).
    ///
    /// # Errors
    /// [`Ros2Error::Dds`] when DDS cannot start, [`Ros2Error::Name`] for a bad node name.
    pub fn node(&self, name: &str) -> Result<Node, Ros2Error> {
        let participant = self.participant()?;
        let context = Context::from_domain_participant(participant).map_err(dds("starting DDS"))?;
        let node_name =
            NodeName::new("/", name).map_err(|e| Ros2Error::Name(format!("{name}: {e:?}")))?;
        context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(dds("creating the node"))
    }
}

/// ROS 2's sensor-data QoS (best effort, volatile), with a deeper history than rclcpp's 5:
/// the depth does not take part in matching, and the reader thread drains it anyway.
pub fn sensor_qos() -> QosProfile {
    QosProfile::subscription_default().history(History::KeepLast { depth: 100 })
}

/// Reliable and transient local: a late subscriber (RViz, Nav2) still gets the last sample.
pub fn latched_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// Reliable, volatile, keeping the last `depth` samples.
pub fn reliable_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .history(History::KeepLast { depth })
}

/// Turns a DDS error into [`Ros2Error::Dds`] naming `what` failed.
pub fn dds<E: std::fmt::Debug>(what: &str) -> impl Fn(E) -> Ros2Error + '_ {
    move |e| Ros2Error::Dds(format!("{what}: {e:?}"))
}

/// A topic of `package/ty` messages named `name`.
///
/// # Errors
/// [`Ros2Error::Name`] for a name ROS 2 refuses, [`Ros2Error::Dds`] when DDS cannot make it.
pub fn topic(
    node: &mut Node,
    name: &str,
    package: &str,
    ty: &str,
    qos: &QosProfile,
) -> Result<ros2_client::dds::rustdds::Topic, Ros2Error> {
    let parsed = Name::parse(name).map_err(|e| Ros2Error::Name(format!("{name}: {e:?}")))?;
    node.create_topic(&parsed, MessageTypeName::new(package, ty), qos)
        .map_err(dds(name))
}

/// A reader of `package/ty` on `name` with `qos`.
///
/// # Errors
/// As [`topic`].
pub fn subscribe<M: 'static>(
    node: &mut Node,
    name: &str,
    (package, ty): (&str, &str),
    qos: &QosProfile,
) -> Result<Subscription<M>, Ros2Error> {
    let t = topic(node, name, package, ty, qos)?;
    node.create_subscription(&t, None).map_err(dds(name))
}

/// A writer of `package/ty` on `name` with `qos`.
///
/// # Errors
/// As [`topic`].
pub fn advertise<M: serde::Serialize>(
    node: &mut Node,
    name: &str,
    (package, ty): (&str, &str),
    qos: &QosProfile,
) -> Result<Publisher<M>, Ros2Error> {
    let t = topic(node, name, package, ty, qos)?;
    node.create_publisher(&t, None).map_err(dds(name))
}

/// DDS source time of a sample \[ns\], else now (a writer that stamps nothing).
pub fn published_ns(info: &ros2_client::MessageInfo) -> i64 {
    info.source_timestamp().map_or_else(
        || {
            SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as i64)
        },
        |t| t.to_nanos(),
    )
}

/// Takes every sample a reader holds into `tx`, each wrapped by `wrap`; a read error is
/// wrapped by `error`. Returns false once `tx` is closed.
pub fn drain<M: 'static + serde::de::DeserializeOwned, T>(
    reader: &Subscription<M>,
    tx: &Sender<T>,
    wrap: impl Fn(M, &ros2_client::MessageInfo) -> T,
    error: impl Fn(String) -> T,
) -> bool {
    loop {
        let incoming = match reader.take() {
            Ok(Some((msg, info))) => wrap(msg, &info),
            Ok(None) => return true,
            Err(e) => error(format!("{e:?}")),
        };
        if tx.send(incoming).is_err() {
            return false;
        }
    }
}

/// Counts the messages a node could not use, keeping why for the first few.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Refusals {
    /// Messages that did not convert.
    pub count: usize,
    /// Why the first ones were refused.
    pub examples: Vec<String>,
}

impl Refusals {
    /// Examples kept.
    pub const KEPT: usize = 5;

    /// Counts one refused message.
    pub fn add(&mut self, why: String) {
        self.count += 1;
        if self.examples.len() < Self::KEPT {
            self.examples.push(why);
        }
    }
}

/// The writers of an estimated pose: the transform on `/tf`, the pose on `/pose`, and
/// optionally the path of all poses so far.
pub struct PoseWriters {
    /// `tf2_msgs/TFMessage`.
    pub tf: Publisher<msgs::TfMessage>,
    /// `geometry_msgs/PoseWithCovarianceStamped`.
    pub pose: Publisher<PoseWithCovarianceStamped>,
    /// `nav_msgs/Path`, with the poses published so far.
    pub path: Option<(Publisher<msgs::Path>, Vec<msgs::PoseStamped>)>,
}

/// Topic names of [`PoseWriters`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseTopics<'a> {
    /// Transforms.
    pub tf: &'a str,
    /// The pose.
    pub pose: &'a str,
    /// The path, if published.
    pub path: Option<&'a str>,
}

impl PoseWriters {
    /// Writers on `topics`: `/tf` reliable with a deep history, the pose reliable (as
    /// `slam_toolbox` publishes it), the path transient local (a late RViz gets it whole).
    ///
    /// # Errors
    /// As [`topic`].
    pub fn open(node: &mut Node, topics: &PoseTopics) -> Result<Self, Ros2Error> {
        let tf = advertise(
            node,
            topics.tf,
            ("tf2_msgs", "TFMessage"),
            &reliable_qos(100),
        )?;
        let pose = advertise(
            node,
            topics.pose,
            ("geometry_msgs", "PoseWithCovarianceStamped"),
            &reliable_qos(10),
        )?;
        let path = match topics.path {
            Some(name) => Some((
                advertise(node, name, ("nav_msgs", "Path"), &latched_qos())?,
                Vec::new(),
            )),
            None => None,
        };
        Ok(Self { tf, pose, path })
    }

    /// Publishes `parent_from_child` on `/tf` and `map_from_base` (in `map_frame`) on `/pose`
    /// and the path, at `stamp`. The covariance is left zero: the sessions do not estimate one.
    /// Best effort: a full send window must not stop the session, so send errors are dropped.
    pub fn publish(
        &mut self,
        (parent, child, parent_from_child): (&str, &str, &Pose3),
        map_frame: &str,
        map_from_base: &Pose3,
        stamp: Time,
    ) {
        let header = |frame: &str| Header {
            stamp,
            frame_id: frame.to_string(),
        };
        let tf = msgs::TfMessage {
            transforms: vec![msgs::TransformStamped {
                header: header(parent),
                child_frame_id: child.to_string(),
                transform: msgs::Pose::from_isometry(parent_from_child),
            }],
        };
        let _ = self.tf.publish(tf);
        let pose = msgs::Pose::from_isometry(map_from_base);
        let _ = self.pose.publish(PoseWithCovarianceStamped {
            header: header(map_frame),
            pose: PoseWithCovariance {
                pose,
                ..PoseWithCovariance::default()
            },
        });
        if let Some((writer, poses)) = &mut self.path {
            poses.push(msgs::PoseStamped {
                header: header(map_frame),
                pose,
            });
            let _ = writer.publish(msgs::Path {
                header: header(map_frame),
                poses: poses.clone(),
            });
        }
    }
}

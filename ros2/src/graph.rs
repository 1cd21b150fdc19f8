//! Joining the ROS 2 graph: the domain, the participant, topic names and their remapping, QoS.
//!
//! - **Domain**: `--ros-domain N` when given, else `ROS_DOMAIN_ID`, else 0 (ROS 2's rule). Valid
//!   domains are 0–232 (the RTPS port formula, `7400 + 250·domain + …`, must stay below 65536).
//! - **Localhost only**: `ROS_LOCALHOST_ONLY=1` (Humble) or
//!   `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` (Jazzy), or [`GraphConfig::localhost_only`],
//!   keeps discovery and data on 127.0.0.1. RustDDS also announces itself to the well-known
//!   unicast discovery ports on 127.0.0.1, so two participants on one host find each other
//!   without multicast on `lo` — which is how the tests run in a sandbox whose loopback has no
//!   multicast.
//! - **Names**: ROS 2 names (`/mmt/robot/pose`), travelling on DDS as `rt/mmt/robot/pose`.
//! - **QoS** ([`Qos`]): what ROS 2 calls reliability, durability and history depth.

use std::net::{IpAddr, Ipv4Addr};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::rustdds::mio1::{Interest, Poll, Token, event::Source};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{Context, MessageTypeName, Name, Node, NodeName, NodeOptions, QosProfile};

use crate::msg::RosMessage;

/// Largest ROS domain id.
pub const MAX_DOMAIN_ID: u16 = 232;

/// Why the graph could not be joined, or a name or QoS is not valid.
#[derive(Debug, thiserror::Error)]
pub enum GraphError {
    /// A domain id out of range.
    #[error("{source_name} = {value:?}: expected a ROS domain id, 0 to 232")]
    Domain {
        /// Where it came from (`--ros-domain` or `ROS_DOMAIN_ID`).
        source_name: &'static str,
        /// The value.
        value: String,
    },
    /// A topic name ROS 2 does not accept.
    #[error(
        "topic {what} = {name:?} is not a valid ROS 2 name ({reason}): expected e.g. /mmt/robot/pose"
    )]
    Name {
        /// Which topic.
        what: String,
        /// The name.
        name: String,
        /// The parser's reason.
        reason: String,
    },
    /// A QoS that cannot be parsed.
    #[error(
        "QoS {value:?}: {reason}; expected e.g. best-effort,volatile,keep-last-1 or reliable,transient-local,keep-last-1"
    )]
    Qos {
        /// The value.
        value: String,
        /// What is wrong.
        reason: String,
    },
    /// The DDS participant, a node or an endpoint could not be created.
    #[error("ROS 2 (DDS) {what}: {reason}")]
    Dds {
        /// What was being created.
        what: String,
        /// The middleware's reason.
        reason: String,
    },
}

/// Where and how to join the graph.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GraphConfig {
    /// The DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// Keep discovery and data on 127.0.0.1.
    pub localhost_only: bool,
}

impl GraphConfig {
    /// From `--ros-domain` (if given) and the environment: `ROS_DOMAIN_ID`, `ROS_LOCALHOST_ONLY`,
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    pub fn from_env(flag: Option<u16>) -> Result<GraphConfig, GraphError> {
        Self::from_vars(flag, |k| std::env::var(k).ok())
    }

    /// [`GraphConfig::from_env`] with the environment given (for tests).
    pub fn from_vars(
        flag: Option<u16>,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<GraphConfig, GraphError> {
        let domain_id = match flag {
            Some(d) if d <= MAX_DOMAIN_ID => d,
            Some(d) => {
                return Err(GraphError::Domain {
                    source_name: "--ros-domain",
                    value: d.to_string(),
                });
            }
            None => match var("ROS_DOMAIN_ID").filter(|v| !v.trim().is_empty()) {
                None => 0,
                Some(v) => match v.trim().parse::<u16>() {
                    Ok(d) if d <= MAX_DOMAIN_ID => d,
                    _ => {
                        return Err(GraphError::Domain {
                            source_name: "ROS_DOMAIN_ID",
                            value: v,
                        });
                    }
                },
            },
        };
        let localhost_only = var("ROS_LOCALHOST_ONLY").is_some_and(|v| v.trim() == "1")
            || var("ROS_AUTOMATIC_DISCOVERY_RANGE")
                .is_some_and(|v| v.trim().eq_ignore_ascii_case("LOCALHOST"));
        Ok(GraphConfig {
            domain_id,
            localhost_only,
        })
    }
}

/// A participant on the graph; clone it to share it between threads (each makes its own node).
#[derive(Clone)]
pub struct Graph {
    context: Context,
    config: GraphConfig,
}

impl std::fmt::Debug for Graph {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Graph")
            .field("config", &self.config)
            .finish()
    }
}

impl Graph {
    /// Joins the domain of `config`.
    pub fn join(config: &GraphConfig) -> Result<Graph, GraphError> {
        let mut builder = DomainParticipantBuilder::new(config.domain_id);
        if config.localhost_only {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = builder.build().map_err(|e| GraphError::Dds {
            what: format!("participant in domain {}", config.domain_id),
            reason: e.to_string(),
        })?;
        let context =
            Context::from_domain_participant(participant).map_err(|e| GraphError::Dds {
                what: "context".into(),
                reason: e.to_string(),
            })?;
        Ok(Graph {
            context,
            config: config.clone(),
        })
    }

    /// The configuration it joined with.
    pub fn config(&self) -> &GraphConfig {
        &self.config
    }

    /// A node `name` (no rosout, no parameter services: this side only publishes and
    /// subscribes).
    pub fn node(&self, name: &str) -> Result<Node, GraphError> {
        let dds = |reason: String| GraphError::Dds {
            what: format!("node {name}"),
            reason,
        };
        let node_name = NodeName::new("/", name).map_err(|e| dds(format!("{e:?}")))?;
        self.context
            .new_node(
                node_name,
                NodeOptions::new()
                    .enable_rosout(false)
                    .start_parameter_services(false),
            )
            .map_err(|e| dds(format!("{e:?}")))
    }
}

/// A checked topic name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicName(String);

impl TopicName {
    /// `name` if ROS 2 accepts it as an absolute topic name; `what` names it in the error.
    pub fn parse(what: &str, name: &str) -> Result<TopicName, GraphError> {
        let err = |reason: String| GraphError::Name {
            what: what.to_owned(),
            name: name.to_owned(),
            reason,
        };
        if !name.starts_with('/') {
            return Err(err("not absolute: start it with /".into()));
        }
        Name::parse(name).map_err(|e| err(format!("{e:?}")))?;
        Ok(TopicName(name.to_owned()))
    }

    /// The name.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The DDS topic it travels on (`rt/…`).
    pub fn dds_name(&self) -> String {
        format!("rt{}", self.0)
    }
}

impl std::fmt::Display for TopicName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Reliability, durability and history of an endpoint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Retransmit lost samples.
    pub reliable: bool,
    /// Late joiners get the last samples.
    pub transient_local: bool,
    /// Samples kept.
    pub depth: usize,
}

impl Qos {
    /// State in and commands out: best-effort, volatile, keep-last-1 (ROS 2's sensor-data
    /// profile with depth 1: the newest sample or nothing, never a queue of old ones).
    pub const STREAM: Qos = Qos {
        reliable: false,
        transient_local: false,
        depth: 1,
    };
    /// Settings (the model, the contact state): reliable, transient-local, keep-last-1, so a
    /// subscriber that joins late gets the current value.
    pub const SETTINGS: Qos = Qos {
        reliable: true,
        transient_local: true,
        depth: 1,
    };
    /// ROS 2's default (`SystemDefaultsQoS`, what forcedimension_ros2 publishes with):
    /// reliable, volatile, keep-last-10.
    pub const SYSTEM_DEFAULT: Qos = Qos {
        reliable: true,
        transient_local: false,
        depth: 10,
    };

    /// Parses `best-effort|reliable`, `volatile|transient-local`, `keep-last-N`, comma separated,
    /// each optional (the others from `base`).
    pub fn parse(text: &str, base: Qos) -> Result<Qos, GraphError> {
        let mut q = base;
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part {
                "best-effort" => q.reliable = false,
                "reliable" => q.reliable = true,
                "volatile" => q.transient_local = false,
                "transient-local" => q.transient_local = true,
                other => match other.strip_prefix("keep-last-").map(str::parse::<usize>) {
                    Some(Ok(n)) if (1..=1000).contains(&n) => q.depth = n,
                    _ => {
                        return Err(GraphError::Qos {
                            value: text.to_owned(),
                            reason: format!("unknown or out-of-range part {other:?}"),
                        });
                    }
                },
            }
        }
        Ok(q)
    }

    /// The `ros2-client` profile. A reliable writer that finds its window full waits at most
    /// 1 ms (it runs on an I/O thread, never the loop).
    pub fn profile(&self) -> QosProfile {
        let base = QosProfile::subscription_default();
        let base = if self.reliable {
            base.reliability(Reliability::Reliable {
                when_full: WhenFull::Wait(std::time::Duration::from_millis(1)),
            })
        } else {
            base.reliability(Reliability::BestEffort)
        };
        base.durability(if self.transient_local {
            Durability::TransientLocal
        } else {
            Durability::Volatile
        })
        .history(History::KeepLast { depth: self.depth })
    }
}

impl std::fmt::Display for Qos {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{},{},keep-last-{}",
            if self.reliable {
                "reliable"
            } else {
                "best-effort"
            },
            if self.transient_local {
                "transient-local"
            } else {
                "volatile"
            },
            self.depth
        )
    }
}

/// The `ros2-client` topic of message type `M` called `name` on `node`.
pub fn topic<M: RosMessage>(
    node: &Node,
    name: &TopicName,
    qos: Qos,
) -> Result<ros2_client::dds::rustdds::Topic, GraphError> {
    let ros_name = Name::parse(name.as_str()).map_err(|e| GraphError::Name {
        what: M::ros_name(),
        name: name.to_string(),
        reason: format!("{e:?}"),
    })?;
    node.create_topic(
        &ros_name,
        MessageTypeName::new(M::PACKAGE, M::NAME),
        &qos.profile(),
    )
    .map_err(|e| GraphError::Dds {
        what: format!("topic {name} ({})", M::ros_name()),
        reason: e.to_string(),
    })
}

/// A subscription to `name` of type `M`.
pub fn subscribe<M: RosMessage>(
    node: &mut Node,
    name: &TopicName,
    qos: Qos,
) -> Result<ros2_client::Subscription<M>, GraphError> {
    let t = topic::<M>(node, name, qos)?;
    node.create_subscription::<M>(&t, Some(qos.profile()))
        .map_err(|e| GraphError::Dds {
            what: format!("subscription to {name} ({})", M::ros_name()),
            reason: e.to_string(),
        })
}

/// A publisher on `name` of type `M`.
pub fn advertise<M: RosMessage>(
    node: &mut Node,
    name: &TopicName,
    qos: Qos,
) -> Result<ros2_client::Publisher<M>, GraphError> {
    let t = topic::<M>(node, name, qos)?;
    node.create_publisher::<M>(&t, Some(qos.profile()))
        .map_err(|e| GraphError::Dds {
            what: format!("publisher on {name} ({})", M::ros_name()),
            reason: e.to_string(),
        })
}

/// Takes the next message waiting on `sub` (an optional topic: `None`, nothing), if any. One
/// that does not decode is counted in `undecodable`; `any` is set when something (decodable or
/// not) was waiting, so that an I/O thread drains every subscription until none has anything
/// (readiness is edge-triggered).
pub(crate) fn take<M: RosMessage>(
    sub: Option<&ros2_client::Subscription<M>>,
    any: &mut bool,
    undecodable: &mut u64,
) -> Option<M> {
    match sub?.take() {
        Ok(Some((msg, _))) => {
            *any = true;
            Some(msg)
        }
        Ok(None) => None,
        Err(_) => {
            *any = true;
            *undecodable += 1;
            None
        }
    }
}

/// The error of creating `what` (a poll, a waker, a thread) on an I/O thread.
pub(crate) fn io_error(what: &str) -> impl FnOnce(std::io::Error) -> GraphError + '_ {
    move |e| GraphError::Dds {
        what: what.to_owned(),
        reason: e.to_string(),
    }
}

/// Registers `source` (an optional subscription: `None`, nothing) with `poll` for readable
/// events under `token`; `what` names it in the error.
pub(crate) fn register<S: Source>(
    poll: &Poll,
    source: Option<&mut S>,
    token: Token,
    what: &str,
) -> Result<(), GraphError> {
    match source {
        Some(s) => poll
            .registry()
            .register(s, token, Interest::READABLE)
            .map_err(io_error(what)),
        None => Ok(()),
    }
}

/// ROS time now (the system clock), in nanoseconds since the Unix epoch: what ROS 2 nodes stamp
/// headers with.
pub fn ros_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// ROS time − [`rt::monotonic_ns`] \[ns\]: adds to a loop time to stamp a header with it.
pub fn wall_minus_monotonic_ns() -> i64 {
    let before = rt::monotonic_ns();
    let wall = ros_now_ns();
    let after = rt::monotonic_ns();
    wall - (before + (after - before) / 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_domain_comes_from_the_flag_then_ros_domain_id_then_zero() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                pairs
                    .iter()
                    .find(|(key, _)| *key == k)
                    .map(|(_, v)| (*v).to_owned())
            }
        };
        let none: &[(&str, &str)] = &[];
        assert_eq!(
            GraphConfig::from_vars(None, env(none)).unwrap().domain_id,
            0
        );
        assert_eq!(
            GraphConfig::from_vars(None, env(&[("ROS_DOMAIN_ID", " 42 ")]))
                .unwrap()
                .domain_id,
            42
        );
        assert_eq!(
            GraphConfig::from_vars(Some(7), env(&[("ROS_DOMAIN_ID", "42")]))
                .unwrap()
                .domain_id,
            7
        );
        let e = GraphConfig::from_vars(None, env(&[("ROS_DOMAIN_ID", "300")])).unwrap_err();
        assert!(e.to_string().contains("ROS_DOMAIN_ID = \"300\""), "{e}");
        let e = GraphConfig::from_vars(None, env(&[("ROS_DOMAIN_ID", "x")])).unwrap_err();
        assert!(e.to_string().contains("0 to 232"), "{e}");
        let e = GraphConfig::from_vars(Some(233), env(none)).unwrap_err();
        assert!(e.to_string().contains("--ros-domain"), "{e}");
        assert!(
            GraphConfig::from_vars(None, env(&[("ROS_LOCALHOST_ONLY", "1")]))
                .unwrap()
                .localhost_only
        );
        assert!(
            GraphConfig::from_vars(None, env(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")]))
                .unwrap()
                .localhost_only
        );
        assert!(
            !GraphConfig::from_vars(None, env(none))
                .unwrap()
                .localhost_only
        );
    }

    #[test]
    fn topic_names_are_checked() {
        let t = TopicName::parse("robot_pose", "/franka/ee_pose").unwrap();
        assert_eq!(t.dds_name(), "rt/franka/ee_pose");
        for bad in ["franka/ee_pose", "/", "/a//b", "/a/b/", "/a-b", "/1a"] {
            let e = TopicName::parse("robot_pose", bad).unwrap_err();
            assert!(e.to_string().starts_with("topic robot_pose = "), "{e}");
        }
    }

    #[test]
    fn qos_parses_and_prints() {
        let q = Qos::parse("reliable,transient-local,keep-last-5", Qos::STREAM).unwrap();
        assert_eq!(
            q,
            Qos {
                reliable: true,
                transient_local: true,
                depth: 5
            }
        );
        assert_eq!(q.to_string(), "reliable,transient-local,keep-last-5");
        assert_eq!(Qos::parse("reliable", Qos::STREAM).unwrap().depth, 1);
        assert_eq!(Qos::STREAM.to_string(), "best-effort,volatile,keep-last-1");
        for bad in [
            "fast",
            "keep-last-0",
            "keep-last-x",
            "reliable,keep-last-100000",
        ] {
            assert!(Qos::parse(bad, Qos::STREAM).is_err(), "{bad}");
        }
    }
}

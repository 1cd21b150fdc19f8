//! One message → its channel's schema and its bytes: JSON (with a JSON Schema) for the recorded
//! types, protobuf with Foxglove's schemas for point clouds, events, the scene and transforms.

use foxglove::Encode as _;
use foxglove::messages::{Log, PackedElementField, PointCloud, Pose, Quaternion, Timestamp};
use foxglove::messages::{log, packed_element_field::NumericType};

use crate::schema::{CloudRec, EventRec, Level, Message, json_topic_schema, topic};

/// A channel's schema: name, encoding (`jsonschema`, `protobuf`) and data, and the message
/// encoding (`json`, `protobuf`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChannelSchema {
    /// Schema name (`mmt.OperatorTick`, `foxglove.PointCloud`, …).
    pub name: String,
    /// Schema encoding.
    pub schema_encoding: &'static str,
    /// Schema data: a JSON Schema, or a protobuf `FileDescriptorSet`.
    pub data: Vec<u8>,
    /// Message encoding.
    pub message_encoding: &'static str,
}

impl ChannelSchema {
    /// The schema of a Foxglove message type.
    pub fn foxglove<T: foxglove::Encode>() -> ChannelSchema {
        let schema = T::get_schema();
        ChannelSchema {
            name: schema.as_ref().map_or_else(String::new, |s| s.name.clone()),
            schema_encoding: "protobuf",
            data: schema.map_or_else(Vec::new, |s| s.data.into_owned()),
            message_encoding: "protobuf",
        }
    }
}

/// The schema of a topic of a recording.
pub fn topic_schema(topic_name: &str) -> Option<ChannelSchema> {
    if let Some((name, data)) = json_topic_schema(topic_name) {
        return Some(ChannelSchema {
            name: name.to_owned(),
            schema_encoding: "jsonschema",
            data,
            message_encoding: "json",
        });
    }
    Some(match topic_name {
        topic::OPERATOR_CLOUD | topic::TELEROBOT_CLOUD => ChannelSchema::foxglove::<PointCloud>(),
        topic::EVENTS => ChannelSchema::foxglove::<Log>(),
        topic::SCENE => ChannelSchema::foxglove::<foxglove::messages::SceneUpdate>(),
        topic::TF => ChannelSchema::foxglove::<foxglove::messages::FrameTransform>(),
        _ => return None,
    })
}

/// Encodes `message` into `buf` (cleared first); `log_time_ns` stamps the Foxglove messages.
pub fn encode(message: &Message, log_time_ns: u64, buf: &mut Vec<u8>) -> Result<(), String> {
    buf.clear();
    match message {
        Message::Run(m) => json(buf, m.as_ref()),
        Message::RunEnd(m) => json(buf, m.as_ref()),
        Message::OperatorTick(m) => json(buf, m.as_ref()),
        Message::Measurement(m) => json(buf, m.as_ref()),
        Message::Parameters(_, m) => json(buf, m.as_ref()),
        Message::Contact(_, m) => json(buf, m.as_ref()),
        Message::StateSync(_, m) => json(buf, m.as_ref()),
        Message::TelerobotTick(m) => json(buf, m.as_ref()),
        Message::Link(_, m) => json(buf, m.as_ref()),
        Message::Cloud(_, c) => point_cloud(c).encode(buf).map_err(|e| e.to_string()),
        Message::Event(e) => event(e, log_time_ns).encode(buf).map_err(|e| e.to_string()),
    }
}

fn json<T: serde::Serialize>(buf: &mut Vec<u8>, value: &T) -> Result<(), String> {
    serde_json::to_writer(buf, value).map_err(|e| e.to_string())
}

/// A Foxglove timestamp from nanoseconds since the Unix epoch.
pub fn timestamp(unix_ns: u64) -> Timestamp {
    let sec = u32::try_from(unix_ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (unix_ns % 1_000_000_000) as u32)
}

/// The identity pose.
pub fn identity_pose() -> Pose {
    Pose {
        position: Some(foxglove::messages::Vector3 {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    }
}

/// A cloud frame as a `foxglove.PointCloud` in the `world` frame: `x`, `y`, `z` as float32,
/// 12 bytes per point, little-endian.
pub fn point_cloud(c: &CloudRec) -> PointCloud {
    let mut data = Vec::with_capacity(c.points.len() * 12);
    for p in c.points.iter() {
        for v in p {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name: &str, offset: u32| PackedElementField {
        name: name.to_owned(),
        offset,
        r#type: NumericType::Float32 as i32,
    };
    PointCloud {
        timestamp: Some(timestamp(u64::try_from(c.timestamp_ns).unwrap_or(0))),
        frame_id: "world".to_owned(),
        pose: Some(identity_pose()),
        point_stride: 12,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        data: data.into(),
    }
}

/// The points of a `foxglove.PointCloud` written by [`point_cloud`]; `None` for another layout.
pub fn points_of(cloud: &PointCloud) -> Option<Vec<[f32; 3]>> {
    let float = NumericType::Float32 as i32;
    let layout = cloud.fields.len() == 3
        && cloud.point_stride == 12
        && ["x", "y", "z"]
            .iter()
            .zip(&cloud.fields)
            .enumerate()
            .all(|(i, (name, f))| f.name == *name && f.offset == 4 * i as u32 && f.r#type == float);
    if !layout || !cloud.data.len().is_multiple_of(12) {
        return None;
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    Some(
        cloud
            .data
            .chunks_exact(12)
            .map(|p| [f(&p[0..4]), f(&p[4..8]), f(&p[8..12])])
            .collect(),
    )
}

/// An event as a `foxglove.Log`.
pub fn event(e: &EventRec, log_time_ns: u64) -> Log {
    let level = match e.level {
        Level::Info => log::Level::Info,
        Level::Warning => log::Level::Warning,
        Level::Error => log::Level::Error,
    };
    Log {
        timestamp: Some(timestamp(log_time_ns)),
        level: level as i32,
        message: e.text.clone(),
        name: e.source.to_owned(),
        file: String::new(),
        line: 0,
    }
}

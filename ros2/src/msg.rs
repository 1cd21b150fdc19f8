//! The ROS 2 message types this system exchanges, defined here with ROS 2's exact type names and
//! CDR layout (XCDR1, final extensibility: the fields in declaration order, each aligned to its
//! own size from the start of the payload, strings as `u32` length with the NUL counted, then the
//! bytes and the NUL; sequences as `u32` count, then the elements).
//!
//! | ROS 2 type | DDS type name | here |
//! |---|---|---|
//! | `builtin_interfaces/msg/Time` | `builtin_interfaces::msg::dds_::Time_` | [`Time`] |
//! | `std_msgs/msg/Header` | `std_msgs::msg::dds_::Header_` | [`Header`] |
//! | `geometry_msgs/msg/PoseStamped` | `geometry_msgs::msg::dds_::PoseStamped_` | [`PoseStamped`] |
//! | `geometry_msgs/msg/TwistStamped` | `geometry_msgs::msg::dds_::TwistStamped_` | [`TwistStamped`] |
//! | `geometry_msgs/msg/WrenchStamped` | `geometry_msgs::msg::dds_::WrenchStamped_` | [`WrenchStamped`] |
//! | `sensor_msgs/msg/PointCloud2` | `sensor_msgs::msg::dds_::PointCloud2_` | [`PointCloud2`] |
//! | `std_msgs/msg/Float64MultiArray` | `std_msgs::msg::dds_::Float64MultiArray_` | [`Float64MultiArray`] |
//! | `std_msgs/msg/Bool` | `std_msgs::msg::dds_::Bool_` | [`Bool`] |
//!
//! The serde derives are the layout: `ros2-client` hands these structs to RustDDS's CDR codec
//! (`cdr-encoding`), which writes exactly the fields above. The golden-byte tests
//! (`msg/tests.rs`) pin the bytes against layouts worked out by hand from the `.msg` files.

use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A message type: its ROS 2 package and name (`geometry_msgs`, `PoseStamped`).
pub trait RosMessage: Serialize + for<'de> Deserialize<'de> + Send + 'static {
    /// The package, e.g. `geometry_msgs`.
    const PACKAGE: &'static str;
    /// The type, e.g. `PoseStamped`.
    const NAME: &'static str;

    /// `package/msg/Name`, as ROS 2 tools print it.
    fn ros_name() -> String {
        format!("{}/msg/{}", Self::PACKAGE, Self::NAME)
    }

    /// The name the type travels under on DDS: `package::msg::dds_::Name_`.
    fn dds_name() -> String {
        format!("{}::msg::dds_::{}_", Self::PACKAGE, Self::NAME)
    }
}

macro_rules! ros_message {
    ($ty:ty, $package:literal, $name:literal) => {
        impl RosMessage for $ty {
            const PACKAGE: &'static str = $package;
            const NAME: &'static str = $name;
        }
    };
}

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch (ROS time; the
/// system clock unless a driver says otherwise).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second, `0..1e9`.
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the epoch (saturating at the `i32` seconds range, as ROS does).
    pub fn from_nanos(ns: i64) -> Time {
        let sec = ns.div_euclid(1_000_000_000);
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        match i32::try_from(sec) {
            Ok(sec) => Time { sec, nanosec },
            Err(_) if sec < 0 => Time {
                sec: i32::MIN,
                nanosec: 0,
            },
            Err(_) => Time {
                sec: i32::MAX,
                nanosec: 999_999_999,
            },
        }
    }

    /// Nanoseconds since the epoch; `None` when `nanosec` is not below 1e9 (a malformed stamp).
    pub fn to_nanos(self) -> Option<i64> {
        (self.nanosec < 1_000_000_000)
            .then(|| i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec))
    }
}
ros_message!(Time, "builtin_interfaces", "Time");

/// `std_msgs/Header`: stamp and coordinate frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was acquired.
    pub stamp: Time,
    /// The frame the data is expressed in (e.g. `fr3_link0`).
    pub frame_id: String,
}
ros_message!(Header, "std_msgs", "Header");

/// `geometry_msgs/Point` \[m\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Quaternion` (x, y, z, w; ROS's default is the identity `w = 1`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl Vector3 {
    /// As an array.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// From an array.
    pub fn from_array(v: [f64; 3]) -> Vector3 {
        Vector3 {
            x: v[0],
            y: v[1],
            z: v[2],
        }
    }
}

impl Point {
    /// As an array.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// From an array.
    pub fn from_array(v: [f64; 3]) -> Point {
        Point {
            x: v[0],
            y: v[1],
            z: v[2],
        }
    }
}

/// `geometry_msgs/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position \[m\].
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}
ros_message!(PoseStamped, "geometry_msgs", "PoseStamped");

/// `geometry_msgs/Twist`: linear \[m/s\] and angular \[rad/s\] velocity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity \[m/s\].
    pub linear: Vector3,
    /// Angular velocity \[rad/s\].
    pub angular: Vector3,
}

/// `geometry_msgs/TwistStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The twist.
    pub twist: Twist,
}
ros_message!(TwistStamped, "geometry_msgs", "TwistStamped");

/// `geometry_msgs/Wrench`: force \[N\] and torque \[N·m\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Wrench {
    /// Force \[N\].
    pub force: Vector3,
    /// Torque \[N·m\].
    pub torque: Vector3,
}

/// `geometry_msgs/WrenchStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WrenchStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The wrench.
    pub wrench: Wrench,
}
ros_message!(WrenchStamped, "geometry_msgs", "WrenchStamped");

/// `sensor_msgs/PointField`: one field of a [`PointCloud2`] point.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PointField {
    /// Name (`x`, `y`, `z`, `rgb`, `intensity`, `ring`, ...).
    pub name: String,
    /// Byte offset within the point.
    pub offset: u32,
    /// One of the `PointField::INT8..FLOAT64` constants.
    pub datatype: u8,
    /// Elements in the field (1 for a scalar).
    pub count: u32,
}

impl PointField {
    /// `int8`.
    pub const INT8: u8 = 1;
    /// `uint8`.
    pub const UINT8: u8 = 2;
    /// `int16`.
    pub const INT16: u8 = 3;
    /// `uint16`.
    pub const UINT16: u8 = 4;
    /// `int32`.
    pub const INT32: u8 = 5;
    /// `uint32`.
    pub const UINT32: u8 = 6;
    /// `float32`.
    pub const FLOAT32: u8 = 7;
    /// `float64`.
    pub const FLOAT64: u8 = 8;

    /// Bytes of one element of `datatype`, `None` for an unknown datatype.
    pub fn datatype_size(datatype: u8) -> Option<u32> {
        match datatype {
            Self::INT8 | Self::UINT8 => Some(1),
            Self::INT16 | Self::UINT16 => Some(2),
            Self::INT32 | Self::UINT32 | Self::FLOAT32 => Some(4),
            Self::FLOAT64 => Some(8),
            _ => None,
        }
    }
}

/// `sensor_msgs/PointCloud2`: `height` rows of `width` points, `point_step` bytes each, rows
/// `row_step` bytes apart. Decoded by [`crate::pointcloud2`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    /// Stamp and the camera's frame.
    pub header: Header,
    /// Rows (1 for an unorganised cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The fields of a point.
    pub fields: Vec<PointField>,
    /// Multi-byte values are big-endian.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points.
    pub data: Bytes,
    /// No invalid (NaN) points.
    pub is_dense: bool,
}
ros_message!(PointCloud2, "sensor_msgs", "PointCloud2");

/// `std_msgs/MultiArrayDimension`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// Label of the dimension.
    pub label: String,
    /// Elements along it.
    pub size: u32,
    /// Stride.
    pub stride: u32,
}

/// `std_msgs/MultiArrayLayout`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// The dimensions.
    pub dim: Vec<MultiArrayDimension>,
    /// Padding elements at the front of `data`.
    pub data_offset: u32,
}

/// `std_msgs/Float64MultiArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64MultiArray {
    /// The layout.
    pub layout: MultiArrayLayout,
    /// The values.
    pub data: Vec<f64>,
}
ros_message!(Float64MultiArray, "std_msgs", "Float64MultiArray");

/// `std_msgs/Bool`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Bool {
    /// The value.
    pub data: bool,
}
ros_message!(Bool, "std_msgs", "Bool");

/// A `uint8[]` field (de)serialised as one block of bytes instead of one call per byte: the same
/// CDR bytes (a `u32` count, then the bytes), 5 MB of a camera frame copied at once.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct Bytes(pub Vec<u8>);

impl std::fmt::Debug for Bytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Bytes({} bytes)", self.0.len())
    }
}

impl Serialize for Bytes {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_bytes(&self.0)
    }
}

impl<'de> Deserialize<'de> for Bytes {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Bytes, D::Error> {
        deserializer.deserialize_byte_buf(BytesVisitor)
    }
}

struct BytesVisitor;

impl<'de> Visitor<'de> for BytesVisitor {
    type Value = Bytes;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a byte sequence")
    }

    fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Bytes, E> {
        Ok(Bytes(v.to_vec()))
    }

    fn visit_byte_buf<E: de::Error>(self, v: Vec<u8>) -> Result<Bytes, E> {
        Ok(Bytes(v))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Bytes, A::Error> {
        // Only formats without a byte-buffer path get here; the size hint is not trusted for
        // more than a bounded reservation.
        let mut v = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 16));
        while let Some(b) = seq.next_element()? {
            v.push(b);
        }
        Ok(Bytes(v))
    }
}

#[cfg(test)]
mod tests;

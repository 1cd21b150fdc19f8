//! Golden bytes: each layout worked out by hand from the `.msg` definitions and the XCDR1 rules
//! (align every primitive to its size from the payload start; strings `u32` length with NUL).

use byteorder::{BigEndian, LittleEndian};
use cdr_encoding::{from_bytes, to_vec};

use super::*;

fn le<T: Serialize>(value: &T) -> Vec<u8> {
    to_vec::<T, LittleEndian>(value).unwrap()
}

fn round_trip<T: RosMessage + PartialEq + std::fmt::Debug>(value: &T) {
    let bytes = le(value);
    let (back, used) = from_bytes::<T, LittleEndian>(&bytes).unwrap();
    assert_eq!(&back, value);
    assert_eq!(used, bytes.len());
    let be = to_vec::<T, BigEndian>(value).unwrap();
    let (back, _) = from_bytes::<T, BigEndian>(&be).unwrap();
    assert_eq!(&back, value, "big-endian encapsulation");
}

fn f64le(v: f64) -> [u8; 8] {
    v.to_le_bytes()
}

#[test]
fn type_names_are_ros2s() {
    assert_eq!(
        PoseStamped::dds_name(),
        "geometry_msgs::msg::dds_::PoseStamped_"
    );
    assert_eq!(PoseStamped::ros_name(), "geometry_msgs/msg/PoseStamped");
    assert_eq!(
        TwistStamped::dds_name(),
        "geometry_msgs::msg::dds_::TwistStamped_"
    );
    assert_eq!(
        WrenchStamped::dds_name(),
        "geometry_msgs::msg::dds_::WrenchStamped_"
    );
    assert_eq!(
        PointCloud2::dds_name(),
        "sensor_msgs::msg::dds_::PointCloud2_"
    );
    assert_eq!(
        Float64MultiArray::dds_name(),
        "std_msgs::msg::dds_::Float64MultiArray_"
    );
    assert_eq!(Bool::dds_name(), "std_msgs::msg::dds_::Bool_");
    assert_eq!(Header::dds_name(), "std_msgs::msg::dds_::Header_");
    assert_eq!(Time::dds_name(), "builtin_interfaces::msg::dds_::Time_");
    // ros2-client derives the same DDS name from package and type.
    let name = ros2_client::MessageTypeName::new(PoseStamped::PACKAGE, PoseStamped::NAME);
    assert_eq!(name.dds_msg_type(), PoseStamped::dds_name());
}

#[test]
fn header_bytes() {
    let h = Header {
        stamp: Time { sec: 1, nanosec: 2 },
        frame_id: "ab".into(),
    };
    assert_eq!(le(&h), [1, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0]);
    round_trip(&h);
}

#[test]
fn pose_stamped_bytes_pad_the_point_to_eight() {
    let m = PoseStamped {
        header: Header {
            stamp: Time {
                sec: -1,
                nanosec: 5,
            },
            frame_id: "b".into(),
        },
        pose: Pose {
            position: Point {
                x: 1.0,
                y: 2.0,
                z: 3.0,
            },
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.5,
                w: -0.25,
            },
        },
    };
    let mut want = vec![0xff, 0xff, 0xff, 0xff, 5, 0, 0, 0, 2, 0, 0, 0, b'b', 0];
    want.extend([0, 0]); // 14 → 16
    for v in [1.0, 2.0, 3.0, 0.0, 0.0, 0.5, -0.25] {
        want.extend(f64le(v));
    }
    assert_eq!(le(&m), want);
    assert_eq!(want.len(), 72);
    round_trip(&m);
}

#[test]
fn twist_and_wrench_stamped_bytes() {
    let header = Header {
        stamp: Time { sec: 7, nanosec: 0 },
        frame_id: String::new(),
    };
    // Empty frame: length 1 (the NUL), then pad 13 → 16.
    let mut prefix = vec![7, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0];
    let t = TwistStamped {
        header: header.clone(),
        twist: Twist {
            linear: Vector3::from_array([0.1, 0.2, 0.3]),
            angular: Vector3::from_array([4.0, 5.0, 6.0]),
        },
    };
    let mut want = prefix.clone();
    for v in [0.1, 0.2, 0.3, 4.0, 5.0, 6.0] {
        want.extend(f64le(v));
    }
    assert_eq!(le(&t), want);
    round_trip(&t);
    let w = WrenchStamped {
        header,
        wrench: Wrench {
            force: Vector3::from_array([-1.0, 0.0, 2.5]),
            torque: Vector3::from_array([0.0, 0.125, 0.0]),
        },
    };
    for v in [-1.0, 0.0, 2.5, 0.0, 0.125, 0.0] {
        prefix.extend(f64le(v));
    }
    assert_eq!(le(&w), prefix);
    round_trip(&w);
}

#[test]
fn float64_multi_array_bytes() {
    let m = Float64MultiArray {
        layout: MultiArrayLayout {
            dim: vec![MultiArrayDimension {
                label: "k".into(),
                size: 2,
                stride: 2,
            }],
            data_offset: 0,
        },
        data: vec![1.0, 2.0],
    };
    let mut want = vec![1, 0, 0, 0, 2, 0, 0, 0, b'k', 0, 0, 0];
    want.extend([2, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0]);
    want.extend([0, 0, 0, 0]); // 28 → 32
    want.extend(f64le(1.0));
    want.extend(f64le(2.0));
    assert_eq!(le(&m), want);
    round_trip(&m);
}

#[test]
fn bool_is_one_byte() {
    assert_eq!(le(&Bool { data: true }), [1]);
    assert_eq!(le(&Bool { data: false }), [0]);
    round_trip(&Bool { data: true });
}

#[test]
fn point_cloud2_bytes_carry_the_data_as_one_block() {
    let m = PointCloud2 {
        header: Header {
            stamp: Time::default(),
            frame_id: "c".into(),
        },
        height: 1,
        width: 2,
        fields: vec![PointField {
            name: "x".into(),
            offset: 0,
            datatype: PointField::FLOAT32,
            count: 1,
        }],
        is_bigendian: false,
        point_step: 4,
        row_step: 8,
        data: Bytes(vec![1, 2, 3, 4, 5, 6, 7, 8]),
        is_dense: true,
    };
    let mut want = vec![0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0, b'c', 0, 0, 0];
    want.extend([1, 0, 0, 0, 2, 0, 0, 0]); // height, width
    want.extend([1, 0, 0, 0, 2, 0, 0, 0, b'x', 0, 0, 0]); // one field, "x", pad 34 → 36
    want.extend([0, 0, 0, 0, 7, 0, 0, 0, 1, 0, 0, 0]); // offset, datatype + pad, count
    want.extend([0, 0, 0, 0, 4, 0, 0, 0, 8, 0, 0, 0]); // is_bigendian + pad, steps
    want.extend([8, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 1]); // data, is_dense
    assert_eq!(le(&m), want);
    round_trip(&m);
}

#[test]
fn truncated_bytes_are_an_error_not_a_panic() {
    let m = PointCloud2 {
        data: Bytes(vec![0; 64]),
        ..PointCloud2::default()
    };
    let bytes = le(&m);
    for cut in 0..bytes.len() {
        assert!(from_bytes::<PointCloud2, LittleEndian>(&bytes[..cut]).is_err());
    }
    // A data length far beyond the buffer.
    let mut lying = bytes.clone();
    let at = bytes.len() - 64 - 1 - 4;
    lying[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(from_bytes::<PointCloud2, LittleEndian>(&lying).is_err());
}

#[test]
fn time_conversions() {
    assert_eq!(
        Time::from_nanos(1_500_000_000),
        Time {
            sec: 1,
            nanosec: 500_000_000
        }
    );
    assert_eq!(
        Time::from_nanos(-1),
        Time {
            sec: -1,
            nanosec: 999_999_999
        }
    );
    assert_eq!(Time::from_nanos(-1).to_nanos(), Some(-1));
    assert_eq!(Time::from_nanos(i64::MAX).sec, i32::MAX);
    assert_eq!(
        Time {
            sec: 0,
            nanosec: 1_000_000_000
        }
        .to_nanos(),
        None
    );
}

//! Point-cloud frames: points in the world frame with their capture time and sensor pose
//! (`DESIGN.md` §5, thesis appendix C and H.2.1).
//!
//! # Frames and units
//!
//! A [`CloudFrame`] holds points **in the world frame**, in metres, stored as `f32` (a depth
//! camera's precision; 640×480 points are 3.7 MB). The proxy math ([`crate::contact`]) is done in
//! `f64`. The frame also carries the capture time (`timestamp_ns`, the sensor's clock, in ns) and
//! where the sensor was (`sensor_pose`, world ← sensor); points measured in the sensor frame are
//! brought into the world frame with [`CloudFrame::from_sensor_points`].
//!
//! Where frames come from is not this crate's business: synthetic clouds are the `sim` crate's,
//! PLY/PCD files and voxel downsampling the `cloud-io` crate's.

mod pose;

pub use pose::Pose;

use thiserror::Error;

use crate::vec3;

/// Why a set of points cannot make a [`CloudFrame`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CloudError {
    /// A coordinate is NaN or infinite.
    #[error("point {index}: coordinate {axis} is {value}, expected a finite number")]
    NonFinite {
        /// Index of the point in the input.
        index: usize,
        /// `x`, `y` or `z`.
        axis: char,
        /// The offending value.
        value: f32,
    },
    /// A coordinate is finite but beyond [`CloudFrame::MAX_ABS_COORDINATE_M`].
    #[error("point {index}: coordinate {axis} = {value} m, expected |{axis}| <= {limit} m")]
    OutOfRange {
        /// Index of the point in the input.
        index: usize,
        /// `x`, `y` or `z`.
        axis: char,
        /// The offending value [m].
        value: f32,
        /// The limit [m].
        limit: f32,
    },
    /// More points than a `u32` index can address (the kd-tree's item type).
    #[error("{count} points, expected at most {max}")]
    TooManyPoints {
        /// Number of points given.
        count: usize,
        /// The limit.
        max: usize,
    },
}

/// One point-cloud frame: world-frame points [m] with capture time and sensor pose.
///
/// Built only through [`CloudFrame::new`] (or [`CloudFrame::from_sensor_points`]), so every
/// point is finite and within [`CloudFrame::MAX_ABS_COORDINATE_M`] of the origin: a frame that
/// exists is safe to index and to feed to the proxy.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudFrame {
    points: Vec<[f32; 3]>,
    timestamp_ns: i64,
    sensor_pose: Pose,
}

impl CloudFrame {
    /// Largest accepted |coordinate| [m]: 1000 km. Anything beyond is a unit or parsing error
    /// (and `f32::MAX` is a sentinel inside the kd-tree).
    pub const MAX_ABS_COORDINATE_M: f32 = 1.0e6;

    /// Most points in one frame (the kd-tree indexes points with `u32`).
    pub const MAX_POINTS: usize = u32::MAX as usize;

    /// A frame of world-frame points [m], captured at `timestamp_ns` (sensor clock) by a
    /// sensor at `sensor_pose` (world ← sensor). Rejects non-finite and out-of-range points,
    /// naming the first offender.
    pub fn new(
        points: Vec<[f32; 3]>,
        timestamp_ns: i64,
        sensor_pose: Pose,
    ) -> Result<Self, CloudError> {
        if points.len() > Self::MAX_POINTS {
            return Err(CloudError::TooManyPoints {
                count: points.len(),
                max: Self::MAX_POINTS,
            });
        }
        for (index, p) in points.iter().enumerate() {
            check_point(index, *p)?;
        }
        Ok(Self {
            points,
            timestamp_ns,
            sensor_pose,
        })
    }

    /// A frame from points measured in the sensor frame: each is mapped to the world frame by
    /// `sensor_pose` (in `f64`, then rounded to `f32`).
    pub fn from_sensor_points(
        points_in_sensor: &[[f32; 3]],
        timestamp_ns: i64,
        sensor_pose: Pose,
    ) -> Result<Self, CloudError> {
        let world = points_in_sensor
            .iter()
            .map(|p| vec3::to_f32(sensor_pose.transform_point(vec3::from_f32(*p))))
            .collect();
        Self::new(world, timestamp_ns, sensor_pose)
    }

    /// The points, world frame [m].
    pub fn points(&self) -> &[[f32; 3]] {
        &self.points
    }

    /// Capture time [ns] on the sensor's clock.
    pub fn timestamp_ns(&self) -> i64 {
        self.timestamp_ns
    }

    /// Where the sensor was (world ← sensor).
    pub fn sensor_pose(&self) -> &Pose {
        &self.sensor_pose
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Gives the points back.
    pub fn into_points(self) -> Vec<[f32; 3]> {
        self.points
    }
}

fn check_point(index: usize, p: [f32; 3]) -> Result<(), CloudError> {
    for (value, axis) in p.into_iter().zip(['x', 'y', 'z']) {
        if !value.is_finite() {
            return Err(CloudError::NonFinite { index, axis, value });
        }
        if value.abs() > CloudFrame::MAX_ABS_COORDINATE_M {
            return Err(CloudError::OutOfRange {
                index,
                axis,
                value,
                limit: CloudFrame::MAX_ABS_COORDINATE_M,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_non_finite_and_out_of_range_points_by_index() {
        let err =
            CloudFrame::new(vec![[0.0; 3], [0.0, f32::NAN, 0.0]], 0, Pose::IDENTITY).unwrap_err();
        assert!(matches!(
            err,
            CloudError::NonFinite {
                index: 1,
                axis: 'y',
                ..
            }
        ));
        assert!(err.to_string().contains("point 1"));
        let err = CloudFrame::new(vec![[0.0, 0.0, f32::MAX]], 0, Pose::IDENTITY).unwrap_err();
        assert!(matches!(
            err,
            CloudError::OutOfRange {
                index: 0,
                axis: 'z',
                ..
            }
        ));
    }

    #[test]
    fn sensor_points_are_moved_into_the_world_frame() {
        let pose = Pose::from_translation([1.0, 2.0, 3.0]);
        let frame = CloudFrame::from_sensor_points(&[[0.5, 0.0, 0.0]], 7, pose).unwrap();
        assert_eq!(frame.points(), &[[1.5, 2.0, 3.0]]);
        assert_eq!(frame.timestamp_ns(), 7);
        assert_eq!(frame.sensor_pose(), &pose);
    }
}

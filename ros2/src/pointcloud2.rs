//! `sensor_msgs/PointCloud2` decoding: any field layout a camera driver sends, into points in the
//! robot's base frame.
//!
//! What a layout may be, and what is checked (every refusal names the field and the value):
//! - `x`, `y`, `z` fields, each `float32` or `float64` with `count ≥ 1` (the first element is
//!   read), at any offset, each inside `point_step`; other fields (`rgb`, `intensity`, `ring`,
//!   padding) are skipped by `point_step`;
//! - `point_step` larger than the fields, `row_step` larger than `width · point_step` (row
//!   padding), either byte order (`is_bigendian`);
//! - `is_dense = false` with NaN (or infinite) points: left out and counted — as are they when a
//!   driver claims `is_dense = true` and sends them anyway;
//! - `data` must hold every row: `(height − 1) · row_step + width · point_step` bytes at least
//!   (checked in 64-bit arithmetic, so no product can wrap).
//!
//! [`decode_into`] reuses the caller's buffer and allocates nothing once it is large enough; the
//! voxel grid ([`cloud_io::voxel::VoxelGrid`]) and the point budget follow in
//! [`CloudPipeline`]. A 307,200-point organised frame with NaN holes is decoded, transformed and
//! downsampled in a few milliseconds (`cargo bench -p ros2 --bench pointcloud2`).

use cloud_io::voxel::{VoxelError, VoxelGrid};
use mmt::cloud::Pose;

use crate::msg::{PointCloud2, PointField};

/// Why a PointCloud2 message cannot be decoded. Each names the field and the value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// A coordinate field is missing.
    #[error("no `{axis}` field (fields: {fields}): expected x, y and z")]
    MissingField {
        /// `x`, `y` or `z`.
        axis: char,
        /// The fields the message has.
        fields: String,
    },
    /// A coordinate field is of a type that cannot hold a coordinate.
    #[error("field `{axis}` has datatype {datatype}: expected 7 (float32) or 8 (float64)")]
    FieldType {
        /// `x`, `y` or `z`.
        axis: char,
        /// The datatype given.
        datatype: u8,
    },
    /// A coordinate field with `count = 0`.
    #[error("field `{axis}` has count 0: expected at least 1")]
    FieldCount {
        /// `x`, `y` or `z`.
        axis: char,
    },
    /// A coordinate field reaches past the end of a point.
    #[error(
        "field `{axis}` at offset {offset} ({size} bytes) does not fit in point_step {point_step}"
    )]
    FieldOutsidePoint {
        /// `x`, `y` or `z`.
        axis: char,
        /// Its offset.
        offset: u32,
        /// Its size in bytes.
        size: u32,
        /// The point's size.
        point_step: u32,
    },
    /// `row_step` cannot hold a row.
    #[error("row_step {row_step} < width {width} × point_step {point_step}")]
    RowStep {
        /// The row step given.
        row_step: u32,
        /// Points per row.
        width: u32,
        /// Bytes per point.
        point_step: u32,
    },
    /// `data` is shorter than the rows it must hold.
    #[error(
        "data has {len} bytes, expected at least {needed} for {height} rows × {width} points \
         (row_step {row_step}, point_step {point_step})"
    )]
    DataTooShort {
        /// Bytes given.
        len: usize,
        /// Bytes needed.
        needed: u64,
        /// Rows.
        height: u32,
        /// Points per row.
        width: u32,
        /// Bytes per row.
        row_step: u32,
        /// Bytes per point.
        point_step: u32,
    },
    /// More points than a frame can hold.
    #[error("{count} points (width {width} × height {height}): expected at most {max}")]
    TooManyPoints {
        /// width · height.
        count: u64,
        /// Points per row.
        width: u32,
        /// Rows.
        height: u32,
        /// The limit.
        max: u64,
    },
}

/// Most points one message may declare: 16 M (a 4K depth image has 8.3 M).
pub const MAX_POINTS: u64 = 1 << 24;

/// Where one coordinate sits in a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Coordinate {
    offset: usize,
    float64: bool,
}

/// The checked layout of a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    xyz: [Coordinate; 3],
    big_endian: bool,
    point_step: usize,
    row_step: usize,
    width: usize,
    height: usize,
}

impl Layout {
    /// Checks `msg`'s fields, steps and data length.
    pub fn of(msg: &PointCloud2) -> Result<Layout, DecodeError> {
        let count = u64::from(msg.width) * u64::from(msg.height);
        if count > MAX_POINTS {
            return Err(DecodeError::TooManyPoints {
                count,
                width: msg.width,
                height: msg.height,
                max: MAX_POINTS,
            });
        }
        let mut xyz = [Coordinate {
            offset: 0,
            float64: false,
        }; 3];
        for (c, axis) in xyz.iter_mut().zip(['x', 'y', 'z']) {
            *c = coordinate(msg, axis)?;
        }
        let row = u64::from(msg.width) * u64::from(msg.point_step);
        if count > 0 && u64::from(msg.row_step) < row {
            return Err(DecodeError::RowStep {
                row_step: msg.row_step,
                width: msg.width,
                point_step: msg.point_step,
            });
        }
        let needed = if count == 0 {
            0
        } else {
            u64::from(msg.height - 1) * u64::from(msg.row_step) + row
        };
        if (msg.data.0.len() as u64) < needed {
            return Err(DecodeError::DataTooShort {
                len: msg.data.0.len(),
                needed,
                height: msg.height,
                width: msg.width,
                row_step: msg.row_step,
                point_step: msg.point_step,
            });
        }
        // An empty cloud has no rows to read, whatever its other dimension says: `width 0,
        // height 2^32 − 1` used to make the decoder walk four billion empty rows (seconds of
        // the camera thread per message; found by the `pointcloud2` fuzz target).
        let (width, height) = if count == 0 {
            (0, 0)
        } else {
            (msg.width as usize, msg.height as usize)
        };
        Ok(Layout {
            xyz,
            big_endian: msg.is_bigendian,
            point_step: msg.point_step as usize,
            row_step: msg.row_step as usize,
            width,
            height,
        })
    }

    /// Rows the decoder reads: `height`, or 0 for an empty cloud.
    pub fn rows(&self) -> usize {
        self.height
    }

    /// Points the message declares (`width · height`).
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

fn coordinate(msg: &PointCloud2, axis: char) -> Result<Coordinate, DecodeError> {
    let name = axis.to_string();
    let Some(f) = msg.fields.iter().find(|f| f.name == name) else {
        return Err(DecodeError::MissingField {
            axis,
            fields: msg
                .fields
                .iter()
                .map(|f| f.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        });
    };
    let float64 = match f.datatype {
        PointField::FLOAT32 => false,
        PointField::FLOAT64 => true,
        datatype => return Err(DecodeError::FieldType { axis, datatype }),
    };
    if f.count == 0 {
        return Err(DecodeError::FieldCount { axis });
    }
    let size = if float64 { 8 } else { 4 };
    if u64::from(f.offset) + size > u64::from(msg.point_step) {
        return Err(DecodeError::FieldOutsidePoint {
            axis,
            offset: f.offset,
            size: size as u32,
            point_step: msg.point_step,
        });
    }
    Ok(Coordinate {
        offset: f.offset as usize,
        float64,
    })
}

/// What [`decode_into`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecodeCounts {
    /// Points the message declared.
    pub declared: usize,
    /// Points left out: a coordinate NaN or infinite (holes of an organised depth image).
    pub non_finite: usize,
    /// Points left out: beyond [`mmt::cloud::CloudFrame::MAX_ABS_COORDINATE_M`] after the
    /// transform (a unit or driver error).
    pub out_of_range: usize,
}

/// Decodes every finite point of `msg` (laid out as `layout`, from [`Layout::of`]), maps it by
/// `camera_to_base` (base ← camera) and appends it to `out` (cleared first). Allocates only if
/// `out` is too small.
///
/// The usual layout (`x`, `y`, `z` consecutive little-endian `float32`, as every depth camera
/// and lidar driver sends) has a loop of its own; any other reads each coordinate by its type and
/// byte order. Both compute the same: the coordinates in `f64`, `R·p + t` summed left to right,
/// rounded to `f32` once.
pub fn decode_into(
    msg: &PointCloud2,
    layout: &Layout,
    camera_to_base: &Pose,
    out: &mut Vec<[f32; 3]>,
) -> DecodeCounts {
    let [x, y, z] = layout.xyz;
    let packed = !(layout.big_endian || x.float64 || y.float64 || z.float64)
        && y.offset == x.offset + 4
        && z.offset == x.offset + 8;
    if packed {
        decode_with(msg, layout, camera_to_base, out, |point| {
            let b = point.get(x.offset..)?.first_chunk::<12>()?;
            let f = |i: usize| f64::from(f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]));
            Some([f(0), f(4), f(8)])
        })
    } else {
        decode_with(msg, layout, camera_to_base, out, |point| {
            Some(layout.xyz.map(|c| read(point, c, layout.big_endian)))
        })
    }
}

/// [`decode_into`] with `read_xyz` reading a point's coordinates (`None`: not inside the point,
/// which [`Layout::of`] rules out).
#[inline(always)]
fn decode_with(
    msg: &PointCloud2,
    layout: &Layout,
    camera_to_base: &Pose,
    out: &mut Vec<[f32; 3]>,
    read_xyz: impl Fn(&[u8]) -> Option<[f64; 3]>,
) -> DecodeCounts {
    // Every point is written at `kept`, which moves on only for a point kept: no branch per
    // point. `out` keeps its capacity between frames (no allocation once it has grown), but
    // `resize` writes the frame's length past the last frame's kept points each time.
    out.resize(layout.len(), [0.0; 3]);
    let mut kept = 0;
    let mut non_finite = 0;
    let data = msg.data.0.as_slice();
    let r = camera_to_base.rotation;
    let t = camera_to_base.translation_m;
    let limit = f64::from(mmt::cloud::CloudFrame::MAX_ABS_COORDINATE_M);
    let points = (0..layout.height).flat_map(|row| {
        let start = row * layout.row_step;
        // Layout::of checked that every row's points lie inside `data`.
        let bytes = data.get(start..start + layout.width * layout.point_step);
        bytes.unwrap_or_default().chunks_exact(layout.point_step)
    });
    for point in points {
        let p = read_xyz(point).unwrap_or([f64::NAN; 3]);
        let w = [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + t[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + t[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + t[2],
        ];
        // A non-finite coordinate makes every `w` NaN or infinite, so this one test keeps a
        // point; a point it drops is non-finite or else out of range. `&`, not `&&`: no branch.
        let ok = (w[0].abs() <= limit) & (w[1].abs() <= limit) & (w[2].abs() <= limit);
        let finite = (p[0] * 0.0 + p[1] * 0.0 + p[2] * 0.0) == 0.0;
        // kept ≤ points read ≤ out.len().
        if let Some(slot) = out.get_mut(kept) {
            *slot = [w[0] as f32, w[1] as f32, w[2] as f32];
        }
        kept += usize::from(ok);
        non_finite += usize::from(!finite);
    }
    out.truncate(kept);
    DecodeCounts {
        declared: layout.len(),
        non_finite,
        out_of_range: layout.len() - kept - non_finite,
    }
}

#[inline(always)]
fn read(point: &[u8], c: Coordinate, big_endian: bool) -> f64 {
    if c.float64 {
        let b: [u8; 8] = match point
            .get(c.offset..c.offset + 8)
            .and_then(|s| s.try_into().ok())
        {
            Some(b) => b,
            None => return f64::NAN,
        };
        if big_endian {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    } else {
        let b: [u8; 4] = match point
            .get(c.offset..c.offset + 4)
            .and_then(|s| s.try_into().ok())
        {
            Some(b) => b,
            None => return f64::NAN,
        };
        f64::from(if big_endian {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        })
    }
}

/// How a camera's frames become the contact detector's cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineConfig {
    /// base ← camera (from the scene).
    pub camera_to_base: Pose,
    /// Voxel edge [m]; `None` keeps every point.
    pub voxel_m: Option<f64>,
    /// Most points kept; above it the voxel edge grows until the cloud fits.
    pub max_points: usize,
}

/// What one frame became.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameCounts {
    /// Decoding.
    pub decode: DecodeCounts,
    /// Points after the voxel grid and the budget.
    pub kept: usize,
    /// The voxel edge that met the budget [m] (the configured one unless the budget acted).
    pub voxel_m: Option<f64>,
    /// The point budget made the voxel edge grow.
    pub budget_acted: bool,
}

/// Why a frame was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// The message's layout.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The voxel grid refused the points.
    #[error("voxel grid: {0}")]
    Voxel(#[from] VoxelError),
}

/// Decode → transform → voxel → budget, with buffers kept between frames (a camera thread owns
/// one).
#[derive(Debug)]
pub struct CloudPipeline {
    config: PipelineConfig,
    decoded: Vec<[f32; 3]>,
    grid: VoxelGrid,
}

impl CloudPipeline {
    /// A pipeline for `config`.
    pub fn new(config: PipelineConfig) -> CloudPipeline {
        CloudPipeline {
            config,
            decoded: Vec::new(),
            grid: VoxelGrid::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.config
    }

    /// One frame: the points, base frame, in `out` (cleared first).
    pub fn process(
        &mut self,
        msg: &PointCloud2,
        out: &mut Vec<[f32; 3]>,
    ) -> Result<FrameCounts, FrameError> {
        let layout = Layout::of(msg)?;
        let decode = decode_into(msg, &layout, &self.config.camera_to_base, &mut self.decoded);
        let (voxel_m, budget_acted) = self.grid.downsample_to_budget(
            &self.decoded,
            self.config.voxel_m,
            self.config.max_points,
            out,
        )?;
        Ok(FrameCounts {
            decode,
            kept: out.len(),
            voxel_m,
            budget_acted,
        })
    }
}

/// A PointCloud2 of `points` as a depth camera driver sends them (`realsense2_camera`'s layout:
/// `x`, `y`, `z` float32 at 0, 4, 8 and a packed `rgb` float32 at 12, 16 bytes per point,
/// little-endian, one row), in the frame `frame_id`, stamped `stamp_ns`. NaN points are kept
/// (`is_dense` says whether there are any). What the test arm publishes.
pub fn encode_xyz(points: &[[f32; 3]], frame_id: &str, stamp_ns: i64) -> PointCloud2 {
    const STEP: usize = 16;
    let mut data = Vec::with_capacity(points.len() * STEP);
    let mut dense = true;
    for p in points {
        dense &= p.iter().all(|c| c.is_finite());
        for c in p {
            data.extend_from_slice(&c.to_le_bytes());
        }
        data.extend_from_slice(&0x00C0_C0C0_u32.to_le_bytes()); // grey
    }
    let field = |name: &str, offset: u32| PointField {
        name: name.to_owned(),
        offset,
        datatype: PointField::FLOAT32,
        count: 1,
    };
    PointCloud2 {
        header: crate::msg::Header {
            stamp: crate::msg::Time::from_nanos(stamp_ns),
            frame_id: frame_id.to_owned(),
        },
        height: 1,
        width: points.len() as u32,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("rgb", 12),
        ],
        is_bigendian: false,
        point_step: STEP as u32,
        row_step: (points.len() * STEP) as u32,
        data: crate::msg::Bytes(data),
        is_dense: dense,
    }
}

#[cfg(test)]
mod tests;

//! The scene's `[cloud]`: where the contact detector's point cloud comes from.
//!
//! ```toml
//! [cloud]                      # the simulated camera (default)
//! source = "plane"             # plane | file | ros2 | none
//! size_m = [0.3, 0.3]
//! centre = "tool"              # tool | surface: where the window is centred
//! spacing_m = 0.0045
//! noise_m = 0.0005
//! dropout = 0.0                # random missing points
//! holes = 0.0                  # fraction of the face in hole patches (dark, shiny parts)
//! hole_radius_m = 0.015        # their mean radius
//! depth_noise_per_m = 0.0      # depth noise σ = this × range² along the ray
//! camera_distance_m = 0.6      # the range: camera above the window's centre
//! rate_hz = 30.0
//! moving = true
//!
//! [cloud]                      # a recorded cloud: PLY or PCD
//! source = "file"
//! path = "clouds/table.ply"    # absolute, or relative to the scene file
//! pose = { translation_m = [0.0, 0.0, 0.0], quaternion_xyzw = [0.0, 0.0, 0.0, 1.0] }
//! voxel_m = 0.003              # optional voxel grid spacing
//! max_points = 200000          # optional point budget (default 200,000)
//! rate_hz = 30.0               # how often it is re-sent when moving
//! moving = false               # false: sent once
//!
//! [cloud]                      # a camera on a ROS 2 graph (sensor_msgs/PointCloud2)
//! source = "ros2"
//! topic = "/camera/camera/depth/color/points"
//! pose = { translation_m = [0.5, 0.0, 0.6], quaternion_xyzw = [1.0, 0.0, 0.0, 0.0] }
//! voxel_m = 0.003
//! max_points = 200000
//! stale_ms = 200.0             # a cloud older than this is flagged stale
//! ```
//!
//! `pose` is base ← cloud (the file's or the camera's frame in the robot's base frame): the
//! translation \[m\] and the rotation as a unit quaternion (x, y, z, w), the order of ROS's
//! `geometry_msgs/Transform` and `static_transform_publisher`.

use mmt::cloud::Pose;
use serde::{Deserialize, Serialize};

use super::validate::SceneError;

/// Default point budget of a file or ROS 2 cloud: a 300 mm × 300 mm patch at 1 mm, well within
/// a kd-tree built in a few milliseconds.
pub const DEFAULT_MAX_POINTS: usize = 200_000;

/// Default age beyond which a ROS 2 cloud is flagged stale \[ms\]: several frames of a 30 Hz
/// camera.
pub const DEFAULT_STALE_MS: f64 = 200.0;

/// Where the point cloud comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloudSource {
    /// `plane`: the simulated camera on the object's contact face; `file`: a PLY or PCD file;
    /// `ros2`: `sensor_msgs/PointCloud2` from a camera driver; `none`: no cloud (contact from
    /// the true geometry on the telerobot, remote contact on the operator).
    pub source: CloudKind,
    /// `plane`: the camera's window on the face, along the surface's two tangents [m], centred
    /// as `centre` says. Centred on the tool, it must cover the tool's motion over a round trip
    /// (at 400 ms each way and 15 cm/s, 12 cm); on the surface point, the workspace the tool
    /// uses.
    pub size_m: [f64; 2],
    /// `plane`: where the window is centred: on the tool (a camera that follows it, as one on
    /// the wrist does), or on the scene's surface point (a camera fixed above the table; then
    /// `size_m` must cover the tool's whole workspace, at any delay).
    pub centre: WindowCentre,
    /// `plane`: grid spacing [m]. Must be below `√2·(r1 + r2)/2` of the proxy.
    pub spacing_m: f64,
    /// `plane`: Gaussian noise per coordinate [m].
    pub noise_m: f64,
    /// `plane`: fraction of points dropped per frame, at random (missing depth pixels).
    pub dropout: f64,
    /// `plane`: fraction of the face in clustered holes: patches with no depth that stay on the
    /// object (dark or shiny parts of its surface), of mean radius `hole_radius_m`
    /// ([`crate::holes`]). Default 0.
    pub holes: f64,
    /// `plane`: mean radius of the hole patches [m] (radii uniform in 0.5–1.5 times it).
    /// Default 0.015: patches 1.5–4.5 cm across.
    pub hole_radius_m: f64,
    /// `plane`: depth noise along the camera's ray, `σ = depth_noise_per_m · range²` [1/m]
    /// (a stereo camera's; a RealSense D435 is about 0.0037: 1.3 mm at 0.6 m, 3 mm at 0.9 m),
    /// beside `noise_m`. Default 0.
    pub depth_noise_per_m: f64,
    /// `plane`: distance of the camera from the face, along the normal above the window's
    /// centre [m]: the range the depth noise grows with. Default 0.6.
    pub camera_distance_m: f64,
    /// Frame rate [Hz] (`file`: how often a moving cloud is re-sent).
    pub rate_hz: f64,
    /// The cloud follows the object as it slides (new frames each `1/rate_hz`). A static cloud is
    /// sent once.
    pub moving: bool,
    /// `file`: the PLY or PCD file (absolute, or relative to the scene file).
    pub path: Option<String>,
    /// `ros2`: the PointCloud2 topic (default `/mmt/camera/points`).
    pub topic: Option<String>,
    /// `file`, `ros2`: base ← cloud.
    pub pose: CloudPose,
    /// `file`, `ros2`: voxel grid spacing [m]; none keeps every point.
    pub voxel_m: Option<f64>,
    /// `file`, `ros2`: the point budget; above it the voxel spacing grows until the cloud fits.
    pub max_points: usize,
    /// `ros2`: a cloud older than this is flagged stale [ms].
    pub stale_ms: f64,
    /// The loops' real-time budget for this robot PC (`[cloud.budget]`: any of
    /// `mmt::contact::budget::CloudBudget`'s fields; the rest keep their defaults, measured on
    /// a loaded 2-core machine). The telerobot holds every cloud to it; the operator holds the
    /// frames it receives to its own default budget.
    pub budget: mmt::contact::budget::CloudBudget,
}

impl Default for CloudSource {
    fn default() -> Self {
        CloudSource {
            source: CloudKind::Plane,
            size_m: [0.3, 0.3],
            centre: WindowCentre::Tool,
            spacing_m: 0.0045,
            noise_m: 0.0005,
            dropout: 0.0,
            holes: 0.0,
            hole_radius_m: 0.015,
            depth_noise_per_m: 0.0,
            camera_distance_m: 0.6,
            rate_hz: 30.0,
            moving: true,
            path: None,
            topic: None,
            pose: CloudPose::default(),
            voxel_m: None,
            max_points: DEFAULT_MAX_POINTS,
            stale_ms: DEFAULT_STALE_MS,
            budget: mmt::contact::budget::CloudBudget::default(),
        }
    }
}

/// Point-cloud source kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CloudKind {
    /// A noisy plane patch on the contact surface.
    Plane,
    /// A PLY or PCD file.
    File,
    /// `sensor_msgs/PointCloud2` on a ROS 2 graph.
    Ros2,
    /// No cloud.
    None,
}

/// Where the simulated camera's window on the face is centred.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WindowCentre {
    /// On the tool, frame by frame. Over a link of round trip `T` the operator's newest frame
    /// is centred where the tool was `T` ago: `size_m` must cover the tool's motion over `T`.
    Tool,
    /// On the scene's surface point, whatever the tool does.
    Surface,
}

/// A rigid transform as a scene writes it: base ← cloud.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloudPose {
    /// Translation [m].
    pub translation_m: [f64; 3],
    /// Rotation, a unit quaternion (x, y, z, w).
    pub quaternion_xyzw: [f64; 4],
}

impl Default for CloudPose {
    fn default() -> Self {
        CloudPose {
            translation_m: [0.0; 3],
            quaternion_xyzw: [0.0, 0.0, 0.0, 1.0],
        }
    }
}

impl CloudPose {
    /// The pose; `None` if the quaternion is not a unit one (within 1e-3) or a value is not
    /// finite.
    pub fn pose(&self) -> Option<Pose> {
        let [x, y, z, w] = self.quaternion_xyzw;
        let norm = (x * x + y * y + z * z + w * w).sqrt();
        if !(norm.is_finite() && (norm - 1.0).abs() <= 1e-3) {
            return None;
        }
        if !self.translation_m.iter().all(|v| v.is_finite()) {
            return None;
        }
        Pose::from_quaternion([w, x, y, z], self.translation_m)
    }
}

/// `cloud.budget.NAME` for a field of the budget.
fn budget_field(name: &str) -> &'static str {
    match name {
        "step_share" => "cloud.budget.step_share",
        "step_fixed_ns" => "cloud.budget.step_fixed_ns",
        "step_ns_per_point" => "cloud.budget.step_ns_per_point",
        "index_share" => "cloud.budget.index_share",
        "build_ns_per_point" => "cloud.budget.build_ns_per_point",
        "max_points" => "cloud.budget.max_points",
        _ => "cloud.budget",
    }
}

fn field(
    field: &'static str,
    value: impl std::fmt::Debug,
    ok: bool,
    expected: &'static str,
) -> Result<(), SceneError> {
    if ok {
        Ok(())
    } else {
        Err(SceneError::Field {
            origin: String::new(),
            field,
            value: format!("{value:?}"),
            expected,
        })
    }
}

impl CloudSource {
    /// The simulated camera's largest noise along the normal [m]: the per-coordinate noise and
    /// the depth noise at the window's farthest corner, added in quadrature.
    pub fn noise_sigma_m(&self) -> f64 {
        let half = [0.5 * self.size_m[0], 0.5 * self.size_m[1]];
        let range = (self.camera_distance_m.powi(2) + half[0].powi(2) + half[1].powi(2)).sqrt();
        let depth = crate::holes::depth_sigma_m(self.depth_noise_per_m, range);
        self.noise_m.hypot(depth)
    }

    /// Every number of the section is finite, whichever source reads it: a key the source
    /// ignores is still part of the accepted scene (written back out by `toml`, shown in
    /// reports), and a NaN there used to pass because only the source's own keys were checked.
    pub(super) fn validate_finite(&self) -> Result<(), SceneError> {
        let p = &self.pose;
        let numbers: [(&'static str, &[f64]); 12] = [
            ("cloud.size_m", &self.size_m),
            ("cloud.spacing_m", &[self.spacing_m]),
            ("cloud.noise_m", &[self.noise_m]),
            ("cloud.dropout", &[self.dropout]),
            ("cloud.holes", &[self.holes]),
            ("cloud.hole_radius_m", &[self.hole_radius_m]),
            ("cloud.depth_noise_per_m", &[self.depth_noise_per_m]),
            ("cloud.camera_distance_m", &[self.camera_distance_m]),
            ("cloud.rate_hz", &[self.rate_hz]),
            ("cloud.stale_ms", &[self.stale_ms]),
            ("cloud.pose.translation_m", &p.translation_m),
            ("cloud.pose.quaternion_xyzw", &p.quaternion_xyzw),
        ];
        for (name, values) in numbers {
            field(
                name,
                values,
                values.iter().all(|v| v.is_finite()),
                "finite numbers (every key is checked, whichever source uses it)",
            )?;
        }
        if let Some(v) = self.voxel_m {
            field("cloud.voxel_m", v, v.is_finite(), "a finite number")?;
        }
        Ok(())
    }

    /// The real-time budget's keys, and those of a `file` or `ros2` source (the plane's are
    /// checked with the proxy, in `validate`).
    pub(super) fn validate_external(&self) -> Result<(), SceneError> {
        // Every source: the budget holds file and ROS 2 clouds as it holds the plane.
        if let Some((name, value, expected)) = self.budget.invalid_field() {
            field(budget_field(name), value, false, expected)?;
        }
        match self.source {
            CloudKind::File => field(
                "cloud.path",
                &self.path,
                self.path.as_ref().is_some_and(|p| !p.trim().is_empty()),
                "a PLY or PCD file (source = \"file\" needs path = \"…\")",
            )?,
            CloudKind::Ros2 => field(
                "cloud.topic",
                &self.topic,
                self.topic.as_ref().is_none_or(|t| t.starts_with('/')),
                "an absolute topic name, e.g. \"/camera/camera/depth/color/points\"",
            )?,
            CloudKind::Plane | CloudKind::None => return Ok(()),
        }
        field(
            "cloud.pose",
            self.pose,
            self.pose.pose().is_some(),
            "finite translation_m and a unit quaternion_xyzw (x, y, z, w)",
        )?;
        if let Some(v) = self.voxel_m {
            field(
                "cloud.voxel_m",
                v,
                v.is_finite() && (1e-4..=1.0).contains(&v),
                "in [0.1 mm, 1 m]",
            )?;
        }
        field(
            "cloud.max_points",
            self.max_points,
            (1..=protocol::MAX_CLOUD_POINTS).contains(&self.max_points),
            "1 to 4,194,304 (the largest cloud the protocol carries)",
        )?;
        field(
            "cloud.stale_ms",
            self.stale_ms,
            self.stale_ms.is_finite() && self.stale_ms > 0.0,
            "a finite age > 0 ms",
        )?;
        field(
            "cloud.rate_hz",
            self.rate_hz,
            self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 1000.0,
            "in (0, 1000] Hz",
        )
    }
}

//! A scene's `[cloud] source = "file"`: a PLY or PCD file, read once at start, mapped into the
//! robot's base frame by the scene's pose, voxel-downsampled and held to the point budget; then
//! sent as frames like the simulated camera's (once, or at `rate_hz` following the object when
//! `moving`).

use std::path::{Path, PathBuf};

use cloud_io::voxel::{VoxelError, VoxelGrid};
use cloud_io::{LoadError, LoadOptions, NonFinitePolicy};
use mmt::cloud::{CloudError, CloudFrame, Pose};
use mmt::vec3;
use sim::scene::{CloudSource, Scene};
use sim::world::World;

/// Why a cloud file cannot be used (refused at start).
#[derive(Debug, thiserror::Error)]
pub enum CloudFileError {
    /// The scene names no file.
    #[error("[cloud] source = \"file\" needs path = \"…\"")]
    NoPath,
    /// The file could not be read or parsed (the loader's located error).
    #[error("cloud file {0}")]
    Load(#[from] LoadError),
    /// The scene's pose is not a rigid transform.
    #[error("[cloud] pose {0:?}: expected finite translation_m and a unit quaternion_xyzw")]
    Pose(sim::scene::CloudPose),
    /// The voxel grid refused the points.
    #[error("cloud file {path}: voxel grid: {source}")]
    Voxel {
        /// The file.
        path: PathBuf,
        /// Why.
        source: VoxelError,
    },
    /// Over the real-time budget even at the coarsest voxel the proxy cannot slip through.
    #[error("cloud file {path}: {source}")]
    Budget {
        /// The file.
        path: PathBuf,
        /// Why.
        source: cloud_io::budget::BudgetFitError,
    },
    /// Nothing left (every point was non-finite, or the file is empty).
    #[error("cloud file {path}: no finite points ({skipped} non-finite skipped)")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Non-finite points skipped.
        skipped: usize,
    },
    /// A point is out of the cloud frame's range after the pose.
    #[error("cloud file {path}: {source}")]
    Frame {
        /// The file.
        path: PathBuf,
        /// Why.
        source: CloudError,
    },
}

/// What was loaded, for the start log and the report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FileCloudInfo {
    /// The file.
    pub path: PathBuf,
    /// Points in the file (finite ones).
    pub read: usize,
    /// Non-finite points skipped.
    pub skipped_non_finite: usize,
    /// Points kept after the voxel grid and the budget.
    pub kept: usize,
    /// The voxel spacing used [m] (grown beyond the scene's when the budget acted).
    pub voxel_m: Option<f64>,
    /// The point budget made the voxel spacing grow.
    pub budget_acted: bool,
    /// What the real-time budget did after the point budget (`None`: nothing), for the
    /// start-up warning.
    #[serde(skip)]
    pub real_time: Option<cloud_io::budget::BudgetFit>,
}

/// A cloud from a file, in the base frame, ready to be sent.
#[derive(Debug)]
pub struct FileCloud {
    points: Vec<[f32; 3]>,
    info: FileCloudInfo,
    moving: bool,
    period_ns: i64,
    next_ns: Option<i64>,
    tangents: [[f64; 3]; 2],
    shifted: Vec<[f32; 3]>,
}

/// The file a scene's cloud path names: absolute, or relative to the scene file's directory
/// (`scene_file` `None`: the working directory).
pub fn resolve(path: &str, scene_file: Option<&Path>) -> PathBuf {
    let p = Path::new(path);
    match scene_file.and_then(Path::parent) {
        Some(dir) if p.is_relative() => dir.join(p),
        _ => p.to_owned(),
    }
}

impl FileCloud {
    /// Loads the file of `scene`'s `[cloud]` (its path already resolved, see [`resolve`]);
    /// `geometry` gives the surface's tangents a moving cloud slides along.
    pub fn load(scene: &Scene, geometry: &World) -> Result<FileCloud, CloudFileError> {
        let c: &CloudSource = &scene.cloud;
        let path = PathBuf::from(c.path.as_deref().ok_or(CloudFileError::NoPath)?);
        let loaded = cloud_io::load_path(
            &path,
            LoadOptions {
                non_finite: NonFinitePolicy::Skip,
            },
        )?;
        let pose: Pose = c.pose.pose().ok_or(CloudFileError::Pose(c.pose))?;
        let base: Vec<[f32; 3]> = loaded
            .points
            .iter()
            .map(|p| pose.transform_point(p.map(f64::from)).map(|v| v as f32))
            .collect();
        let mut points = Vec::new();
        let mut grid = VoxelGrid::new();
        let (mut voxel_m, budget_acted) = grid
            .downsample_to_budget(&base, c.voxel_m, c.max_points, &mut points)
            .map_err(|source| CloudFileError::Voxel {
                path: path.clone(),
                source,
            })?;
        // The loops' budget (`mmt::contact::budget`): the proxy's worst step at the scene's
        // radii and rate, and the frames at `rate_hz` when the cloud moves.
        let proxy = scene.proxy.config(scene.rates.control_hz);
        let rate = c.moving.then_some(c.rate_hz);
        let budget = scene.cloud.budget;
        let real_time =
            cloud_io::budget::fit_to_budget(&mut points, &proxy, &budget, rate, &mut grid)
                .map_err(|source| CloudFileError::Budget {
                    path: path.clone(),
                    source,
                })?;
        if let Some(fit) = &real_time {
            voxel_m = Some(fit.voxel_m);
        }
        if points.is_empty() {
            return Err(CloudFileError::Empty {
                path,
                skipped: loaded.skipped_non_finite,
            });
        }
        // The frame's own checks (coordinate range), once, so that no frame fails later.
        CloudFrame::new(points.clone(), 0, Pose::IDENTITY).map_err(|source| {
            CloudFileError::Frame {
                path: path.clone(),
                source,
            }
        })?;
        let frame = geometry.frame();
        Ok(FileCloud {
            info: FileCloudInfo {
                path,
                read: loaded.points.len(),
                skipped_non_finite: loaded.skipped_non_finite,
                kept: points.len(),
                voxel_m,
                budget_acted,
                real_time,
            },
            points,
            moving: c.moving,
            period_ns: (1e9 / c.rate_hz).round() as i64,
            next_ns: None,
            tangents: [frame.tangent1, frame.tangent2],
            shifted: Vec::new(),
        })
    }

    /// What was loaded.
    pub fn info(&self) -> &FileCloudInfo {
        &self.info
    }

    /// A frame if one is due at `now_ns`: the first at once; then, when moving, one each period,
    /// the points moved by the object's slide `offset` along the surface's tangents.
    pub fn frame(
        &mut self,
        now_ns: i64,
        offset: &[f64; 2],
    ) -> Result<Option<CloudFrame>, CloudError> {
        match self.next_ns {
            Some(_) if !self.moving => return Ok(None),
            Some(next) if now_ns < next => return Ok(None),
            _ => {}
        }
        self.next_ns = Some(now_ns + self.period_ns);
        let shift = vec3::add(
            vec3::scale(self.tangents[0], offset[0]),
            vec3::scale(self.tangents[1], offset[1]),
        )
        .map(|v| v as f32);
        self.shifted.clear();
        self.shifted.extend(
            self.points
                .iter()
                .map(|p| [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]]),
        );
        CloudFrame::new(self.shifted.clone(), now_ns, Pose::IDENTITY).map(Some)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use cloud_io::{PcdEncoding, PlyEncoding, encode_pcd, encode_ply};
    use sim::scene::{CloudKind, CloudPose};

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("mmt-cloud-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    /// A 1 mm grid of `n`×`n` points on z = 0 in the file's frame, half a millimetre off the
    /// voxel edges.
    fn grid(n: usize) -> Vec<[f32; 3]> {
        let at = |k: usize| (k as f32 + 0.5) * 0.001;
        (0..n * n).map(|i| [at(i % n), at(i / n), 0.0]).collect()
    }

    fn scene_with(path: &Path, tweak: impl FnOnce(&mut CloudSource)) -> (Scene, World) {
        let mut scene = Scene::exp1();
        scene.cloud.source = CloudKind::File;
        scene.cloud.path = Some(path.display().to_string());
        tweak(&mut scene.cloud);
        let world = World::new(&scene, [0.0, 0.0, 0.01], 1).unwrap();
        (scene, world)
    }

    #[test]
    fn a_ply_file_is_posed_voxelised_and_sent_once() {
        let path = temp("grid.ply");
        std::fs::write(
            &path,
            encode_ply(&grid(100), PlyEncoding::BinaryLittleEndian),
        )
        .unwrap();
        // base ← file: 90° about x (y → z), then 1 m along x.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let (scene, world) = scene_with(&path, |c| {
            c.pose = CloudPose {
                translation_m: [1.0, 0.0, 0.0],
                quaternion_xyzw: [h, 0.0, 0.0, h],
            };
            c.voxel_m = Some(0.002);
            c.moving = false;
        });
        let mut file = FileCloud::load(&scene, &world).unwrap();
        let info = file.info().clone();
        assert_eq!(
            (info.read, info.kept, info.budget_acted),
            (10_000, 2_500, false)
        );
        let frame = file.frame(5, &[0.0; 2]).unwrap().unwrap();
        assert_eq!(frame.points().len(), 2_500);
        for p in frame.points() {
            // x in [1, 1.1], the file's y became z, and y = 0.
            assert!((1.0..=1.1).contains(&p[0]) && p[1].abs() < 1e-6, "{p:?}");
            assert!((0.0..=0.1).contains(&p[2]), "{p:?}");
        }
        // Not moving: sent once.
        assert!(file.frame(1_000_000_000, &[0.0; 2]).unwrap().is_none());
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn the_budget_holds_and_a_moving_cloud_follows_the_object() {
        let path = temp("grid.pcd");
        std::fs::write(&path, encode_pcd(&grid(200), PcdEncoding::Binary)).unwrap();
        let (scene, world) = scene_with(&path, |c| {
            c.max_points = 1_000;
            c.rate_hz = 10.0;
            c.moving = true;
        });
        let mut file = FileCloud::load(&scene, &world).unwrap();
        let info = file.info().clone();
        assert!(
            info.budget_acted && info.kept <= 1_000 && info.kept > 300,
            "{info:?}"
        );
        let first = file.frame(0, &[0.0; 2]).unwrap().unwrap();
        assert!(file.frame(50_000_000, &[0.01, 0.0]).unwrap().is_none());
        let moved = file.frame(100_000_000, &[0.01, 0.0]).unwrap().unwrap();
        let t1 = world.frame().tangent1;
        for (a, b) in first.points().iter().zip(moved.points()) {
            for k in 0..3 {
                assert!((b[k] - a[k] - 0.01 * t1[k] as f32).abs() < 1e-6);
            }
        }
        std::fs::remove_file(&path).unwrap();
    }

    /// Issue 11, finding 5: a million-point file (0.25 mm) within the point budget's reach no
    /// longer reaches the loops unreduced: the real-time budget downsamples it further, and
    /// says so for the start-up warning.
    #[test]
    fn a_million_point_file_is_held_to_the_real_time_budget() {
        let path = temp("dense.ply");
        let points: Vec<[f32; 3]> = (0..1_001 * 1_001)
            .map(|k| {
                [
                    (k % 1_001) as f32 * 0.00025,
                    (k / 1_001) as f32 * 0.00025,
                    0.0,
                ]
            })
            .collect();
        std::fs::write(&path, encode_ply(&points, PlyEncoding::BinaryLittleEndian)).unwrap();
        let (scene, world) = scene_with(&path, |c| {
            c.max_points = 1_000_000;
            c.moving = true;
        });
        let file = FileCloud::load(&scene, &world).unwrap();
        let info = file.info().clone();
        let fit = info.real_time.expect("over the real-time budget");
        let b = mmt::contact::budget::CloudBudget::default();
        assert!(info.kept <= b.max_points(Some(30.0)), "{info:?}");
        assert_eq!(
            (fit.after.points, info.voxel_m),
            (info.kept, Some(fit.voxel_m))
        );
        let proxy = scene.proxy.config(scene.rates.control_hz);
        assert!(fit.after.points_in_ball <= b.max_points_in_ball(&proxy));
        assert!(
            fit.to_string().contains("over the real-time budget"),
            "{fit}"
        );
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn a_bad_file_is_refused_with_the_loaders_located_error() {
        let path = temp("bad.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
             property float z\nend_header\n0 0 0\n1 oops 2\n",
        )
        .unwrap();
        let (scene, world) = scene_with(&path, |_| {});
        let e = FileCloud::load(&scene, &world).unwrap_err().to_string();
        assert!(
            e.contains(&path.display().to_string()) && e.contains("line 9"),
            "{e}"
        );
        let (scene, world) = scene_with(Path::new("/nonexistent/cloud.pcd"), |_| {});
        let e = FileCloud::load(&scene, &world).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/cloud.pcd"), "{e}");
        // Only NaN points: nothing to use.
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             property float z\nend_header\nnan 0 0\n",
        )
        .unwrap();
        let (scene, world) = scene_with(&path, |_| {});
        let e = FileCloud::load(&scene, &world).unwrap_err().to_string();
        assert!(e.contains("no finite points (1 non-finite skipped)"), "{e}");
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn a_relative_path_is_the_scene_files_neighbour() {
        let scene_file = Path::new("/labs/a/scenes/table.toml");
        assert_eq!(
            resolve("clouds/t.ply", Some(scene_file)),
            PathBuf::from("/labs/a/scenes/clouds/t.ply")
        );
        assert_eq!(
            resolve("/abs/t.ply", Some(scene_file)),
            PathBuf::from("/abs/t.ply")
        );
        assert_eq!(resolve("t.ply", None), PathBuf::from("t.ply"));
    }
}

//! A camera on the ROS 2 graph: `sensor_msgs/PointCloud2` from any driver (`realsense2_camera`,
//! `zed_wrapper`, …) → points in the robot's base frame, voxel-downsampled to the budget
//! ([`crate::pointcloud2::CloudPipeline`]), as [`CloudFrame`]s timed on the loop's clock.
//!
//! Polled by the telerobot's camera thread (never the 1 kHz loop): each poll takes every message
//! that arrived and processes the newest only (older ones are counted as superseded). A message
//! that cannot be used — undecodable CDR, a bad layout, data shorter than its fields say, no
//! finite point — is refused and counted, never a panic; a cloud older than the configured age
//! when it arrives is used and counted stale.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use mmt::cloud::{CloudFrame, Pose};
use ros2_client::{Node, Subscription};
use serde::Serialize;

use crate::graph::{self, Graph, GraphError, Qos, TopicName};
use crate::msg::PointCloud2;
use crate::pointcloud2::{CloudPipeline, PipelineConfig};

/// What a camera source needs.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraConfig {
    /// The PointCloud2 topic.
    pub topic: TopicName,
    /// Its QoS (camera drivers publish best-effort or reliable, keep-last; best-effort
    /// subscriptions match both).
    pub qos: Qos,
    /// Frame transform, voxel grid, budget.
    pub pipeline: PipelineConfig,
    /// A cloud older than this on arrival is counted stale \[ns\].
    pub stale_ns: i64,
}

/// The camera source's counters (shared with whoever reports them).
#[derive(Debug, Default)]
pub struct CameraCounters {
    messages: AtomicU64,
    frames: AtomicU64,
    superseded: AtomicU64,
    undecodable: AtomicU64,
    refused: AtomicU64,
    stale: AtomicU64,
    non_finite_points: AtomicU64,
    budget_acted: AtomicU64,
    max_age_ns: AtomicU64,
}

/// The counters, read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CameraReport {
    /// Messages taken.
    pub messages: u64,
    /// Frames made (one per poll with news).
    pub frames: u64,
    /// Messages left for a newer one of the same poll.
    pub superseded: u64,
    /// Messages whose CDR could not be decoded.
    pub undecodable: u64,
    /// Messages refused: bad layout, short data, no finite point (the log names why, once).
    pub refused: u64,
    /// Frames older than the configured age on arrival.
    pub stale: u64,
    /// NaN/infinite points left out (an organised cloud's holes).
    pub non_finite_points: u64,
    /// Frames the point budget coarsened.
    pub budget_acted: u64,
    /// The oldest frame on arrival \[ms\].
    pub max_age_ms: f64,
}

impl CameraCounters {
    /// Reads them.
    pub fn report(&self) -> CameraReport {
        CameraReport {
            messages: self.messages.load(Relaxed),
            frames: self.frames.load(Relaxed),
            superseded: self.superseded.load(Relaxed),
            undecodable: self.undecodable.load(Relaxed),
            refused: self.refused.load(Relaxed),
            stale: self.stale.load(Relaxed),
            non_finite_points: self.non_finite_points.load(Relaxed),
            budget_acted: self.budget_acted.load(Relaxed),
            max_age_ms: self.max_age_ns.load(Relaxed) as f64 * 1e-6,
        }
    }
}

/// A PointCloud2 subscription and its pipeline.
pub struct CameraSource {
    _node: Node,
    sub: Subscription<PointCloud2>,
    pipeline: CloudPipeline,
    config: CameraConfig,
    counters: Arc<CameraCounters>,
    points: Vec<[f32; 3]>,
    /// ROS time − loop clock \[ns\], measured at start.
    wall_offset_ns: i64,
    /// The last refusal's reason, logged when it changes.
    last_refusal: Option<String>,
}

impl CameraSource {
    /// Subscribes on `graph`.
    pub fn start(graph: &Graph, config: CameraConfig) -> Result<CameraSource, GraphError> {
        let mut node = graph.node("mmt_camera")?;
        let sub = graph::subscribe::<PointCloud2>(&mut node, &config.topic, config.qos)?;
        Ok(CameraSource {
            _node: node,
            sub,
            pipeline: CloudPipeline::new(config.pipeline),
            config,
            counters: Arc::new(CameraCounters::default()),
            points: Vec::new(),
            wall_offset_ns: graph::wall_minus_monotonic_ns(),
            last_refusal: None,
        })
    }

    /// The counters, to report.
    pub fn counters(&self) -> Arc<CameraCounters> {
        Arc::clone(&self.counters)
    }

    /// The newest usable cloud that arrived since the last poll, if any; `now_ns` on the loop's
    /// clock.
    pub fn poll(&mut self, now_ns: i64) -> Option<CloudFrame> {
        let mut newest = None;
        loop {
            match self.sub.take() {
                Ok(Some((msg, _))) => {
                    self.counters.messages.fetch_add(1, Relaxed);
                    if newest.replace(msg).is_some() {
                        self.counters.superseded.fetch_add(1, Relaxed);
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    self.counters.messages.fetch_add(1, Relaxed);
                    self.counters.undecodable.fetch_add(1, Relaxed);
                    self.refuse(format!("undecodable CDR: {e}"));
                }
            }
        }
        let msg = newest?;
        match self.frame(&msg, now_ns) {
            Ok(frame) => Some(frame),
            Err(reason) => {
                self.counters.refused.fetch_add(1, Relaxed);
                self.refuse(reason);
                None
            }
        }
    }

    /// One message → one frame (its stamp on the loop's clock), or why not.
    pub fn frame(&mut self, msg: &PointCloud2, now_ns: i64) -> Result<CloudFrame, String> {
        let topic = &self.config.topic;
        let counts = self
            .pipeline
            .process(msg, &mut self.points)
            .map_err(|e| format!("{topic}: {e}"))?;
        self.counters
            .non_finite_points
            .fetch_add(counts.decode.non_finite as u64, Relaxed);
        if counts.budget_acted {
            self.counters.budget_acted.fetch_add(1, Relaxed);
        }
        if self.points.is_empty() {
            return Err(format!(
                "{topic}: no usable point ({} declared, {} NaN, {} out of range)",
                counts.decode.declared, counts.decode.non_finite, counts.decode.out_of_range
            ));
        }
        // An unset or impossible stamp is taken as "now" (and cannot be judged stale).
        let stamp = msg
            .header
            .stamp
            .to_nanos()
            .filter(|&s| s > 0)
            .map_or(now_ns, |s| s - self.wall_offset_ns);
        let age = (now_ns - stamp).max(0);
        self.counters
            .max_age_ns
            .fetch_max(u64::try_from(age).unwrap_or(0), Relaxed);
        if age > self.config.stale_ns {
            self.counters.stale.fetch_add(1, Relaxed);
        }
        let frame = CloudFrame::new(self.points.clone(), stamp.min(now_ns), Pose::IDENTITY)
            .map_err(|e| format!("{topic}: {e}"))?;
        self.counters.frames.fetch_add(1, Relaxed);
        Ok(frame)
    }

    fn refuse(&mut self, reason: String) {
        if self.last_refusal.as_deref() != Some(reason.as_str()) {
            tracing::warn!(%reason, "camera cloud refused (counted; logged again when the reason changes)");
            self.last_refusal = Some(reason);
        }
    }
}

//! The object's slide as the operator's own model predicts it, and the received cloud moved by
//! it (issue 13 item 6).
//!
//! A frame of a sliding object shows it where it was when the telerobot captured the frame. The
//! telerobot was then executing the operator's command of a round trip earlier (plus the frame's
//! age), and the operator's model has been sliding its own copy of the object ever since. The
//! proxy runs on the frame moved by that predicted slide, so contact with the object's sides and
//! the camera window's edge follows the object instead of lagging it by the delay:
//!
//! - every tick, the velocity of the rendered object's mass (world frame, from each tangent's
//!   renderer) is integrated into a running displacement, sampled into a ring;
//! - a frame's capture time (telerobot clock) is mapped to the operator's command time through
//!   the newest contact message (`header.sample_time_ns − command_sample_time_ns`);
//! - the move is the displacement since then, linear between samples, less its component along
//!   the contact's normal averaged over [`NORMAL_AVERAGING_S`]: the model slides the object
//!   across its contact normal only, and a tangent tilted by the noise of one episode's frame
//!   (up to 1° on the exp-1 cloud) would otherwise lift or sink the moved surface by
//!   `sin(tilt)` of the move, 2 mm for 0.12 m (measured on exp 3 at 400 ms one way, seeds 1–5:
//!   error after stable 2.50–2.83 % unmoved, 2.78–3.14 % moved without this);
//! - a view of the frame's index moved by it ([`mmt::contact::Moved`]) keeps its id while the
//!   move stays within [`REUSE_M`], so the proxy reuses its query between renewals.
//!
//! A state sync or a model start replays the renderers, not this record: the slide integrated
//! before a replay stays as it was rendered.

use mmt::contact::{CloudIndex, next_cloud_id};
use mmt::vec3::{self, Vec3};

use super::{OperatorNode, PriorStage, Tangential};

/// Sampling period of the displacement ring \[ns\]: 4 ms.
const SAMPLE_NS: i64 = 4_000_000;
/// Samples kept: 16.4 s at [`SAMPLE_NS`], a round trip at the 5 s one-way delay the system
/// accepts plus six seconds for a frame's age.
const CAPACITY: usize = 4096;
/// The longest tick integrated \[ns\]: a stall longer than this is not a slide.
const MAX_STEP_NS: i64 = 10_000_000;
/// How far the predicted move may go from the view's before the view is renewed \[m\]: 0.1 mm,
/// a fifth of the shipped camera's noise.
pub(super) const REUSE_M: f64 = 1e-4;
/// Time constant of the average of the contact normal the move is taken across \[s\]: each
/// cloud frame's noise tilts the detected normal independently, so a long average of many
/// frames (300 at 30 Hz) leaves a tilt of about a tenth of a degree.
pub(super) const NORMAL_AVERAGING_S: f64 = 10.0;
/// A detected normal this far from the average (cos of 30°) starts a new average: another face.
const NEW_FACE_COS: f64 = 0.866;

/// The predicted slide of the object and the view of the newest frame moved by it.
#[derive(Clone, Debug)]
pub(super) struct Slide {
    /// `(time [ns, operator], displacement [m])`, oldest first from `head`.
    ring: Box<[(i64, Vec3)]>,
    head: usize,
    len: usize,
    /// The displacement now [m, world].
    total_m: Vec3,
    last_ns: Option<i64>,
    /// The move of the view in use: `(cloud id, move [m], view id)`.
    view: Option<(u64, Vec3, u64)>,
    /// Decayed sum of the detected normals in contact, and its per-tick decay.
    normal_sum: Vec3,
    normal_decay: f64,
    /// Frames moved, and the largest move [m].
    pub(super) moved_views: u64,
    pub(super) largest_move_m: f64,
    /// Moves from a capture older than a full ring (the whole ring's slide was used).
    pub(super) beyond_ring: u64,
}

impl Slide {
    /// For a loop of period `period_s` \[s\].
    pub(super) fn new(period_s: f64) -> Self {
        Slide {
            normal_sum: [0.0; 3],
            normal_decay: (-period_s / NORMAL_AVERAGING_S).exp(),
            ring: vec![(i64::MIN, [0.0; 3]); CAPACITY].into_boxed_slice(),
            head: 0,
            len: 0,
            total_m: [0.0; 3],
            last_ns: None,
            view: None,
            moved_views: 0,
            largest_move_m: 0.0,
            beyond_ring: 0,
        }
    }

    /// One tick at `now_ns` with the rendered object's velocity \[m/s, world\].
    pub(super) fn advance(&mut self, now_ns: i64, velocity_m_per_s: Vec3) {
        let dt_ns = self
            .last_ns
            .map_or(0, |last| (now_ns - last).clamp(0, MAX_STEP_NS));
        if vec3::is_finite(velocity_m_per_s) {
            let dt = dt_ns as f64 * 1e-9;
            self.total_m = vec3::add(self.total_m, vec3::scale(velocity_m_per_s, dt));
        }
        self.last_ns = Some(now_ns);
        let due = self.len == 0 || now_ns >= self.newest().0 + SAMPLE_NS;
        if due {
            let slot = (self.head + self.len) % CAPACITY;
            self.ring[slot] = (now_ns, self.total_m);
            if self.len < CAPACITY {
                self.len += 1;
            } else {
                self.head = (self.head + 1) % CAPACITY;
            }
        }
    }

    /// The detector's outward normal this tick, while touching.
    pub(super) fn observe_normal(&mut self, normal: Vec3) {
        if !vec3::is_finite(normal) {
            return;
        }
        let same_face = vec3::normalize(self.normal_sum)
            .is_some_and(|avg| vec3::dot(avg, normal) >= NEW_FACE_COS);
        self.normal_sum = if same_face {
            vec3::add(vec3::scale(self.normal_sum, self.normal_decay), normal)
        } else {
            normal
        };
    }

    fn at(&self, k: usize) -> (i64, Vec3) {
        self.ring[(self.head + k) % CAPACITY]
    }

    fn newest(&self) -> (i64, Vec3) {
        self.at(self.len - 1)
    }

    /// The predicted displacement since `t_ns` [m]; whether `t_ns` was older than the ring.
    pub(super) fn since(&self, t_ns: i64) -> (Vec3, bool) {
        let Some(now_ns) = self.last_ns else {
            return ([0.0; 3], false);
        };
        if self.len == 0 || t_ns >= now_ns {
            return ([0.0; 3], false);
        }
        let oldest = self.at(0);
        if t_ns <= oldest.0 {
            // Before a full ring's oldest sample the slide is unknown; before the node's first
            // tick there was none.
            let beyond = t_ns < oldest.0 && self.len == CAPACITY;
            return (vec3::sub(self.total_m, oldest.1), beyond);
        }
        // The last sample at or before `t_ns`, then the next one (or now).
        let (mut lo, mut hi) = (0, self.len - 1);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if self.at(mid).0 <= t_ns {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let a = self.at(lo);
        let b = if lo + 1 < self.len {
            self.at(lo + 1)
        } else {
            (now_ns, self.total_m)
        };
        let w = if b.0 > a.0 {
            (t_ns - a.0) as f64 / (b.0 - a.0) as f64
        } else {
            1.0
        };
        let then = vec3::add(a.1, vec3::scale(vec3::sub(b.1, a.1), w));
        (vec3::sub(self.total_m, then), false)
    }

    /// The move of the frame `cloud_id` captured when the telerobot executed the operator's
    /// command of `command_ns`, and the id of its view: `None` when nothing slid.
    pub(super) fn view(&mut self, cloud_id: u64, command_ns: i64) -> Option<(Vec3, u64)> {
        let (mut by, beyond) = self.since(command_ns);
        if let Some(n) = vec3::normalize(self.normal_sum) {
            by = vec3::sub(by, vec3::scale(n, vec3::dot(by, n)));
        }
        if vec3::norm(by) < 1e-9 {
            self.view = None;
            return None;
        }
        if let Some((id, held, view_id)) = self.view
            && id == cloud_id
            && vec3::norm(vec3::sub(by, held)) <= REUSE_M
        {
            return Some((held, view_id));
        }
        let view_id = next_cloud_id();
        self.view = Some((cloud_id, by, view_id));
        self.moved_views += 1;
        self.beyond_ring += u64::from(beyond);
        self.largest_move_m = self.largest_move_m.max(vec3::norm(by));
        Some((by, view_id))
    }
}

impl OperatorNode {
    /// When the operator sampled the command the telerobot was executing as it captured `cloud`
    /// [ns, operator clock], from the newest contact message; `None` when the cloud does not
    /// follow the object, moving it is off, or no contact message has come yet.
    pub(super) fn frame_command_ns(&self, cloud: &CloudIndex) -> Option<i64> {
        if !(self.settings.cloud_follows_object && self.config.move_cloud_with_slide) {
            return None;
        }
        let remote = self.remote.filter(|r| r.command_sample_time_ns != 0)?;
        // Both times come from the peer: checked, so that no value of theirs can overflow.
        let lag_ns = remote
            .header
            .sample_time_ns
            .checked_sub(remote.command_sample_time_ns)?;
        cloud.timestamp_ns().checked_sub(lag_ns)
    }

    /// The velocity of the object being rendered along `tangents` [m/s, world]: the prior's
    /// while it renders alone, else the model's; 0 before either (and for a shear contact,
    /// which does not slide).
    pub(super) fn object_velocity(&self, tangents: &[[f64; 3]; 2]) -> [f64; 3] {
        let axes = match self.prior_tangential {
            PriorStage::Prior => &self.prior_axes,
            _ if self.rendering => &self.tangential,
            _ => return [0.0; 3],
        };
        let mut v = [0.0; 3];
        for (axis, t) in tangents.iter().zip(axes) {
            if let Tangential::Sliding(r) = t {
                v = vec3::add(v, vec3::scale(*axis, r.snapshot().mass_velocity_m_per_s));
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// 0.05 m/s along x for 2 s from t = 1 s, still before and after: exact displacements.
    fn slid() -> Slide {
        let mut s = Slide::new(1e-3);
        for k in 0..=4000 {
            let t = k * MS;
            let v = if (1000..3000).contains(&k) { 0.05 } else { 0.0 };
            s.advance(t, [v, 0.0, 0.0]);
        }
        s
    }

    #[test]
    fn the_displacement_since_a_time_is_the_integral_of_the_velocity() {
        let s = slid();
        let close = |a: Vec3, b: Vec3| vec3::norm(vec3::sub(a, b)) < 1e-9;
        // Tick k integrates its own velocity over the tick before it: ticks 1000–2999 slide.
        assert!(close(s.since(0).0, [0.1, 0.0, 0.0]), "{:?}", s.since(0));
        assert!(close(s.since(2000 * MS).0, [0.04995, 0.0, 0.0]));
        // Between samples (every 4 ms): linear, as the slide is there.
        assert!(close(s.since(2003 * MS).0, [0.0498, 0.0, 0.0]));
        assert!(close(s.since(3500 * MS).0, [0.0; 3]));
        assert!(
            close(s.since(5000 * MS).0, [0.0; 3]),
            "a future time has no slide"
        );
        // Before the first tick: nothing slid then, and the ring is not full.
        assert!(close(s.since(-500 * MS).0, [0.1, 0.0, 0.0]));
        assert!(!s.since(-500 * MS).1);
    }

    #[test]
    fn a_capture_older_than_the_ring_takes_the_whole_ring_and_is_counted() {
        let mut s = Slide::new(1e-3);
        // 20 s of 0.01 m/s: the ring holds the last 16.4 s.
        for k in 0..=20_000 {
            s.advance(k * MS, [0.0, 0.01, 0.0]);
        }
        let (by, beyond) = s.since(0);
        assert!(beyond);
        let held = (CAPACITY as i64 - 1) * SAMPLE_NS;
        assert!((by[1] - 0.01 * held as f64 * 1e-9).abs() < 1e-6, "{by:?}");
        let view = s.view(1, 0);
        assert!(view.is_some());
        assert_eq!(s.beyond_ring, 1);
    }

    #[test]
    fn a_view_is_kept_while_the_move_stays_within_its_tolerance() {
        let mut s = slid();
        assert_eq!(s.view(7, 3500 * MS), None, "nothing slid since");
        let (by, first) = s.view(7, 2000 * MS).unwrap();
        assert!((by[0] - 0.04995).abs() < 1e-9);
        // 1 ms earlier: 0.05 mm more, within the tolerance: the same view.
        assert_eq!(s.view(7, 1999 * MS), Some((by, first)));
        // 3 ms earlier: 0.15 mm more: renewed.
        let (_, second) = s.view(7, 1997 * MS).unwrap();
        assert_ne!(first, second);
        // Another frame: renewed.
        let (_, third) = s.view(8, 1997 * MS).unwrap();
        assert_ne!(second, third);
        assert_eq!(s.moved_views, 3);
    }

    /// The move is taken across the averaged normal: a slide along a tangent tilted by 1° does
    /// not lift the surface, and a normal from another face starts a new average.
    #[test]
    fn the_move_is_taken_across_the_averaged_normal() {
        let tilt = 1f64.to_radians();
        let mut s = Slide::new(1e-3);
        // The noisy normals of the face z = 0: ±2° about z, alternating (mean exactly z).
        for k in 0..=2000 {
            let a = if k % 2 == 0 { 2.0 } else { -2.0 } * tilt;
            s.observe_normal([a.sin(), 0.0, a.cos()]);
            // Sliding 0.05 m/s along a tangent tilted up by 1°.
            s.advance(k * MS, [0.05 * tilt.cos(), 0.0, 0.05 * tilt.sin()]);
        }
        let (by, _) = s.view(1, 0).unwrap();
        assert!(by[2].abs() < 1e-5, "{by:?}");
        assert!((by[0] - 0.1 * tilt.cos()).abs() < 1e-4, "{by:?}");
        // The side x = 0.2 (normal −x), another face: the average restarts there, and the move
        // keeps no component along it.
        s.observe_normal([-1.0, 0.0, 0.0]);
        let (by, side) = s.view(2, 0).unwrap();
        assert!(
            by[0].abs() < 1e-12 && (by[2] - 0.1 * tilt.sin()).abs() < 1e-6,
            "{by:?}"
        );
        // Garbage leaves the average as it was.
        s.observe_normal([f64::NAN, 0.0, 1.0]);
        assert_eq!(s.view(2, 0), Some((by, side)));
    }

    #[test]
    fn garbage_velocities_and_stalls_do_not_move_the_object() {
        let mut s = Slide::new(1e-3);
        s.advance(0, [0.0; 3]);
        s.advance(MS, [f64::NAN, 0.0, 0.0]);
        s.advance(2 * MS, [f64::INFINITY, 0.0, 0.0]);
        // A 10 s stall integrates at most 10 ms.
        s.advance(10_000 * MS, [0.1, 0.0, 0.0]);
        let (by, _) = s.since(0);
        assert!((by[0] - 0.001).abs() < 1e-12, "{by:?}");
        // Time going backwards integrates nothing.
        s.advance(5_000 * MS, [0.1, 0.0, 0.0]);
        assert!((s.since(0).0[0] - 0.001).abs() < 1e-12);
    }
}

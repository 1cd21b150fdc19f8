//! Contact episodes: when the tool is in contact, and in which frame.

use mmt::contact::{ContactOutput, SurfaceFrame};
use mmt::vec3;

/// Height above the fitted surface [m] the tool must rise to end an episode: hysteresis against
/// the noise of the filtered height (about ±0.02 mm on the exp-1 cloud) and of the
/// position sensor, so contact cannot flicker at the surface.
pub const RELEASE_HYSTERESIS_M: f64 = 5e-5;

/// Time constant of the complementary filter on the tool's height above the surface [s]. The
/// height follows the tool's own motion along the normal at once (exact) and the fitted surface
/// with this time constant: each cloud frame's noise moves the fitted surface by ~0.1 mm, which
/// would otherwise be a force step. 0.5 s averages 15 frames at 30 Hz; a surface moving along its
/// normal would be followed with that lag (none of the shipped scenes does).
pub const PLANE_SMOOTHING_S: f64 = 0.5;

/// Time constant of the average of the detector's normal while the tool approaches [s]; the
/// episode's frame is built from this average, not from one noisy estimate.
pub const NORMAL_AVERAGING_S: f64 = 0.03;

/// How long the proxy may report `Free` during an episode before it ends [s]. The proxy rests
/// between `(r1+r2)/2` and `r2` from the cloud and pushing straight in does not move it closer,
/// so cloud noise can put the nearest point beyond `r2` for a tick while the tool is millimetres
/// deep; the plane test, not that flicker, decides release.
pub const FREE_GRACE_S: f64 = 0.03;

/// Tracks contact episodes from the detector's output and the tool position.
#[derive(Clone, Debug)]
pub struct ContactTracker {
    alpha: f64,
    normal_alpha: f64,
    /// Running average of the detector's normal before the episode.
    normal_sum: Option<[f64; 3]>,
    grace_ticks: u32,
    free_ticks: u32,
    /// Frame frozen at the onset of the current episode.
    episode: Option<SurfaceFrame>,
    /// Filtered height of the tool above the surface [m], and the position it was computed at.
    height: Option<(f64, [f64; 3])>,
}

/// What the tracker concluded this tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tracked {
    /// In contact (pressing into the surface).
    pub in_contact: bool,
    /// An episode began this tick.
    pub onset: bool,
    /// An episode ended this tick.
    pub release: bool,
    /// The frame: the episode's, else the detector's current one.
    pub frame: Option<SurfaceFrame>,
    /// Tool position along the normal relative to the surface [m] (negative inside).
    pub normal_position_m: Option<f64>,
}

impl ContactTracker {
    /// A tracker for a loop of period `dt_s`.
    pub fn new(dt_s: f64) -> Self {
        ContactTracker {
            alpha: 1.0 - (-dt_s / PLANE_SMOOTHING_S).exp(),
            normal_alpha: 1.0 - (-dt_s / NORMAL_AVERAGING_S).exp(),
            normal_sum: None,
            grace_ticks: (FREE_GRACE_S / dt_s).ceil() as u32,
            free_ticks: 0,
            episode: None,
            height: None,
        }
    }

    /// Whether an episode is under way.
    pub fn in_episode(&self) -> bool {
        self.episode.is_some()
    }

    /// One tick: the detector's output and the tool position.
    pub fn update(&mut self, out: &ContactOutput, position_m: [f64; 3]) -> Tracked {
        self.free_ticks = if out.state.is_touching() {
            0
        } else {
            self.free_ticks.saturating_add(1)
        };
        // In an episode the proxy counts as touching until it has been free for the grace period.
        let touching = out.state.is_touching()
            || (self.episode.is_some() && self.free_ticks < self.grace_ticks);
        if self.episode.is_none() {
            self.normal_sum = match (out.normal, self.normal_sum) {
                (Some(n), Some(avg)) if touching => Some(vec3::add(
                    avg,
                    vec3::scale(vec3::sub(n, avg), self.normal_alpha),
                )),
                (Some(n), _) if touching => Some(n),
                _ => None,
            };
        }
        let averaged = self.normal_sum.and_then(SurfaceFrame::from_normal);
        let frame = self.episode.or(averaged).or(out.frame);
        let (Some(frame), Some(point)) = (frame, out.surface_point_m) else {
            return self.end(None);
        };
        if !touching && self.episode.is_none() {
            self.height = None;
            return Tracked {
                in_contact: false,
                onset: false,
                release: false,
                frame: Some(frame),
                normal_position_m: None,
            };
        }
        // Height above the local surface estimate: insensitive to the normal's wobble because the
        // surface point is next to the tool.
        let measured = vec3::dot(frame.normal, vec3::sub(position_m, point));
        let s = match self.height {
            Some((h, last)) => {
                let predicted = h + vec3::dot(frame.normal, vec3::sub(position_m, last));
                predicted + self.alpha * (measured - predicted)
            }
            None => measured,
        };
        self.height = Some((s, position_m));
        match self.episode {
            Some(_) if !touching || s > RELEASE_HYSTERESIS_M => {
                let mut t = self.end(Some(frame));
                t.normal_position_m = Some(s);
                t
            }
            Some(_) => Tracked {
                in_contact: true,
                onset: false,
                release: false,
                frame: Some(frame),
                normal_position_m: Some(s),
            },
            None if s < 0.0 => {
                self.episode = Some(frame);
                Tracked {
                    in_contact: true,
                    onset: true,
                    release: false,
                    frame: Some(frame),
                    normal_position_m: Some(s),
                }
            }
            None => Tracked {
                in_contact: false,
                onset: false,
                release: false,
                frame: Some(frame),
                normal_position_m: Some(s),
            },
        }
    }

    fn end(&mut self, frame: Option<SurfaceFrame>) -> Tracked {
        let release = self.episode.take().is_some();
        self.normal_sum = None;
        if !release {
            self.height = None;
        }
        Tracked {
            in_contact: false,
            onset: false,
            release,
            frame,
            normal_position_m: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmt::contact::ContactState;

    fn output(state: ContactState, z_surface: f64) -> ContactOutput {
        let frame = SurfaceFrame::from_normal([0.0, 0.0, 1.0]);
        ContactOutput {
            state,
            step_state: state,
            proxy_m: [0.0, 0.0, z_surface + 0.004],
            normal: frame.map(|f| f.normal),
            frame,
            penetration_m: None,
            surface_point_m: Some([0.0, 0.0, z_surface]),
            points_used: 10,
        }
    }

    #[test]
    fn contact_needs_both_the_proxy_and_the_tool_below_the_surface() {
        let mut t = ContactTracker::new(1e-3);
        // Proxy touching, tool still 2 mm above: no contact.
        assert!(
            !t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, 0.002])
                .in_contact
        );
        let on = t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, -0.001]);
        assert!(on.in_contact && on.onset);
        assert!((on.normal_position_m.unwrap() + 0.001).abs() < 1e-12);
        // Inside the hysteresis: still in contact.
        assert!(
            t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, 0.00004])
                .in_contact
        );
        let off = t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, 0.0002]);
        assert!(!off.in_contact && off.release);
        // Proxy free: no contact whatever the position.
        assert!(
            !t.update(&output(ContactState::Free, 0.0), [0.0, 0.0, -0.01])
                .in_contact
        );
    }

    #[test]
    fn the_frame_is_frozen_for_the_episode() {
        let mut t = ContactTracker::new(1e-3);
        t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, -0.001]);
        let mut tilted = output(ContactState::Contact, 0.0);
        let f = SurfaceFrame::from_normal([0.05, 0.0, 1.0]);
        tilted.frame = f;
        tilted.normal = f.map(|f| f.normal);
        let r = t.update(&tilted, [0.0, 0.0, -0.001]);
        assert_eq!(r.frame.unwrap().normal, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn a_jumping_surface_estimate_is_smoothed_and_motion_is_followed_at_once() {
        let mut t = ContactTracker::new(1e-3);
        t.update(&output(ContactState::Contact, 0.0), [0.0, 0.0, -0.001]);
        // The next cloud frame fits the surface 0.1 mm higher.
        let r = t.update(&output(ContactState::Contact, 0.0001), [0.0, 0.0, -0.001]);
        let moved = -0.001 - r.normal_position_m.unwrap();
        assert!(moved > 0.0 && moved < 0.0001 * 0.01, "{moved}");
        // The tool moves 1 mm deeper: the height follows exactly.
        let r2 = t.update(&output(ContactState::Contact, 0.0001), [0.0, 0.0, -0.002]);
        let step = r.normal_position_m.unwrap() - r2.normal_position_m.unwrap();
        assert!((step - 0.001).abs() < 2e-6, "{step}");
    }
}

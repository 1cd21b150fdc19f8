//! Point-cloud contact detection: the three-sphere proxy of thesis appendix C on a kd-tree
//! (`DESIGN.md` §5; thesis D.3 and H.2.1).
//!
//! A [`Proxy`] follows the haptic interaction point (HIP) without passing through the surface
//! sampled by a point cloud. Each [`Proxy::step`] takes the HIP and the newest cloud's index and
//! returns a [`ContactOutput`]: free / contact / entrenched, the proxy position, the surface
//! normal and frame, the penetration along the normal and a point on the local surface — what
//! the telerobot needs to identify in the surface frame and what the operator needs to switch
//! contact at once on its delayed copy of the cloud.
//!
//! - [`ProxyConfig`]: the radii `r1 < r2 < r3`, `γ`, `ζ`, the rate (how to choose them).
//! - [`distance`]: eq. 24–29, the analytic shortest-distance roots (eq. 29 corrected).
//! - [`CloudIndex`] / [`BruteForce`]: radius queries behind one [`Neighbours`] trait, so the
//!   benchmark's brute-force proxy is the same code on a different backend.
//! - [`Moved`]: a cloud seen moved by a translation (the operator's cloud of a sliding object,
//!   moved by its locally predicted slide), with no new index.
//! - [`bridge`]: where the points are a plane with holes in it, the fitted plane is the surface
//!   (a depth camera's dropout, hole patches and noise do not let the proxy through).
//! - [`budget`]: whether a cloud can run at the loop rate (points in the query ball, frame
//!   size against the camera rate), estimated before it reaches a loop.
//! - [`SurfaceFrame`]: normal and two tangents, right-handed, chosen deterministically.
//!
//! Units: metres, seconds; every position is in the world frame of the cloud.

pub mod bridge;
pub mod budget;
mod config;
mod density;
pub mod distance;
mod moved;
mod neighbours;
mod proxy;
mod surface;

pub use config::{ProxyConfig, ProxyError};
pub use moved::Moved;
pub use neighbours::{BruteForce, CloudIndex, IndexError, Neighbour, Neighbours, next_cloud_id};
pub use proxy::Proxy;
pub use surface::{NormalEstimator, SurfaceFrame, wendland};

use serde::{Deserialize, Serialize};

/// The proxy's state (thesis appendix C).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ContactState {
    /// No point within `r2`: the proxy follows the HIP (eq. 16–17).
    Free,
    /// A point within `r2`, none within `r1`: the proxy slides on the surface (eq. 20–22).
    Contact,
    /// A point within `r1`: the proxy is pushed out along the normal (eq. 18–19).
    Entrenched,
}

impl ContactState {
    /// Touching the surface (contact or entrenched): what the estimator and renderer switch on
    /// (thesis D.3: "any point within r2").
    pub fn is_touching(self) -> bool {
        !matches!(self, ContactState::Free)
    }
}

/// What one proxy step reports. Quantities that are undefined are `None`, never NaN.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContactOutput {
    /// State at the proxy's new position (thesis D.3: contact iff a point is within `r2`).
    pub state: ContactState,
    /// State that chose this step's motion (at the position before the step).
    pub step_state: ContactState,
    /// Proxy position after the step [m].
    pub proxy_m: [f64; 3],
    /// Unit surface normal at the new position, out of the surface toward the free side
    /// (eq. 14); `None` without points within `r3` or when their directions cancel.
    pub normal: Option<[f64; 3]>,
    /// Normal and tangents (see [`SurfaceFrame`]); `Some` exactly when `normal` is.
    pub frame: Option<SurfaceFrame>,
    /// `(proxy − HIP)·normal` [m]: positive when the HIP is pushed into the surface.
    /// `None` without a normal or with a non-finite HIP.
    pub penetration_m: Option<f64>,
    /// A point on the locally fitted surface [m]: the Wendland-weighted centroid of the points
    /// within `r3`. The normal-axis position of the tool is `(x − surface_point)·normal`
    /// (the rest position of the normal axis is 0).
    pub surface_point_m: Option<[f64; 3]>,
    /// Points within `r3` of the new position (the support of `normal` and `surface_point_m`).
    pub points_used: usize,
}

impl ContactOutput {
    /// Free space with the proxy at `proxy_m`: no surface within reach, nothing defined.
    pub fn free(proxy_m: [f64; 3]) -> ContactOutput {
        ContactOutput {
            state: ContactState::Free,
            step_state: ContactState::Free,
            proxy_m,
            normal: None,
            frame: None,
            penetration_m: None,
            surface_point_m: None,
            points_used: 0,
        }
    }
}

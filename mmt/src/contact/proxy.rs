//! The proxy's movement protocol (thesis appendix C, eq. 12–22), one step per haptic tick.
//!
//! Per [`Proxy::step`]:
//! 1. **Moving cloud** (eq. 12–13): the proxy first moves along the last normal by `v̂/f_c`,
//!    where `v̂` is the proxy's speed along the normal in the last step. A cloud pushing the
//!    proxy (entrenched steps) raises `v̂`, so the proxy keeps ahead of an approaching surface.
//! 2. **Normal and state** (eq. 14–15): from the points within `r3` of the proxy.
//! 3. **Step** by state: free (eq. 16–17, swept toward the HIP, stopping `(r1+r2)/2` from the
//!    first point in the way), entrenched (eq. 18–19, out along the normal until every point
//!    is `(r1+r2)/2` away), contact (eq. 20–22, a bounded slide).
//! 4. **Output** (thesis D.3): state, normal, frame and surface point at the new position, so
//!    contact is reported in the tick the proxy reaches the surface.
//!
//! # Where this departs from the text, and why
//!
//! - **Locality of eq. 16.** The minimum "over all points in the cloud" only involves points
//!   within `(r1+r2)/2` of the swept segment; they all lie in the ball around the segment's
//!   midpoint of radius `‖u‖/2 + (r1+r2)/2`. The query takes `‖u‖/2 + r3`, which also covers
//!   the `r3` ball wherever the proxy stops.
//! - **Long sweeps.** A sweep is cut into segments of at most `r3`, one query each, so no query
//!   is larger than `1.5 r3` plus the reuse margin whatever the HIP does; after
//!   [`MAX_SWEEP_SEGMENTS`] segments (`4 r3`, 48 mm at the defaults: 48 m/s at 1 kHz) the proxy
//!   stops, clear of every point as after any sweep, and continues on the next tick. Each
//!   segment is swept exactly, so this changes no outcome but the tick a long jump lands in.
//! - **Sign in eq. 22.** Eq. 14 makes the normal point out of the surface, so the operator
//!   pushes in when `n̂ᵀu < 0` (the text's `> 0` assumes the opposite normal); pushing in
//!   slides along the tangent plane, pulling out moves along `u`.
//! - **Eq. 22 step length.** When sliding, `d` is capped at `‖u_p‖` so the proxy does not
//!   overshoot the HIP's projection and chatter around it.
//! - **Eq. 12–13 velocity term.** Read as `v̂_k = v̂_{k−1} + n̂ᵀs_k f_c` with `s_k` the state
//!   step that follows the velocity step, `v̂` is the proxy's speed along the normal over the
//!   last tick; that is how it is computed (from the velocity step actually taken). It is kept
//!   `≥ 0` and the velocity step is swept like a free step: taken literally (signed, unchecked)
//!   the term moves the proxy toward the surface by the last approach step without looking,
//!   which punches through at 1 m/s (the tests fail that way), and an outward step could jump
//!   into another surface on the free side. `v̂` is 0 when there is no normal (nothing within
//!   `r3`).
//! - **Entrenched step (eq. 18).** "All points" is the points within `r1` (those the step must
//!   clear); without a normal at that instant the last normal is used.
//! - **Holes and noise (issue 14).** Where the plane fitted over the points within `r3` (or
//!   `2 r3`) bridges them ([`super::bridge`]), the distances of eq. 15–19 are to that plane,
//!   not to the nearest point: contact is the plane within `r2`, a free step stops
//!   `(r1+r2)/2` from it, an entrenched step clears it to `(r1+r2)/2`, and pushing in also
//!   settles the proxy down to `(r1+r2)/2` (eq. 22 alone leaves it wherever it first came
//!   within `r2`, and the plane's frame-to-frame wobble would then take it beyond now and
//!   then). Near points a free step moves at most the fit's support less `(r1+r2)/2` per tick,
//!   so the plane it was checked against holds along all of it. [`ProxyConfig::bridge_holes`]
//!   `= false` is the thesis's proxy.
//!
//! # Allocation
//!
//! The neighbour buffer lives in the proxy and is reused. [`Proxy::prepare`], called when a new
//! cloud is set, reserves it for the most points any query of the proxy can return on that
//! cloud ([`Neighbours::max_within`], from the cloud's density); steps on it then never
//! allocate (tested in `tests/contact_alloc.rs` on a 0.5 mm grid, 5 cm jumps and a small box).
//! Without `prepare` the buffer grows to the largest neighbourhood seen.
//! When the cloud ([`Neighbours::cloud_id`]) and the proxy position are unchanged since the end
//! of the last step, the step starts from that step's final query and surface instead of
//! repeating them: a sliding or free proxy costs one radius query per step, a resting one none.

use super::bridge;
use super::distance::{clearing_distance, first_touch};
use super::neighbours::{Neighbour, Neighbours};
use super::surface::{LocalSurface, SurfaceFrame, local_surface};
use super::{ContactOutput, ContactState, ProxyConfig, ProxyError};
use crate::vec3::{self, Vec3};

/// Velocity steps shorter than this [m] are rounding noise (a slide along the tangent plane has
/// `n̂·s` of order 1e-19 m) and are not taken: they would only defeat the query reuse.
const NEGLIGIBLE_MOVE_M: f64 = 1e-9;

/// Initial capacity of the neighbour buffer, before [`Proxy::prepare`]: the default 12 mm ball
/// holds ~450 points of a 1 mm grid; a sweep's ball a few hundred more.
const INITIAL_NEIGHBOURS: usize = 1024;

/// Longest stretch of a sweep answered by one query, as a fraction of `r3`: the query is then
/// at most `1.5 r3` (plus the margin) in radius, about twice the points of the `r3` ball on a
/// surface.
const SWEEP_SEGMENT_OF_R3: f64 = 1.0;

/// Most segments one sweep covers in a tick; a longer move continues on the next tick. Bounds
/// the queries per step (two sweeps: the velocity step and the free step).
const MAX_SWEEP_SEGMENTS: usize = 4;

/// Where the points within `r3` lack points around the proxy, the plane is fitted again over
/// this many `r3` ([`super::bridge`]): by the gap rule, round holes up to about `1.9 r3` in
/// radius are then bridged from anywhere over them (58 mm at the exp-1 radii; a 9 cm hole is
/// tested), where `r3` alone bridges up to about `0.95 r3`.
const WIDE_OF_R3: f64 = 2.0;

/// A query asks for this fraction of `r3` beyond the ball it needs, so that the next ticks,
/// while the proxy moves less than that, reuse its answer instead of querying again (every pass
/// filters by its own radius, so extra points change nothing but the summation order). At the
/// default radii on a 1 mm grid: step median 9.6 → 7.3 µs, p99 20 → 17 µs (`mmt contact-bench`).
const QUERY_MARGIN_OF_R3: f64 = 1.0 / 24.0;

/// The three-sphere proxy (thesis appendix C). See the module docs for the protocol.
#[derive(Clone, Debug)]
pub struct Proxy {
    config: ProxyConfig,
    position: Vec3,
    /// `v̂` of eq. 12 [m/s]: the proxy's speed along `last_normal` in the last step, ≥ 0.
    normal_speed: f64,
    /// `n̂_{k−1}`: the normal that governed the last step.
    last_normal: Option<Vec3>,
    /// Whether the proxy was touching the surface at the end of the last step.
    touching: bool,
    scratch: Scratch,
}

impl Proxy {
    /// A proxy at the HIP's position [m]. Start it in free space (it cannot tell which side
    /// of a surface it is on).
    pub fn new(config: ProxyConfig, initial_hip: [f64; 3]) -> Result<Self, ProxyError> {
        config.validate()?;
        let mut proxy = Self {
            config,
            position: [0.0; 3],
            normal_speed: 0.0,
            last_normal: None,
            touching: false,
            scratch: Scratch::default(),
        };
        proxy.reset(initial_hip)?;
        Ok(proxy)
    }

    /// Moves the proxy to `hip` [m] and forgets its motion (the velocity term and last normal).
    pub fn reset(&mut self, hip: [f64; 3]) -> Result<(), ProxyError> {
        if !vec3::is_finite(hip) {
            return Err(ProxyError::NonFinitePosition { value: hip });
        }
        self.position = hip;
        self.normal_speed = 0.0;
        self.last_normal = None;
        self.touching = false;
        Ok(())
    }

    /// Reserves the neighbour buffer for the largest answer any query of this proxy can get
    /// from `cloud` (its [`Neighbours::max_within`] at the largest query radius), so that no
    /// step on `cloud` allocates. Call it when a new cloud is set, off the per-step path: it may
    /// allocate. Capacity only grows.
    pub fn prepare<N: Neighbours>(&mut self, cloud: &N) {
        let need = cloud.max_within(max_query_radius_m(&self.config));
        let buf = &mut self.scratch.buf;
        buf.reserve(need.saturating_sub(buf.len()));
    }

    /// The parameters.
    pub fn config(&self) -> &ProxyConfig {
        &self.config
    }

    /// Current proxy position [m].
    pub fn position(&self) -> [f64; 3] {
        self.position
    }

    /// `v̂` of eq. 12 [m/s]: the speed along the normal the next step starts with.
    pub fn normal_speed_m_per_s(&self) -> f64 {
        self.normal_speed
    }

    /// One tick: moves the proxy toward `hip` [m] without crossing the cloud behind `cloud`,
    /// and reports the contact at its new position. `cloud` may be a different frame's index on
    /// every call. A non-finite `hip` holds the proxy where it is (and gives no penetration).
    pub fn step<N: Neighbours>(&mut self, hip: [f64; 3], cloud: &N) -> ContactOutput {
        let c = self.config;

        // 1. Eq. 12–13: keep up with a moving cloud (swept, outward only).
        let mut pre_move = 0.0;
        let predicted = self.normal_speed / c.rate_hz;
        if let Some(n) = self.last_normal
            && predicted > NEGLIGIBLE_MOVE_M
        {
            pre_move = self.sweep(cloud, n, predicted);
            self.position = vec3::add(self.position, vec3::scale(n, pre_move));
        }

        // 2. Eq. 14–15 and the state at the proxy.
        let here = self.scratch.surface_at(cloud, self.position, &c, false);
        let here = keep_side(here, self.last_normal, self.touching);
        let step_state = classify(&here, &c);
        let normal = match step_state {
            ContactState::Free => here.normal,
            _ => here.normal.or(self.last_normal),
        };

        // 3. The step of the state (eq. 16–22).
        let hip_ok = vec3::is_finite(hip);
        let u = if hip_ok {
            vec3::sub(hip, self.position)
        } else {
            [0.0; 3]
        };
        let step = match (step_state, normal) {
            (ContactState::Free, _) => self.free_step(cloud, u, &here),
            (ContactState::Entrenched, Some(n)) => self.entrenched_step(n, &here),
            (ContactState::Entrenched, None) => [0.0; 3],
            (ContactState::Contact, n) => {
                let slide = contact_step(u, n, &c);
                match (n, here.plane) {
                    (Some(n), Some(plane)) => {
                        vec3::add(slide, plane.settle(u, n, c.rest_distance_m()))
                    }
                    _ => slide,
                }
            }
        };
        self.position = vec3::add(self.position, step);

        // Eq. 12: v̂ ← v̂ + n̂ᵀs f_c, with the velocity step as taken: the proxy's speed along
        // the normal over this tick.
        self.normal_speed = match normal {
            Some(n) => ((pre_move + vec3::dot(n, step)) * c.rate_hz).max(0.0),
            None => 0.0,
        };
        self.last_normal = normal;

        // 4. Thesis D.3: what the surface looks like where the proxy now is.
        let there = self.scratch.surface_at(cloud, self.position, &c, true);
        let there = keep_side(there, normal, step_state.is_touching());
        let state = classify(&there, &c);
        self.touching = state.is_touching();
        let frame = there.normal.and_then(SurfaceFrame::from_normal);
        let normal = frame.map(|f| f.normal);
        ContactOutput {
            state,
            step_state,
            proxy_m: self.position,
            normal,
            frame,
            penetration_m: normal
                .filter(|_| hip_ok)
                .map(|n| vec3::dot(vec3::sub(self.position, hip), n)),
            surface_point_m: there.centroid,
            points_used: there.count,
        }
    }

    /// Eq. 16–17: toward the HIP until `(r1+r2)/2` from the first point in the way — or, where
    /// the fitted plane bridges the points around the proxy (`here`), from that plane and from
    /// the points standing out of it.
    ///
    /// Bridging, one tick moves at most the plane's support (`r3` or `2 r3`) less `(r1+r2)/2`:
    /// every point the moving sphere can meet is then among those `here` was computed from, so
    /// the plane and its obstacles hold along the whole move and a hole cannot be crossed within
    /// one step (25 or 55 mm per millisecond at the exp-1 radii: faster than any hand).
    fn free_step<N: Neighbours>(&mut self, cloud: &N, u: Vec3, here: &LocalSurface) -> Vec3 {
        let len = vec3::norm(u);
        if len <= 0.0 {
            return [0.0; 3];
        }
        let dir = vec3::scale(u, 1.0 / len);
        let rest = self.config.rest_distance_m();
        let d = match (here.plane, here.normal) {
            (Some(plane), Some(n)) => {
                let reach = len.min((here.support_m - rest).max(0.0));
                let from = self.position;
                let points = self.scratch.buf.iter().map(|nb| vec3::sub(nb.point, from));
                plane.free_reach(n, dir, reach, rest, points)
            }
            _ => self.sweep(cloud, dir, len),
        };
        if d >= len {
            // Unobstructed: land exactly on the HIP (no rounding of dir·len).
            u
        } else {
            vec3::scale(dir, d)
        }
    }

    /// How far the proxy can move along the unit `dir`, at most `len` [m] and at most
    /// [`MAX_SWEEP_SEGMENTS`] segments of `r3`, before a point comes within `(r1+r2)/2` (eq. 16,
    /// solved by eq. 28 per point).
    ///
    /// The points that can stop it in a segment lie within `(r1+r2)/2` of the segment, so
    /// within `seg/2 + (r1+r2)/2` of its midpoint. The query asks for `seg/2 + r3` instead,
    /// which also holds the `r3` ball around wherever the proxy stops in that segment: the
    /// surface there is then computed without a second query. A point that stops the proxy in an
    /// earlier segment is found by that segment's query, so the first segment with a touch ends
    /// the sweep.
    fn sweep<N: Neighbours>(&mut self, cloud: &N, dir: Vec3, len: f64) -> f64 {
        let c = self.config;
        let a = c.rest_distance_m();
        let from = self.position;
        let seg = SWEEP_SEGMENT_OF_R3 * c.r3_m;
        let reach = len.min(seg * MAX_SWEEP_SEGMENTS as f64);
        let segments = ((reach / seg).ceil() as usize).clamp(1, MAX_SWEEP_SEGMENTS);
        let mut touch = f64::INFINITY;
        for k in 0..segments {
            let start = k as f64 * seg;
            let end = if k + 1 == segments {
                reach
            } else {
                (k + 1) as f64 * seg
            };
            let mid = vec3::add(from, vec3::scale(dir, 0.5 * (start + end)));
            self.scratch.ensure(
                cloud,
                mid,
                0.5 * (end - start) + c.r3_m.max(a),
                QUERY_MARGIN_OF_R3 * c.r3_m,
            );
            touch = self
                .scratch
                .buf
                .iter()
                .filter_map(|nb| first_touch(a, vec3::sub(nb.point, from), dir))
                .fold(touch, f64::min);
            if touch <= end {
                break;
            }
        }
        touch.min(reach)
    }

    /// Eq. 18–19: out along `n` until every point within `r1` is `(r1+r2)/2` away — or, where
    /// the fitted plane bridges the points (`here`), until that plane and the points standing
    /// out of it within `r1` are.
    fn entrenched_step(&self, n: Vec3, here: &LocalSurface) -> Vec3 {
        let c = &self.config;
        if let Some(plane) = here.plane {
            let from = self.position;
            let points = self.scratch.buf.iter().map(|nb| vec3::sub(nb.point, from));
            return vec3::scale(n, plane.clearance(n, c.rest_distance_m(), c.r1_m, points));
        }
        let (a, r1_sq) = (c.rest_distance_m(), c.r1_m * c.r1_m);
        let d = self
            .scratch
            .buf
            .iter()
            .map(|nb| vec3::sub(nb.point, self.position))
            .filter(|b| vec3::norm2(*b) < r1_sq)
            .filter_map(|b| clearing_distance(a, b, n))
            .fold(0.0, f64::max);
        vec3::scale(n, d)
    }
}

/// Eq. 20–22: `d = γ‖u‖` within `r1` of the HIP, else `ζ r1`; slide along the tangent plane
/// when pushing in (`n̂ᵀu < 0`), else move along `u`.
fn contact_step(u: Vec3, normal: Option<Vec3>, c: &ProxyConfig) -> Vec3 {
    let len = vec3::norm(u);
    if len <= 0.0 {
        return [0.0; 3];
    }
    let d = if len < c.r1_m {
        c.gamma * len
    } else {
        c.zeta * c.r1_m
    };
    match normal {
        Some(n) if vec3::dot(n, u) < 0.0 => {
            let along = vec3::sub(u, vec3::scale(n, vec3::dot(n, u)));
            let along_len = vec3::norm(along);
            if along_len > 0.0 {
                vec3::scale(along, d.min(along_len) / along_len)
            } else {
                [0.0; 3]
            }
        }
        _ => vec3::scale(u, d / len),
    }
}

/// The largest ball the proxy queries [m]: a sweep segment's (`seg/2 + r3`), the surface's
/// (`r3`) or, bridging holes, the wide plane's (`2 r3`), plus the reuse margin.
pub(super) fn max_query_radius_m(c: &ProxyConfig) -> f64 {
    let seg = SWEEP_SEGMENT_OF_R3 * c.r3_m;
    let sweep = 0.5 * seg + c.r3_m.max(c.rest_distance_m());
    let wide = if c.bridges() {
        WIDE_OF_R3 * c.r3_m
    } else {
        0.0
    };
    sweep.max(wide) + QUERY_MARGIN_OF_R3 * c.r3_m
}

/// Eq. 15's states from the distance to the surface: the bridging plane's (or a point standing
/// out of it) where there is one ([`super::bridge`]), else the nearest point's.
fn classify(s: &LocalSurface, c: &ProxyConfig) -> ContactState {
    let d2 = match s.plane {
        Some(plane) => plane.distance2(),
        None => s.nearest_d2,
    };
    if d2 < c.r1_m * c.r1_m {
        ContactState::Entrenched
    } else if d2 <= c.r2_m * c.r2_m {
        ContactState::Contact
    } else {
        ContactState::Free
    }
}

/// A bridging plane has no side of its own: its normal is oriented toward wherever the proxy
/// is. A proxy touching it from one side that finds the fitted normal turned against the last
/// one (`last`) has been carried past the plane — a frame that jumped toward it, a step it could
/// not see — and keeps its side: the normal turned back, the height negative, so that it reads
/// as entrenched and is pushed out to the side it came from instead of reading the surface
/// inverted.
fn keep_side(mut s: LocalSurface, last: Option<Vec3>, touching: bool) -> LocalSurface {
    if let (true, Some(last), Some(n), Some(plane)) = (touching, last, s.normal, s.plane.as_mut())
        && vec3::dot(n, last) < 0.0
    {
        s.normal = Some(vec3::scale(n, -1.0));
        plane.height_m = -plane.height_m;
    }
    s
}

/// The reused neighbour buffer and what it holds: every point within `radius` of `centre` of
/// the cloud `cloud` (0: nothing; ids start at 1), plus the surface last computed from it.
#[derive(Clone, Debug)]
struct Scratch {
    buf: Vec<Neighbour>,
    cloud: u64,
    centre: Vec3,
    radius: f64,
    /// `(at, surface)`: [`local_surface`] at `at` over `buf`, valid until `buf` is refilled.
    surface: Option<(Vec3, bool, LocalSurface)>,
}

impl Default for Scratch {
    fn default() -> Self {
        Self {
            buf: Vec::with_capacity(INITIAL_NEIGHBOURS),
            cloud: 0,
            centre: [0.0; 3],
            radius: -1.0,
            surface: None,
        }
    }
}

impl Scratch {
    /// Makes the buffer hold at least every point of `cloud` within `radius` of `centre`,
    /// querying only when the ball it holds does not contain that one.
    ///
    /// Kept out of line: inlined into the step, the query's code cost the surface passes
    /// about 2 µs per step (measured; register pressure in the hot loops).
    #[inline(never)]
    fn ensure<N: Neighbours>(&mut self, cloud: &N, centre: Vec3, radius: f64, margin: f64) {
        let held = self.cloud == cloud.cloud_id()
            && vec3::norm(vec3::sub(centre, self.centre)) + radius <= self.radius;
        if held {
            return;
        }
        self.buf.clear();
        let buf = &mut self.buf;
        let radius = radius + margin;
        cloud.for_each_within(centre, radius, |nb| buf.push(nb));
        self.cloud = cloud.cloud_id();
        self.centre = centre;
        self.radius = radius;
        self.surface = None;
    }

    /// Eq. 14–15 at `at` (reusing the last result when neither the cloud nor `at` changed);
    /// afterwards the buffer holds every point within `r3` of `at`. The surface point costs a
    /// pass of its own: asked for only where it is reported.
    ///
    /// Where the points within `r3` are planar but do not surround the foot (an edge, or a hole
    /// too wide for `r3`), the plane is fitted once more over [`WIDE_OF_R3`]` · r3`: a hole of
    /// several centimetres is surrounded at that scale, an edge is not ([`super::bridge`]).
    /// Points that are not planar within `r3` are not fitted wider.
    fn surface_at<N: Neighbours>(
        &mut self,
        cloud: &N,
        at: Vec3,
        c: &ProxyConfig,
        with_point: bool,
    ) -> LocalSurface {
        self.ensure(cloud, at, c.r3_m, QUERY_MARGIN_OF_R3 * c.r3_m);
        if let Some((cached_at, cached_point, surface)) = self.surface
            && cached_at == at
            && (cached_point || !with_point)
        {
            return surface;
        }
        let mut surface = self.surface_over(at, c, c.r3_m, with_point);
        // Wider only where r3 lacked points around the proxy, not where its points are not a
        // plane (something on the surface, which a wider fit would only dilute).
        let planar = surface
            .residual_m
            .is_none_or(|r| r <= bridge::MAX_RESIDUAL_OF_BAND * (c.r2_m - c.r1_m));
        if c.bridges() && surface.plane.is_none() && planar {
            let wide = WIDE_OF_R3 * c.r3_m;
            self.ensure(cloud, at, wide, QUERY_MARGIN_OF_R3 * c.r3_m);
            let bridged = self.surface_over(at, c, wide, with_point);
            if bridged.plane.is_some() {
                surface = bridged;
            }
        }
        self.surface = Some((at, with_point, surface));
        surface
    }

    /// Eq. 14–15 at `at` over the buffer's points within `support_m` (which it must hold).
    fn surface_over(
        &self,
        at: Vec3,
        c: &ProxyConfig,
        support_m: f64,
        with_point: bool,
    ) -> LocalSurface {
        let band = c.bridges().then_some(c.r2_m - c.r1_m);
        local_surface(
            at,
            &self.buf,
            (c.r1_m, support_m, band),
            c.normal_estimator,
            with_point,
        )
    }
}

//! Clutch and position scaling, translation only: the map from the device's measured position to
//! the commanded position sent to the telerobot.
//!
//! `commanded = offset + scale · measured`. The invariant is **no teleport**: the commanded
//! position is continuous in the measured position whatever the clutch and scale do.
//! - While the clutch is engaged the device moves but the commanded position holds.
//! - On release the offset is recomputed so the commanded position continues from the held one
//!   (`offset = held − scale · measured`).
//! - A scale change recomputes the offset the same way, so it takes effect without a jump.
//!
//! Orientation is not mapped (the layer is translation only).

use mmt::vec3::{self, Vec3};

/// A validated position scale: finite and > 0 (commanded metres per device metre).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionScale(f64);

/// A scale that is zero, negative, NaN, infinite or above [`PositionScale::MAX`].
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("invalid position scale {0}: expected a finite number > 0 and at most 20 (1 = one-to-one)")]
pub struct InvalidScale(pub f64);

impl PositionScale {
    /// One-to-one.
    pub const ONE: Self = Self(1.0);

    /// The largest scale: a desk device's 10 cm workspace over a large arm's 2 m reach. Beyond
    /// it a hand's tremor commands centimetres (and the telerobot's workspace box clamps the
    /// rest: `node::guard`).
    pub const MAX: f64 = 20.0;

    /// Checks `factor`: finite, > 0 and at most [`Self::MAX`].
    pub fn new(factor: f64) -> Result<Self, InvalidScale> {
        if factor.is_finite() && factor > 0.0 && factor <= Self::MAX {
            Ok(Self(factor))
        } else {
            Err(InvalidScale(factor))
        }
    }

    /// The factor.
    #[must_use]
    pub fn get(self) -> f64 {
        self.0
    }
}

/// Clutch and scale state. See the module docs.
#[derive(Clone, Copy, Debug)]
pub struct PositionMap {
    scale: PositionScale,
    offset: Vec3,
    /// The held commanded position while clutched.
    held: Option<Vec3>,
    last_measured: Option<Vec3>,
    last_commanded: Vec3,
}

impl PositionMap {
    /// Starts unclutched with `commanded = scale · measured`.
    #[must_use]
    pub fn new(scale: PositionScale) -> Self {
        Self {
            scale,
            offset: vec3::ZERO,
            held: None,
            last_measured: None,
            last_commanded: vec3::ZERO,
        }
    }

    /// The map placing the device's origin at `origin_m` [m] in the world (before any clutching).
    #[must_use]
    pub fn with_origin(mut self, origin_m: Vec3) -> Self {
        self.offset = origin_m;
        self
    }

    /// One tick: the commanded position for a (finite) measured position and clutch state.
    pub fn update(&mut self, measured: Vec3, clutch: bool) -> Vec3 {
        if self.last_measured.is_none() {
            // First tick: the "previous" commanded position is the unclutched map of this one.
            self.last_commanded = vec3::add(self.offset, vec3::scale(measured, self.scale.get()));
        }
        let mut released = None;
        match (self.held, clutch) {
            (None, true) => self.held = Some(self.last_commanded),
            (Some(held), false) => {
                self.offset = vec3::sub(held, vec3::scale(measured, self.scale.get()));
                self.held = None;
                released = Some(held);
            }
            _ => {}
        }
        self.last_measured = Some(measured);
        // On the release tick the held position itself (exact, not offset + scale·measured,
        // which can differ in the last bit).
        self.last_commanded = match (self.held, released) {
            (Some(held), _) | (None, Some(held)) => held,
            (None, None) => vec3::add(self.offset, vec3::scale(measured, self.scale.get())),
        };
        self.last_commanded
    }

    /// Holds the last commanded position (used when the measured position is not finite).
    #[must_use]
    pub fn hold(&self) -> Vec3 {
        self.last_commanded
    }

    /// Changes the scale without moving the commanded position.
    pub fn set_scale(&mut self, scale: PositionScale) {
        if let Some(m) = self.last_measured
            && self.held.is_none()
        {
            self.offset = vec3::sub(self.last_commanded, vec3::scale(m, scale.get()));
        }
        self.scale = scale;
    }

    /// The current scale.
    #[must_use]
    pub fn scale(&self) -> PositionScale {
        self.scale
    }

    /// Whether the clutch is engaged.
    #[must_use]
    pub fn clutched(&self) -> bool {
        self.held.is_some()
    }
}

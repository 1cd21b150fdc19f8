//! Field-by-field validation of a parsed scene.

use super::{CloudKind, Scene, StructureName};
use thiserror::Error;

/// Why a scene was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    /// Not TOML, or a field of the wrong type, or an unknown field.
    #[error("{origin}: {message}")]
    Parse {
        /// File (or other source).
        origin: String,
        /// The parser's message (names the line and the key).
        message: String,
    },
    /// A field out of range.
    #[error("{origin}: {field} = {value} is out of range: expected {expected}")]
    Field {
        /// File (or other source).
        origin: String,
        /// Dotted field name.
        field: &'static str,
        /// The value, as written.
        value: String,
        /// The allowed range.
        expected: &'static str,
    },
    /// The simulated camera's cloud cannot run at the loop rate at any spacing the proxy
    /// cannot slip through (`mmt::contact::budget`).
    #[error("{origin}: [cloud] {detail}")]
    CloudBudget {
        /// File (or other source).
        origin: String,
        /// What is over, and what would fit.
        detail: String,
    },
}

/// Points the simulated plane keeps within `r3` of the proxy after dropout and holes (the error
/// messages here and in `budget.rs` say 48 in words).
const PLANE_POINTS_IN_R3: f64 = 48.0;
impl SceneError {
    pub(super) fn with_origin(self, origin: &str) -> SceneError {
        match self {
            SceneError::Field {
                field,
                value,
                expected,
                ..
            } => SceneError::Field {
                origin: origin.to_string(),
                field,
                value,
                expected,
            },
            SceneError::CloudBudget { detail, .. } => SceneError::CloudBudget {
                origin: origin.to_string(),
                detail,
            },
            other => other,
        }
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

fn non_negative(name: &'static str, v: f64) -> Result<(), SceneError> {
    field(name, v, v.is_finite() && v >= 0.0, "a finite number ≥ 0")
}

/// The lightest object a scene may slide [kg].
const MIN_SLIDING_MASS_KG: f64 = 1e-3;

fn positive(name: &'static str, v: f64) -> Result<(), SceneError> {
    field(name, v, v.is_finite() && v > 0.0, "a finite number > 0")
}

impl Scene {
    /// The motion limits: each within `node::MotionLimits`'s ceilings, the box containing the
    /// surface point (where the tool starts).
    fn validate_limits(&self) -> Result<(), SceneError> {
        use node::guard::LimitsError;
        let l = self.motion_limits();
        let name = |e: &LimitsError| match e {
            LimitsError::Workspace { .. } => "limits.workspace_min_m/workspace_max_m",
            LimitsError::Step(_) => "limits.max_step_m",
            LimitsError::Speed(_) => "limits.max_speed_m_per_s",
            LimitsError::ClockJump(_) => "limits.max_clock_jump_s",
        };
        let expected = |e: &LimitsError| match e {
            LimitsError::Workspace { .. } => {
                "finite corners, min < max on each axis, at most 4 m wide"
            }
            LimitsError::Step(_) => "> 0 and at most 0.01 m per tick",
            LimitsError::Speed(_) => "> 0 and at most 2 m/s",
            LimitsError::ClockJump(_) => "0.1 to 60 s",
        };
        if let Err(e) = l.validate() {
            return Err(SceneError::Field {
                origin: String::new(),
                field: name(&e),
                value: match e {
                    LimitsError::Workspace { lo, hi, axis } => {
                        format!("axis {axis}: [{lo}, {hi}]")
                    }
                    LimitsError::Step(v) | LimitsError::Speed(v) => format!("{v}"),
                    LimitsError::ClockJump(ns) => format!("{}", ns as f64 * 1e-9),
                },
                expected: expected(&e),
            });
        }
        field(
            "limits.workspace_min_m/workspace_max_m",
            (l.workspace_min_m, l.workspace_max_m),
            l.contains(self.surface.point_m),
            "a box containing surface.point_m",
        )
    }

    /// Every field against its range, section by section in the file's order: the first
    /// violation is the error.
    pub(super) fn validate(&self) -> Result<(), SceneError> {
        field(
            "name",
            &self.name,
            !self.name.trim().is_empty(),
            "a non-empty name",
        )?;
        self.validate_environment()?;
        self.validate_surface_and_proxy()?;
        self.validate_limits()?;
        field(
            "rates.control_hz",
            self.rates.control_hz,
            (100.0..=20_000.0).contains(&self.rates.control_hz),
            "in [100, 20000] Hz",
        )?;
        self.cloud.validate_finite()?;
        self.cloud.validate_external()?;
        if self.cloud.source == CloudKind::Plane {
            self.validate_cloud()?;
        }
        self.validate_sensors()?;
        self.validate_prior()?;
        self.validate_model()
    }

    /// `[prior]`: every term and the spread, named by its scene field; then the prior it
    /// gives, through the renderers' gates for the scene's structures (what the operator does
    /// with it at the `Welcome`).
    fn validate_prior(&self) -> Result<(), SceneError> {
        let Some(guess) = &self.prior else {
            return Ok(());
        };
        let prior = guess.prior().map_err(|e| {
            let name = match e.field {
                "mass_kg" => "prior.mass_kg",
                "k_ground_n_per_m" => "prior.k_ground_n_per_m",
                "b_ground_ns_per_m" => "prior.b_ground_ns_per_m",
                "k_contact_n_per_m" => "prior.k_contact_n_per_m",
                "b_contact_ns_per_m" => "prior.b_contact_ns_per_m",
                "coulomb_friction_n" => "prior.coulomb_friction_n",
                "spread" => "prior.spread",
                _ => "prior",
            };
            SceneError::Field {
                origin: String::new(),
                field: name,
                value: format!("{:?}", e.value),
                expected: e.expected,
            }
        })?;
        let (normal, tangential) = (
            self.model.normal_structure(),
            self.model.tangential_structure(),
        );
        node::operator::gate_prior(&prior, normal, tangential)
            .map(|_| ())
            .map_err(|e| SceneError::Field {
                origin: String::new(),
                field: "prior",
                value: e.to_string(),
                expected: "a prior the renderers accept for the scene's [model] structures (a \
                           sliding object needs damping above 0)",
            })
    }

    /// `[sensors]`: every noise term, named by its scene field.
    fn validate_sensors(&self) -> Result<(), SceneError> {
        let Some((name, value, expected)) = self.sensors.noise().invalid_field() else {
            return Ok(());
        };
        let name = match name {
            "noise.position_resolution_m" => "sensors.position_resolution_m",
            "noise.position_sd_m" => "sensors.position_sd_m",
            "noise.velocity_sd_m_per_s" => "sensors.velocity_sd_m_per_s",
            "noise.force_sd_n" => "sensors.force_sd_n",
            "noise.force_bias_n" => "sensors.force_bias_n",
            "noise.force_bias_gradient_n_per_m" => "sensors.force_bias_gradient_n_per_m",
            _ => "sensors.force_bias_drift_n_per_s",
        };
        field(name, value, false, expected)
    }

    /// `[environment]`: signs, the Karnopp order, physical upper limits, and what an anchored
    /// or a free object needs.
    fn validate_environment(&self) -> Result<(), SceneError> {
        let e = &self.environment;
        non_negative("environment.mass_kg", e.mass_kg)?;
        non_negative("environment.k_ground_n_per_m", e.k_ground_n_per_m)?;
        non_negative("environment.b_ground_ns_per_m", e.b_ground_ns_per_m)?;
        positive("environment.k_contact_n_per_m", e.k_contact_n_per_m)?;
        non_negative("environment.b_contact_ns_per_m", e.b_contact_ns_per_m)?;
        non_negative("environment.static_friction_n", e.static_friction_n)?;
        non_negative("environment.coulomb_friction_n", e.coulomb_friction_n)?;
        if e.coulomb_friction_n > e.static_friction_n {
            return Err(SceneError::Field {
                origin: String::new(),
                field: "environment.coulomb_friction_n",
                value: format!(
                    "{} (static_friction_n = {})",
                    e.coulomb_friction_n, e.static_friction_n
                ),
                expected: "≤ environment.static_friction_n (Karnopp: dynamic friction does not exceed static)",
            });
        }
        non_negative(
            "environment.stick_velocity_m_per_s",
            e.stick_velocity_m_per_s,
        )?;
        self.validate_physical_limits()?;
        if e.anchored {
            for (name, v) in [
                ("environment.mass_kg", e.mass_kg),
                ("environment.k_ground_n_per_m", e.k_ground_n_per_m),
                ("environment.b_ground_ns_per_m", e.b_ground_ns_per_m),
                ("environment.static_friction_n", e.static_friction_n),
                ("environment.coulomb_friction_n", e.coulomb_friction_n),
            ] {
                field(
                    name,
                    v,
                    v == 0.0,
                    "0 for an anchored object (it cannot move)",
                )?;
            }
        } else {
            // A sliding object of at least a gram: 1/m of a subnormal mass overflows and the
            // simulation's discretisation failed at world creation (found by the scene proptest,
            // mass_kg = 5e-324). Lighter objects are typos, not objects a device can push.
            field(
                "environment.mass_kg",
                e.mass_kg,
                e.mass_kg >= MIN_SLIDING_MASS_KG,
                "≥ 0.001 kg (1 g) for an object that is not anchored",
            )?;
            // The Karnopp stick band of a sliding object: 0 has no band to stick in (the
            // simulation refused it at world creation; found by the scene proptest).
            positive(
                "environment.stick_velocity_m_per_s",
                e.stick_velocity_m_per_s,
            )?;
            field(
                "environment.b_ground_ns_per_m",
                e.b_ground_ns_per_m,
                e.b_ground_ns_per_m > 0.0 || e.k_ground_n_per_m > 0.0,
                "> 0 when k_ground is 0 (an undamped free mass never settles)",
            )?;
        }
        Ok(())
    }

    /// Physical upper limits: beyond them the object is not one a haptic device can touch (the
    /// renderer would clip it to nothing) or the numbers are a typo.
    fn validate_physical_limits(&self) -> Result<(), SceneError> {
        let e = &self.environment;
        for (name, v, hi, expected) in [
            ("environment.mass_kg", e.mass_kg, 1e3, "at most 1000 kg"),
            (
                "environment.k_ground_n_per_m",
                e.k_ground_n_per_m,
                1e7,
                "at most 1e7 N/m",
            ),
            (
                "environment.b_ground_ns_per_m",
                e.b_ground_ns_per_m,
                1e5,
                "at most 1e5 N·s/m",
            ),
            (
                "environment.k_contact_n_per_m",
                e.k_contact_n_per_m,
                1e7,
                "at most 1e7 N/m",
            ),
            (
                "environment.b_contact_ns_per_m",
                e.b_contact_ns_per_m,
                1e5,
                "at most 1e5 N·s/m",
            ),
            (
                "environment.static_friction_n",
                e.static_friction_n,
                1e4,
                "at most 1e4 N",
            ),
            (
                "environment.stick_velocity_m_per_s",
                e.stick_velocity_m_per_s,
                1.0,
                "at most 1 m/s",
            ),
        ] {
            field(name, v, v <= hi, expected)?;
        }
        Ok(())
    }

    /// `[surface]` and `[proxy]`: a finite plane and the proxy's ordered radii.
    fn validate_surface_and_proxy(&self) -> Result<(), SceneError> {
        let s = &self.surface;
        for v in s.point_m {
            field(
                "surface.point_m",
                s.point_m,
                v.is_finite(),
                "three finite coordinates [m]",
            )?;
        }
        let len = (s.normal.iter().map(|c| c * c).sum::<f64>()).sqrt();
        field(
            "surface.normal",
            s.normal,
            len.is_finite() && len > 1e-9,
            "a non-zero finite vector",
        )?;
        let p = &self.proxy;
        positive("proxy.r1_m", p.r1_m)?;
        field(
            "proxy.r2_m",
            p.r2_m,
            p.r2_m.is_finite() && p.r2_m > p.r1_m,
            "> proxy.r1_m",
        )?;
        field(
            "proxy.r3_m",
            p.r3_m,
            p.r3_m.is_finite() && p.r3_m > p.r2_m,
            "> proxy.r2_m",
        )
    }

    /// `[cloud]`, when the simulated camera makes it: sizes, a spacing the proxy cannot slip through, the
    /// point budget, dropout and rate.
    fn validate_cloud(&self) -> Result<(), SceneError> {
        let c = &self.cloud;
        for v in c.size_m {
            field(
                "cloud.size_m",
                c.size_m,
                v.is_finite() && v > 0.0 && v <= 100.0,
                "two sizes in (0, 100] m",
            )?;
        }
        field(
            "cloud.spacing_m",
            c.spacing_m,
            c.spacing_m.is_finite() && c.spacing_m >= 1e-4,
            "≥ 0.1 mm",
        )?;
        non_negative("cloud.noise_m", c.noise_m)?;
        self.validate_camera_noise()?;
        let noise = c.noise_sigma_m();
        let name = if c.depth_noise_per_m > 0.0 {
            "cloud.noise_m with cloud.depth_noise_per_m (σ at the window's farthest corner)"
        } else {
            "cloud.noise_m"
        };
        field(
            name,
            noise,
            noise <= (self.proxy.r2_m - self.proxy.r1_m) / 2.0,
            "≤ (proxy.r2_m − proxy.r1_m)/2, the noise the proxy's band holds (scale the radii \
             with the noise)",
        )?;
        field(
            "cloud.spacing_m",
            c.spacing_m,
            c.spacing_m < self.max_plane_spacing_m(),
            "below √2·(proxy.r1_m + proxy.r2_m)/2 (the gap the proxy's sphere cannot pass), \
             and small enough that the disk of radius proxy.r3_m holds 48 points after \
             cloud.dropout and cloud.holes",
        )?;
        let points = (c.size_m[0] / c.spacing_m) * (c.size_m[1] / c.spacing_m);
        field(
            "cloud.spacing_m",
            c.spacing_m,
            points <= 5e6,
            "at most 5 million points per frame",
        )?;
        field(
            "cloud.dropout",
            c.dropout,
            (0.0..=0.6).contains(&c.dropout),
            "a fraction in [0, 0.6]",
        )?;
        field(
            "cloud.rate_hz",
            c.rate_hz,
            c.rate_hz.is_finite() && c.rate_hz > 0.0 && c.rate_hz <= 1000.0,
            "in (0, 1000] Hz",
        )?;
        Ok(())
    }

    /// The largest grid spacing of the simulated plane [m]: below `√2·(r1 + r2)/2`, so the
    /// proxy's sphere cannot pass between the points of a full grid (at the window's edge,
    /// where no plane bridges them: `ProxyConfig::max_point_spacing_m`), and with
    /// [`PLANE_POINTS_IN_R3`] points within `r3` after dropout and holes, the support the bridging plane needs
    /// (`mmt::contact::bridge`: about a quarter of the points in `r3` count as effective points,
    /// 35–40 of ~140 on the exp-1 plane, and it needs 12). Noise no longer narrows it: where the
    /// plane bridges the points, the proxy rests on the fit, not on the noisiest point (the
    /// thesis's proxy needed `√2·((r1 + r2)/2 − 3σ)`; a 5 mm grid with 0.5 mm noise let a 4 mm
    /// sphere through in 0.7 % of presses).
    pub(super) fn max_plane_spacing_m(&self) -> f64 {
        let c = &self.cloud;
        let proxy = self.proxy.config(self.rates.control_hz);
        let kept = (1.0 - c.dropout) * (1.0 - c.holes);
        let support = self.proxy.r3_m * (std::f64::consts::PI * kept / PLANE_POINTS_IN_R3).sqrt();
        proxy.max_point_spacing_m().min(support)
    }

    /// The simulated camera's clustered holes and depth noise ([`crate::holes`]).
    fn validate_camera_noise(&self) -> Result<(), SceneError> {
        let c = &self.cloud;
        field(
            "cloud.holes",
            c.holes,
            (0.0..=0.6).contains(&c.holes),
            "a fraction in [0, 0.6] of the face in hole patches",
        )?;
        field(
            "cloud.hole_radius_m",
            c.hole_radius_m,
            c.hole_radius_m >= c.spacing_m && c.hole_radius_m <= 0.5,
            "from cloud.spacing_m to 0.5 m",
        )?;
        // The patches are drawn per cell of three radii over the window: a bounded number.
        let cells = c
            .size_m
            .iter()
            .map(|s| s / (3.0 * c.hole_radius_m) + 3.0)
            .product::<f64>();
        field(
            "cloud.hole_radius_m",
            c.hole_radius_m,
            c.holes == 0.0 || cells <= 1e6,
            "at least 1/3000 of cloud.size_m (a million patch cells per frame)",
        )?;
        field(
            "cloud.depth_noise_per_m",
            c.depth_noise_per_m,
            (0.0..=0.1).contains(&c.depth_noise_per_m),
            "in [0, 0.1] 1/m (σ = this × range²; a RealSense D435 is about 0.0037)",
        )?;
        field(
            "cloud.camera_distance_m",
            c.camera_distance_m,
            c.camera_distance_m > 0.0 && c.camera_distance_m <= 10.0,
            "in (0, 10] m",
        )
    }

    /// `[model]`: structures the object can have, the filter's cut-off and the forgetting.
    fn validate_model(&self) -> Result<(), SceneError> {
        let e = &self.environment;
        let m = &self.model;
        field(
            "model.normal",
            format!("{:?}", m.normal),
            m.normal != StructureName::SlidingMass,
            "free or kelvin-voigt (the table holds the object along the normal)",
        )?;
        if e.anchored {
            field(
                "model.tangential",
                format!("{:?}", m.tangential),
                m.tangential != StructureName::SlidingMass,
                "free or kelvin-voigt for an anchored object",
            )?;
        }
        if m.tangential != StructureName::SlidingMass {
            field(
                "model.ground_spring",
                m.ground_spring,
                !m.ground_spring,
                "false unless tangential = \"sliding-mass\"",
            )?;
            field(
                "model.friction",
                m.friction,
                !m.friction,
                "false unless tangential = \"sliding-mass\"",
            )?;
            field(
                "model.select_structure",
                m.select_structure,
                !m.select_structure,
                "false unless tangential = \"sliding-mass\" (only its structures are chosen from)",
            )?;
        }
        field(
            "model.filter_cutoff_hz",
            m.filter_cutoff_hz,
            m.filter_cutoff_hz.is_finite()
                && m.filter_cutoff_hz >= 0.5
                && m.filter_cutoff_hz <= self.rates.control_hz / 10.0,
            "in [0.5 Hz, control rate / 10]",
        )?;
        field(
            "model.forgetting",
            m.forgetting,
            m.forgetting > 0.99 && m.forgetting <= 1.0,
            "in (0.99, 1]",
        )?;
        Ok(())
    }
}

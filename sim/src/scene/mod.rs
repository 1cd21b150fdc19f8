//! Scenes: what the world is and what the model needs (`DESIGN.md` §9). A scene is a TOML file
//! under `scenes/`; [`Scene::from_toml`] parses it and validates every field, naming the field,
//! the value and the allowed range on error, then holds a simulated cloud to the real-time
//! budget ([`Scene::cloud_budget`] says what that changed).
//!
//! ```toml
//! name = "exp1"
//! [environment]               # ground truth of the simulated bridge
//! mass_kg = 1.0
//! k_ground_n_per_m = 0.0
//! b_ground_ns_per_m = 60.0
//! k_contact_n_per_m = 500.0
//! b_contact_ns_per_m = 60.0
//! static_friction_n = 0.1
//! coulomb_friction_n = 0.05
//! stick_velocity_m_per_s = 0.005
//! anchored = false            # true: the object cannot move (a wall)
//! [surface]
//! point_m = [0.0, 0.0, 0.0]   # a point of the contact surface (the object's top)
//! normal = [0.0, 0.0, 1.0]    # outward normal, any orientation
//! [cloud]
//! source = "plane"            # plane | file | ros2 | none (see `cloud`)
//! size_m = [0.3, 0.3]
//! centre = "tool"             # tool | surface: what the camera window is centred on
//! spacing_m = 0.0045
//! noise_m = 0.0005
//! dropout = 0.0
//! rate_hz = 30.0
//! moving = true               # the cloud follows the object as it slides
//! [model]
//! normal = "kelvin-voigt"
//! tangential = "sliding-mass" # free | kelvin-voigt | sliding-mass
//! ground_spring = false
//! friction = true
//! filter_cutoff_hz = 5.0
//! forgetting = 0.9999
//! select_structure = false    # optional: choose k1 and friction from the data (issue 12 item 5)
//! [proxy]
//! r1_m = 0.004
//! r2_m = 0.006
//! r3_m = 0.03
//! [sensors]
//! preset = "franka-like"      # franka-like | arm-wrench | wrist-ft | clean
//! force_sd_n = 0.05           # optional: any term of the preset, set on its own
//! [limits]                    # optional, each key too (defaults: node::MotionLimits)
//! workspace_min_m = [-0.25, -0.25, -0.25]
//! workspace_max_m = [0.25, 0.25, 0.25]
//! max_step_m = 0.001          # per tick
//! max_speed_m_per_s = 1.0
//! max_clock_jump_s = 10.0
//! ```

mod budget;
mod cloud;
mod settings;
mod validate;

pub use budget::CloudBudgetFit;
pub use cloud::{
    CloudKind, CloudPose, CloudSource, DEFAULT_MAX_POINTS, DEFAULT_STALE_MS, WindowCentre,
};
pub use validate::SceneError;

use crate::SensorNoise;
use mmt::contact::ProxyConfig;
use mmt::model::prior::Guess;
use mmt::model::{KelvinVoigt, Physical, Structure};
use serde::{Deserialize, Serialize};

/// A validated scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short name, for reports.
    pub name: String,
    /// One-line description.
    #[serde(default)]
    pub description: String,
    /// Ground truth of the simulated environment.
    pub environment: Environment,
    /// The contact surface.
    pub surface: Surface,
    /// The point-cloud source.
    #[serde(default)]
    pub cloud: CloudSource,
    /// The model structure and its estimation settings.
    pub model: ModelSection,
    /// Contact detector radii.
    #[serde(default)]
    pub proxy: ProxySection,
    /// Sensor noise of the simulated bridge.
    #[serde(default)]
    pub sensors: Sensors,
    /// Loop rates.
    #[serde(default)]
    pub rates: Rates,
    /// What the robot may be told to do (`node::MotionLimits`); each limit left out takes its
    /// default around the surface point ([`Scene::motion_limits`]).
    #[serde(default)]
    pub limits: Option<LimitsSection>,
    /// An informed guess of the object for the operator to render before its first model
    /// (issue 13: e.g. from vision), weighed against the generic class
    /// ([`mmt::model::prior::Guess::prior`]). Left out: the generic prior.
    #[serde(default)]
    pub prior: Option<Guess>,
    /// What the real-time budget did to the cloud at load ([`Scene::cloud_budget`]).
    #[serde(skip)]
    cloud_budget: Option<CloudBudgetFit>,
}

/// The robot's motion limits, each optional (`node::MotionLimits` gives the defaults and the
/// ceilings).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsSection {
    /// Lower corner of the workspace box, base frame [m]. Default: surface point − 0.25 m.
    pub workspace_min_m: Option<[f64; 3]>,
    /// Upper corner of the workspace box, base frame [m]. Default: surface point + 0.25 m.
    pub workspace_max_m: Option<[f64; 3]>,
    /// Largest commanded step per tick [m]. Default 0.001 (1 m/s at 1 kHz); at most 0.01.
    pub max_step_m: Option<f64>,
    /// Largest commanded speed [m/s]. Default 1; at most 2.
    pub max_speed_m_per_s: Option<f64>,
    /// Largest jump of a command's lag from the session's first [s]. Default 10; 0.1 to 60.
    pub max_clock_jump_s: Option<f64>,
}

/// Ground truth of the simulated object (thesis set-up 1), keyed as the issue fixes them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    /// Object mass [kg] (exp 1: 1): 0 for an anchored object, else at least 0.001 (1 g).
    pub mass_kg: f64,
    /// Ground spring k1 [N/m] (exp 1: 0, free to slide).
    pub k_ground_n_per_m: f64,
    /// Ground damper b1 [N·s/m] (exp 1: 60).
    pub b_ground_ns_per_m: f64,
    /// Contact spring k2 [N/m] (exp 1: 500); also the normal-axis stiffness.
    pub k_contact_n_per_m: f64,
    /// Contact damper b2 [N·s/m] (exp 1: 60); also the normal-axis damping.
    pub b_contact_ns_per_m: f64,
    /// Karnopp static friction Fs [N] (exp 1: 0.1).
    pub static_friction_n: f64,
    /// Karnopp dynamic (Coulomb) friction Fd [N] (exp 1: 0.05).
    pub coulomb_friction_n: f64,
    /// Karnopp stick band vd [m/s] (exp 1: 0.005).
    pub stick_velocity_m_per_s: f64,
    /// The object cannot move (a wall): the contact is then Kelvin–Voigt on every axis, and the
    /// mass, ground terms and friction must be 0.
    #[serde(default)]
    pub anchored: bool,
}

impl Environment {
    /// The sliding object's parameters (Coulomb level = the dynamic friction).
    pub fn physical(&self) -> Physical {
        Physical {
            mass_kg: self.mass_kg,
            k_ground_n_per_m: self.k_ground_n_per_m,
            b_ground_ns_per_m: self.b_ground_ns_per_m,
            k_contact_n_per_m: self.k_contact_n_per_m,
            b_contact_ns_per_m: self.b_contact_ns_per_m,
            coulomb_n: self.coulomb_friction_n,
        }
    }

    /// The contact element alone (normal axis, or every axis of an anchored object).
    pub fn contact(&self) -> KelvinVoigt {
        KelvinVoigt {
            k_n_per_m: self.k_contact_n_per_m,
            b_ns_per_m: self.b_contact_ns_per_m,
        }
    }
}

/// The contact surface: a plane through `point_m` with outward `normal`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    /// A point of the surface [m], world frame.
    pub point_m: [f64; 3],
    /// Outward normal (normalised on validation).
    pub normal: [f64; 3],
}

/// The model structure per axis and the estimation settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSection {
    /// Structure of the normal axis.
    pub normal: StructureName,
    /// Structure of the two tangential axes (one model shared by both).
    pub tangential: StructureName,
    /// Sliding mass only: estimate the ground spring k1. Keep it out when the object is free to
    /// slide (`DESIGN.md` §11.7).
    #[serde(default)]
    pub ground_spring: bool,
    /// Sliding mass only: estimate and render Coulomb friction.
    #[serde(default)]
    pub friction: bool,
    /// State-variable filter cut-off [Hz] (§11.2: 5–7 Hz for exp 1, the thesis used 10).
    pub filter_cutoff_hz: f64,
    /// RLS forgetting factor per 1 ms tick.
    pub forgetting: f64,
    /// Sliding mass only: choose from the data which structure inside the one above the object
    /// needs — with or without the ground spring, with or without friction — by an
    /// information criterion on the estimator's fit, and render that one
    /// (`mmt::estimator::EstimatorConfig::select_structure`). Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub select_structure: bool,
}

impl ModelSection {
    /// The normal axis's structure.
    pub fn normal_structure(&self) -> Structure {
        self.normal.structure(false, false)
    }

    /// The tangential axes' structure.
    pub fn tangential_structure(&self) -> Structure {
        self.tangential.structure(self.ground_spring, self.friction)
    }
}

/// A structure by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StructureName {
    /// No force.
    Free,
    /// Kelvin–Voigt (k, b).
    KelvinVoigt,
    /// The sliding flexible object.
    SlidingMass,
}

impl StructureName {
    fn structure(self, ground_spring: bool, friction: bool) -> Structure {
        match self {
            StructureName::Free => Structure::Free,
            StructureName::KelvinVoigt => Structure::KelvinVoigt,
            StructureName::SlidingMass => Structure::SlidingMass {
                ground_spring,
                friction,
            },
        }
    }
}

/// The contact detector's radii (thesis appendix C).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProxySection {
    /// r1 [m].
    pub r1_m: f64,
    /// r2 [m].
    pub r2_m: f64,
    /// r3 [m].
    pub r3_m: f64,
}

impl Default for ProxySection {
    fn default() -> Self {
        ProxySection {
            r1_m: 0.004,
            r2_m: 0.006,
            r3_m: 0.03,
        }
    }
}

impl ProxySection {
    /// The detector configuration at `rate_hz`.
    pub fn config(&self, rate_hz: f64) -> ProxyConfig {
        ProxyConfig {
            r1_m: self.r1_m,
            r2_m: self.r2_m,
            r3_m: self.r3_m,
            rate_hz,
            ..ProxyConfig::default()
        }
    }
}

/// Sensor noise of the simulated bridge: a preset, and any of its terms set on its own
/// (every term of [`SensorNoise`] is a field here; a field given replaces the preset's value).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    /// The preset the fields below start from.
    pub preset: SensorPreset,
    /// Position quantisation step [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_resolution_m: Option<f64>,
    /// Position noise standard deviation [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_sd_m: Option<f64>,
    /// Velocity noise standard deviation [m/s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_sd_m_per_s: Option<f64>,
    /// Force noise standard deviation [N].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_sd_n: Option<f64>,
    /// Constant force offset on every axis [N].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_bias_n: Option<f64>,
    /// Change of the force offset with the axis position [N/m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_bias_gradient_n_per_m: Option<f64>,
    /// Change of the force offset with time [N/s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_bias_drift_n_per_s: Option<f64>,
}

/// Sensor-noise presets ([`SensorNoise`]'s constants say what each assumes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SensorPreset {
    /// 1 µm quantisation, 2 µm / 1 mm/s / 0.02 N noise, 0.05 N force bias.
    #[default]
    FrankaLike,
    /// An arm's model-based wrench estimate (assumed): 0.2 N noise, a 1 N bias drifting with
    /// the position (5 N/m) and in time (1 mN/s).
    ArmWrench,
    /// A wrist force/torque sensor (assumed): 0.01 N noise, a 0.3 N bias drifting 0.5 mN/s.
    WristFt,
    /// No noise.
    Clean,
}

impl SensorPreset {
    /// Every preset, for benchmarks.
    pub const ALL: [SensorPreset; 4] = [
        SensorPreset::FrankaLike,
        SensorPreset::ArmWrench,
        SensorPreset::WristFt,
        SensorPreset::Clean,
    ];

    /// The name a scene uses.
    pub fn name(self) -> &'static str {
        match self {
            SensorPreset::FrankaLike => "franka-like",
            SensorPreset::ArmWrench => "arm-wrench",
            SensorPreset::WristFt => "wrist-ft",
            SensorPreset::Clean => "clean",
        }
    }

    /// The preset of a name, if it is one.
    pub fn parse(name: &str) -> Option<SensorPreset> {
        SensorPreset::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The preset's levels.
    pub fn noise(self) -> SensorNoise {
        match self {
            SensorPreset::FrankaLike => SensorNoise::FRANKA_LIKE,
            SensorPreset::ArmWrench => SensorNoise::ARM_WRENCH,
            SensorPreset::WristFt => SensorNoise::WRIST_FT,
            SensorPreset::Clean => SensorNoise::CLEAN,
        }
    }
}

impl Sensors {
    /// Sensors of a preset, no field changed.
    pub fn preset(preset: SensorPreset) -> Sensors {
        Sensors {
            preset,
            ..Sensors::default()
        }
    }

    /// The noise model: the preset's, with the fields given replacing its values.
    pub fn noise(&self) -> SensorNoise {
        let mut n = self.preset.noise();
        let set = |v: &mut f64, o: Option<f64>| {
            if let Some(o) = o {
                *v = o;
            }
        };
        set(&mut n.position_resolution_m, self.position_resolution_m);
        set(&mut n.position_sd_m, self.position_sd_m);
        set(&mut n.velocity_sd_m_per_s, self.velocity_sd_m_per_s);
        set(&mut n.force_sd_n, self.force_sd_n);
        set(&mut n.force_bias_n, self.force_bias_n);
        set(
            &mut n.force_bias_gradient_n_per_m,
            self.force_bias_gradient_n_per_m,
        );
        set(
            &mut n.force_bias_drift_n_per_s,
            self.force_bias_drift_n_per_s,
        );
        n
    }
}

/// Loop rates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rates {
    /// Haptic and telerobot loop rate [Hz]. Default 1000.
    pub control_hz: f64,
}

impl Default for Rates {
    fn default() -> Self {
        Rates { control_hz: 1000.0 }
    }
}

impl Scene {
    /// Parses and validates a scene. `origin` names the source in errors (a file name).
    pub fn from_toml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        let scene: Scene = toml::from_str(text).map_err(|e| SceneError::Parse {
            origin: origin.to_string(),
            message: e.to_string(),
        })?;
        let mut scene = scene.validated(origin)?;
        let budget = scene.cloud.budget;
        scene
            .fit_cloud_budget(&budget)
            .map_err(|e| e.with_origin(origin))?;
        let n = scene.surface.normal;
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        scene.surface.normal = n.map(|c| c / len);
        Ok(scene)
    }

    /// The scene, checked as [`Scene::from_toml`] checks a file's: for a scene that came from
    /// elsewhere (a recording's `/run`). `origin` names the source in errors.
    pub fn validated(self, origin: &str) -> Result<Scene, SceneError> {
        self.validate().map_err(|e| e.with_origin(origin))?;
        Ok(self)
    }

    /// The built-in experiment-1 scene (`scenes/exp1.toml`).
    pub fn exp1() -> Scene {
        // The file is part of the crate; a failure here is a bug caught by the tests.
        Scene::from_toml(EXP1_TOML, "scenes/exp1.toml")
            .unwrap_or_else(|e| panic!("built-in scene: {e}"))
    }

    /// The built-in wall scene (`scenes/wall.toml`).
    pub fn wall() -> Scene {
        Scene::from_toml(WALL_TOML, "scenes/wall.toml")
            .unwrap_or_else(|e| panic!("built-in scene: {e}"))
    }

    /// The physical terms the scene's model leaves out, for reports.
    pub fn left_out(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (axis, s) in [
            ("normal", self.model.normal_structure()),
            ("tangential", self.model.tangential_structure()),
        ] {
            for term in s.left_out() {
                out.push(format!("{axis}: {term}"));
            }
        }
        if self.cloud.source == CloudKind::None {
            out.push("point cloud".into());
        } else if !self.cloud.moving {
            out.push("moving cloud (the cloud is sent once)".into());
        }
        out
    }
}

/// `scenes/exp1.toml`, compiled in so the demo needs no file.
pub const EXP1_TOML: &str = include_str!("../../../scenes/exp1.toml");
/// `scenes/wall.toml`.
pub const WALL_TOML: &str = include_str!("../../../scenes/wall.toml");

#[cfg(test)]
mod tests;

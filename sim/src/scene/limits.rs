//! The scene's `[limits]`: the command limits every robot bridge sits behind
//! (`node::guard`), in the robot's base frame.
//!
//! ```toml
//! [limits]                                 # every key optional
//! workspace_min_m = [-0.3, -0.3, -0.3]     # default: the surface point ± 0.3 m
//! workspace_max_m = [0.3, 0.3, 0.3]
//! max_step_m = 0.002                       # default 2 mm
//! max_speed_m_per_s = 1.0                  # default 1 m/s
//! state_timeout_ms = 50.0                  # default 50 ms
//! ```

use node::CommandLimits;
use serde::{Deserialize, Serialize};

use super::Scene;
use super::validate::SceneError;

/// Half-edge of the default workspace cube around the surface point \[m\]: the exp-1 motion
/// spans ±8 cm; a lab arm's reach around a table-top object is of this order.
pub const DEFAULT_WORKSPACE_HALF_M: f64 = 0.3;

/// `[limits]`, every key optional.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsSection {
    /// Lower corner of the workspace box, base frame \[m\].
    pub workspace_min_m: Option<[f64; 3]>,
    /// Upper corner \[m\].
    pub workspace_max_m: Option<[f64; 3]>,
    /// Largest move between consecutive commands \[m\].
    pub max_step_m: Option<f64>,
    /// Largest commanded speed \[m/s\].
    pub max_speed_m_per_s: Option<f64>,
    /// A robot state older than this holds the robot \[ms\].
    pub state_timeout_ms: Option<f64>,
}

impl Scene {
    /// The command limits: the scene's `[limits]`, the defaults where it says nothing (a cube of
    /// ±0.3 m around the surface point, 2 mm steps, 1 m/s, 50 ms).
    pub fn command_limits(&self) -> CommandLimits {
        let d = CommandLimits::around(self.surface.point_m, DEFAULT_WORKSPACE_HALF_M);
        let l = &self.limits;
        CommandLimits {
            workspace_min_m: l.workspace_min_m.unwrap_or(d.workspace_min_m),
            workspace_max_m: l.workspace_max_m.unwrap_or(d.workspace_max_m),
            max_step_m: l.max_step_m.unwrap_or(d.max_step_m),
            max_speed_m_per_s: l.max_speed_m_per_s.unwrap_or(d.max_speed_m_per_s),
            state_timeout_ns: l
                .state_timeout_ms
                .map_or(d.state_timeout_ns, |ms| (ms * 1e6).round() as i64),
        }
    }

    pub(super) fn validate_limits(&self) -> Result<(), SceneError> {
        if let Some(ms) = self.limits.state_timeout_ms
            && !(ms.is_finite() && (1.0..=1000.0).contains(&ms))
        {
            return Err(SceneError::Field {
                origin: String::new(),
                field: "limits.state_timeout_ms",
                value: format!("{ms}"),
                expected: "1 to 1000 ms",
            });
        }
        self.command_limits()
            .validate()
            .map_err(|e| SceneError::Field {
                origin: String::new(),
                field: match e.field {
                    "workspace" => "limits.workspace_min_m / limits.workspace_max_m",
                    "max_step_m" => "limits.max_step_m",
                    "max_speed_m_per_s" => "limits.max_speed_m_per_s",
                    _ => "limits.state_timeout_ms",
                },
                value: e.value,
                expected: e.expected,
            })
    }
}

//! Scripted tool trajectories: deterministic functions of time that drive the operator's device
//! in experiments and demos (`scripted:NAME`). The thesis's experiment-1 profile, chirps and steps
//! are added by the experiments work (issue 4); this module fixes the interface.

use serde::{Deserialize, Serialize};

/// Position and velocity of the tool at one instant, in world coordinates [m], [m/s].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrajectorySample {
    /// Position [m].
    pub position_m: [f64; 3],
    /// Velocity [m/s] (the exact derivative of `position_m`).
    pub velocity_m_per_s: [f64; 3],
}

/// A deterministic tool trajectory. Pure: the same `t_s` always gives the same sample.
pub trait Trajectory: Send + Sync {
    /// Short name, as used in `scripted:NAME`.
    fn name(&self) -> &str;
    /// Sample at time `t_s` [s] from the start of the run. Defined for every finite `t_s`
    /// (before 0 it holds the start, after the end it holds the end).
    fn sample(&self, t_s: f64) -> TrajectorySample;
    /// Natural length of the script [s], if it has one.
    fn duration_s(&self) -> Option<f64>;
}

/// Holds one position forever.
#[derive(Clone, Debug)]
pub struct Hold {
    /// The position held [m].
    pub position_m: [f64; 3],
}

impl Trajectory for Hold {
    fn name(&self) -> &str {
        "hold"
    }
    fn sample(&self, _t_s: f64) -> TrajectorySample {
        TrajectorySample {
            position_m: self.position_m,
            velocity_m_per_s: [0.0; 3],
        }
    }
    fn duration_s(&self) -> Option<f64> {
        None
    }
}

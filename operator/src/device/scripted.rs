//! The `scripted:NAME` backend (and, through [`super::replay`], `replay:FILE`): the simulated twin of
//! a device. The handle follows a [`Trajectory`], a pure function of time; forces written are
//! recorded by [`super::ManagedDevice`] (for reports) and go nowhere.
//!
//! Not a physics simulation: the hand is assumed to follow the script whatever force is rendered.

use std::time::Duration;

use sim::trajectory::Trajectory;

use super::{Backend, DeviceCapabilities, DeviceError, DeviceReading};
use mmt::vec3::Vec3;

/// A device whose handle follows a trajectory.
pub struct ScriptedBackend {
    trajectory: Box<dyn Trajectory>,
    capabilities: DeviceCapabilities,
}

impl ScriptedBackend {
    /// A twin of the omega.7: same limits (so the safety layer acts as on the real device),
    /// `outputs_force: false` (nothing is felt).
    #[must_use]
    pub fn new(trajectory: Box<dyn Trajectory>, label: &str) -> Self {
        let mut capabilities =
            DeviceCapabilities::omega7(format!("{label}:{} (omega.7 twin)", trajectory.name()));
        capabilities.outputs_force = false;
        Self {
            trajectory,
            capabilities,
        }
    }
}

impl Backend for ScriptedBackend {
    fn capabilities(&self) -> &DeviceCapabilities {
        &self.capabilities
    }

    fn read(&mut self, now: Duration) -> Result<DeviceReading, DeviceError> {
        let s = self.trajectory.sample(now.as_secs_f64());
        Ok(DeviceReading {
            position_m: s.position_m,
            velocity_m_per_s: s.velocity_m_per_s,
            clutch: false,
        })
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        Ok(())
    }

    fn set_force_enabled(&mut self, _on: bool) -> Result<(), DeviceError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::trajectory::Hold;

    #[test]
    fn follows_the_trajectory_and_declares_no_force_output() {
        let mut b = ScriptedBackend::new(
            Box::new(Hold {
                position_m: [0.01, 0.02, 0.03],
            }),
            "scripted",
        );
        let r = b.read(Duration::from_secs(3)).unwrap();
        assert_eq!(r.position_m, [0.01, 0.02, 0.03]);
        assert_eq!(r.velocity_m_per_s, [0.0; 3]);
        assert!(!b.capabilities().outputs_force);
        assert_eq!(b.capabilities().max_force_n, 12.0);
        assert!(b.capabilities().name.contains("scripted:hold"));
    }
}

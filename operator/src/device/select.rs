//! The `--device` value: [`DeviceSpec`] (parsed, validated) and [`open_device`], which builds the
//! backend and wraps it in the shared state machine.

use std::path::PathBuf;
use std::str::FromStr;

use sim::trajectory::{NAMES, Trajectory, by_name};

use super::omega::{OmegaBackend, OmegaConfig};
use super::replay::ReplayTrajectory;
use super::ros::{RosBackend, RosOptions};
use super::scripted::ScriptedBackend;
use super::spacemouse::{SpaceMouseBackend, SpaceMouseConfig};
use super::{DeviceError, HapticDevice, ManagedConfig, ManagedDevice};

/// Which device to use, as given by `--device`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceSpec {
    /// `scripted:NAME` — a named trajectory ([`scripted_trajectory`]).
    Scripted {
        /// Trajectory name.
        name: String,
    },
    /// `replay:FILE.csv` or `replay:FILE.mcap` — a recorded device trajectory
    /// ([`super::replay`]).
    Replay {
        /// The CSV file.
        path: PathBuf,
    },
    /// `spacemouse` — a 3Dconnexion SpaceMouse over HID (input only).
    SpaceMouse,
    /// `omega` — a Force Dimension device through its SDK.
    Omega,
    /// `ros2` — a device on a ROS 2 graph (forcedimension_ros2's topics by default).
    Ros2,
}

impl FromStr for DeviceSpec {
    type Err = DeviceError;

    fn from_str(value: &str) -> Result<Self, Self::Err> {
        let invalid = |reason: &str| DeviceError::InvalidSpec {
            value: value.to_owned(),
            reason: reason.to_owned(),
        };
        match value.split_once(':') {
            Some(("scripted", name)) if name.trim().is_empty() => {
                Err(invalid("scripted needs a trajectory name after the colon"))
            }
            Some(("scripted", name)) => Ok(Self::Scripted {
                name: name.to_owned(),
            }),
            Some(("replay", file)) if file.trim().is_empty() => {
                Err(invalid("replay needs a CSV file after the colon"))
            }
            Some(("replay", file)) => Ok(Self::Replay {
                path: PathBuf::from(file),
            }),
            Some((kind @ ("spacemouse" | "omega" | "ros2"), _)) => {
                Err(invalid(&format!("{kind} takes no argument")))
            }
            Some((kind, _)) => Err(invalid(&format!("unknown device kind '{kind}'"))),
            None => match value {
                "spacemouse" => Ok(Self::SpaceMouse),
                "omega" => Ok(Self::Omega),
                "ros2" => Ok(Self::Ros2),
                "scripted" | "replay" => {
                    Err(invalid(&format!("{value} needs an argument ({value}:…)")))
                }
                _ => Err(invalid("unknown device kind")),
            },
        }
    }
}

impl std::fmt::Display for DeviceSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Scripted { name } => write!(f, "scripted:{name}"),
            Self::Replay { path } => write!(f, "replay:{}", path.display()),
            Self::SpaceMouse => f.write_str("spacemouse"),
            Self::Omega => f.write_str("omega"),
            Self::Ros2 => f.write_str("ros2"),
        }
    }
}

/// Settings for every backend; only the chosen backend's part is used.
#[derive(Clone, Debug, Default)]
pub struct OpenOptions {
    /// Nominal length of a scripted trajectory \[s\] (its contact episodes are placed within it);
    /// `None`: the profiles' default, 60 s.
    pub scripted_length_s: Option<f64>,
    /// State machine settings (enable ramp, servo watchdog).
    pub managed: ManagedConfig,
    /// SpaceMouse settings.
    pub spacemouse: SpaceMouseConfig,
    /// Force Dimension settings.
    pub omega: OmegaConfig,
    /// ROS 2 device settings.
    pub ros: RosOptions,
}

/// Opens the device a spec names and wraps it in the state machine (Disabled).
pub fn open_device(
    spec: &DeviceSpec,
    options: &OpenOptions,
) -> Result<Box<dyn HapticDevice>, DeviceError> {
    Ok(match spec {
        DeviceSpec::Scripted { name } => Box::new(ManagedDevice::new(
            ScriptedBackend::new(
                scripted_trajectory(name, options.scripted_length_s.unwrap_or(60.0))?,
                "scripted",
            ),
            options.managed,
        )?),
        DeviceSpec::Replay { path } => Box::new(ManagedDevice::new(
            ScriptedBackend::new(Box::new(ReplayTrajectory::open(path)?), "replay"),
            options.managed,
        )?),
        DeviceSpec::SpaceMouse => Box::new(ManagedDevice::new(
            SpaceMouseBackend::open_hid(&options.spacemouse)?,
            options.managed,
        )?),
        DeviceSpec::Omega => Box::new(ManagedDevice::new(
            OmegaBackend::open(&options.omega)?,
            options.managed,
        )?),
        DeviceSpec::Ros2 => Box::new(ManagedDevice::new(
            RosBackend::open(&options.ros)?,
            options.managed,
        )?),
    })
}

/// Names [`scripted_trajectory`] knows: `mmt`'s named profiles.
pub const SCRIPTED_NAMES: &[&str] = &NAMES;

/// Resolves `scripted:NAME` to `mmt`'s named profile of nominal length `length_s` \[s\], placed on
/// the default surface (through the origin, normal +z: the exp-1 table), so that it presses into
/// the scene the telerobot simulates (`hold`: pressed 4 mm into the table, still).
pub fn scripted_trajectory(name: &str, length_s: f64) -> Result<Box<dyn Trajectory>, DeviceError> {
    match by_name(name, length_s, [0.0; 3], [0.0, 0.0, 1.0]) {
        Ok(placed) => Ok(Box::new(placed)),
        Err(_) => Err(DeviceError::UnknownTrajectory {
            name: name.to_owned(),
            known: SCRIPTED_NAMES.join(", "),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::OperatingState;

    #[test]
    fn parses_every_allowed_form() {
        assert_eq!(
            "scripted:hold".parse::<DeviceSpec>().unwrap(),
            DeviceSpec::Scripted {
                name: "hold".into()
            }
        );
        assert_eq!(
            "replay:runs/a.csv".parse::<DeviceSpec>().unwrap(),
            DeviceSpec::Replay {
                path: "runs/a.csv".into()
            }
        );
        assert_eq!(
            "spacemouse".parse::<DeviceSpec>().unwrap(),
            DeviceSpec::SpaceMouse
        );
        assert_eq!("omega".parse::<DeviceSpec>().unwrap(), DeviceSpec::Omega);
        assert_eq!("ros2".parse::<DeviceSpec>().unwrap(), DeviceSpec::Ros2);
        // A Windows-style path keeps its colon.
        assert_eq!(
            "replay:C:/x.csv".parse::<DeviceSpec>().unwrap(),
            DeviceSpec::Replay {
                path: "C:/x.csv".into()
            }
        );
    }

    #[test]
    fn errors_name_the_value_and_the_allowed_forms() {
        for bad in [
            "",
            "phantom",
            "scripted",
            "scripted:",
            "replay:",
            "omega:2",
            "ros2:/fd",
            "falcon:x",
        ] {
            let msg = bad.parse::<DeviceSpec>().unwrap_err().to_string();
            assert!(msg.contains(&format!("'{bad}'")), "{msg}");
            assert!(
                msg.contains(
                    "scripted:NAME, replay:FILE.csv, replay:FILE.mcap, spacemouse, omega, ros2"
                ),
                "{msg}"
            );
        }
    }

    #[test]
    fn display_round_trips() {
        for s in [
            "scripted:hold",
            "replay:a.csv",
            "spacemouse",
            "omega",
            "ros2",
        ] {
            assert_eq!(s.parse::<DeviceSpec>().unwrap().to_string(), s);
        }
    }

    #[test]
    fn unknown_trajectory_lists_known_names() {
        let e = scripted_trajectory("nope", 60.0).err().unwrap().to_string();
        assert!(
            e.contains("'nope'") && e.contains("hold") && e.contains("exp1"),
            "{e}"
        );
    }

    #[test]
    fn the_experiment_profiles_are_scripted_devices() {
        let t = scripted_trajectory("exp1", 20.0).unwrap();
        assert_eq!((t.name(), t.duration_s()), ("exp1", Some(20.0)));
        // Hovering above the table at the start, pressed into it in the first episode.
        assert!(t.sample(0.0).position_m[2] > 0.0);
        assert!(t.sample(3.0).position_m[2] < 0.0);
    }

    #[test]
    fn opens_a_scripted_device_disabled() {
        let d = open_device(&"scripted:hold".parse().unwrap(), &OpenOptions::default()).unwrap();
        assert_eq!(d.operating_state(), OperatingState::Disabled);
        assert!(!d.spec().outputs_force);
    }
}

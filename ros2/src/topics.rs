//! The topics of the ROS 2 robot bridge, their defaults and remapping, and the messages the
//! telerobot publishes about its model.
//!
//! | key | default | type | direction |
//! |---|---|---|---|
//! | `robot_pose` | `/mmt/robot/pose` | `geometry_msgs/PoseStamped` | in: the measured tool pose |
//! | `robot_twist` | `/mmt/robot/twist` | `geometry_msgs/TwistStamped` | in (`none`: differentiate the pose) |
//! | `robot_wrench` | `/mmt/robot/wrench` | `geometry_msgs/WrenchStamped` | in: force on the tool |
//! | `target_pose` | `/mmt/robot/target_pose` | `geometry_msgs/PoseStamped` | out: the commanded pose |
//! | `target_twist` | `/mmt/robot/target_twist` | `geometry_msgs/TwistStamped` | out: its velocity, same stamp (`none`: not published) |
//! | `theta` | `/mmt/theta` | `std_msgs/Float64MultiArray` | out: the gated model parameters |
//! | `in_contact` | `/mmt/in_contact` | `std_msgs/Bool` | out: the telerobot's contact state |
//! | `camera_points` | `/mmt/camera/points` | `sensor_msgs/PointCloud2` | in: the camera's cloud |
//!
//! Remap with `KEY=/new/name` (e.g. `robot_pose=/franka/ee_pose`).

use protocol::telerobot_to_operator::{ModelTerms, ParameterSet, Parameters};

use crate::graph::{GraphError, Qos, TopicName};
use crate::msg::{Float64MultiArray, MultiArrayDimension, MultiArrayLayout};

/// The robot bridge's topics.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotTopics {
    /// Measured tool pose.
    pub robot_pose: TopicName,
    /// Measured tool twist; `None`: the driver gives none (velocity from the pose).
    pub robot_twist: Option<TopicName>,
    /// Measured wrench on the tool.
    pub robot_wrench: TopicName,
    /// Commanded tool pose.
    pub target_pose: TopicName,
    /// Commanded tool velocity (feed-forward for a tracking controller), same stamp as the pose;
    /// `None`: not published.
    pub target_twist: Option<TopicName>,
    /// Gated model parameters.
    pub theta: TopicName,
    /// Contact state.
    pub in_contact: TopicName,
    /// The camera's cloud (a scene's `[cloud] source = "ros2"` may name another).
    pub camera_points: TopicName,
}

impl Default for RobotTopics {
    fn default() -> Self {
        let t = |what, name| TopicName::parse(what, name).unwrap_or_else(|e| panic!("{e}"));
        RobotTopics {
            robot_pose: t("robot_pose", "/mmt/robot/pose"),
            robot_twist: Some(t("robot_twist", "/mmt/robot/twist")),
            robot_wrench: t("robot_wrench", "/mmt/robot/wrench"),
            target_pose: t("target_pose", "/mmt/robot/target_pose"),
            target_twist: Some(t("target_twist", "/mmt/robot/target_twist")),
            theta: t("theta", "/mmt/theta"),
            in_contact: t("in_contact", "/mmt/in_contact"),
            camera_points: t("camera_points", "/mmt/camera/points"),
        }
    }
}

/// The keys [`RobotTopics::remap`] knows.
pub const ROBOT_KEYS: &str = "robot_pose, robot_twist, robot_wrench, target_pose, target_twist, \
     theta, in_contact, camera_points";

impl RobotTopics {
    /// Applies one `KEY=/name` remapping (`robot_twist=none`, `target_twist=none` drop those
    /// topics).
    pub fn remap(&mut self, rule: &str) -> Result<(), GraphError> {
        let (key, name) = split_rule(rule, ROBOT_KEYS)?;
        match (key, name) {
            ("robot_twist", "none") => {
                self.robot_twist = None;
                return Ok(());
            }
            ("target_twist", "none") => {
                self.target_twist = None;
                return Ok(());
            }
            _ => {}
        }
        let topic = TopicName::parse(key, name)?;
        match key {
            "robot_pose" => self.robot_pose = topic,
            "robot_twist" => self.robot_twist = Some(topic),
            "robot_wrench" => self.robot_wrench = topic,
            "target_pose" => self.target_pose = topic,
            "target_twist" => self.target_twist = Some(topic),
            "theta" => self.theta = topic,
            "in_contact" => self.in_contact = topic,
            "camera_points" => self.camera_points = topic,
            _ => return Err(unknown_key(key, ROBOT_KEYS)),
        }
        Ok(())
    }

    /// Every topic, `key = name`, for the start log.
    pub fn describe(&self) -> String {
        format!(
            "robot_pose = {}, robot_twist = {}, robot_wrench = {}, target_pose = {}, \
             target_twist = {}, theta = {}, in_contact = {}",
            self.robot_pose,
            self.robot_twist.as_ref().map_or(
                "none (velocity differentiated from the pose)".to_owned(),
                |t| t.to_string()
            ),
            self.robot_wrench,
            self.target_pose,
            self.target_twist
                .as_ref()
                .map_or("none".to_owned(), |t| t.to_string()),
            self.theta,
            self.in_contact
        )
    }
}

/// Splits `KEY=/name`.
pub fn split_rule<'a>(rule: &'a str, keys: &str) -> Result<(&'a str, &'a str), GraphError> {
    match rule.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() && !v.trim().is_empty() => Ok((k.trim(), v.trim())),
        _ => Err(GraphError::Name {
            what: "remapping".into(),
            name: rule.to_owned(),
            reason: format!("expected KEY=/topic/name with KEY one of {keys}"),
        }),
    }
}

/// A remapping with an unknown key.
pub fn unknown_key(key: &str, keys: &str) -> GraphError {
    GraphError::Name {
        what: "remapping".into(),
        name: key.to_owned(),
        reason: format!("unknown key; expected one of {keys}"),
    }
}

/// Applies `--qos KIND=SPEC` rules in order, each over the QoS of its kind among `kinds`
/// (`("state", &mut state_qos)`, …): the parts a rule leaves out keep that kind's value.
pub fn apply_qos_rules(rules: &[String], kinds: &mut [(&str, &mut Qos)]) -> Result<(), GraphError> {
    let names = kinds.iter().map(|(k, _)| *k).collect::<Vec<_>>().join(", ");
    for rule in rules {
        let (kind, spec) = split_rule(rule, &names)?;
        let Some((_, slot)) = kinds.iter_mut().find(|(k, _)| *k == kind) else {
            return Err(unknown_key(kind, &names));
        };
        **slot = Qos::parse(spec, **slot)?;
    }
    Ok(())
}

/// `/mmt/theta`: one labelled dimension (size 1) per parameter, in SI units, labels
/// `AXES.NAME`: `normal.k` \[N/m\], `normal.b` \[N·s/m\]; `tangential.m` \[kg\], `tangential.k1`
/// \[N/m\] (when the structure has a ground spring), `tangential.b1`, `tangential.k2`,
/// `tangential.b2`, `tangential.Fc` \[N\] (with friction); a Kelvin–Voigt tangential model gives
/// `tangential.k`, `tangential.b`. An axis without a confirmed model has no entries.
pub fn theta_message(p: &Parameters) -> Float64MultiArray {
    let mut labels: Vec<String> = Vec::with_capacity(12);
    let mut data: Vec<f64> = Vec::with_capacity(12);
    for (axis, set) in [("normal", &p.normal), ("tangential", &p.tangential)] {
        if let Some(set) = set {
            for (name, value) in terms(set) {
                labels.push(format!("{axis}.{name}"));
                data.push(value);
            }
        }
    }
    Float64MultiArray {
        layout: MultiArrayLayout {
            dim: labels
                .into_iter()
                .map(|label| MultiArrayDimension {
                    label,
                    size: 1,
                    stride: 1,
                })
                .collect(),
            data_offset: 0,
        },
        data,
    }
}

fn terms(set: &ParameterSet) -> Vec<(&'static str, f64)> {
    match set.terms {
        ModelTerms::KelvinVoigt {
            k_n_per_m,
            b_ns_per_m,
        } => vec![("k", k_n_per_m), ("b", b_ns_per_m)],
        ModelTerms::SlidingMass {
            mass_kg,
            k_ground_n_per_m,
            b_ground_ns_per_m,
            k_contact_n_per_m,
            b_contact_ns_per_m,
            coulomb_n,
        } => {
            let mut v = vec![("m", mass_kg)];
            if let Some(k1) = k_ground_n_per_m {
                v.push(("k1", k1));
            }
            v.push(("b1", b_ground_ns_per_m));
            v.push(("k2", k_contact_n_per_m));
            v.push(("b2", b_contact_ns_per_m));
            if let Some(fc) = coulomb_n {
                v.push(("Fc", fc));
            }
            v
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::Header;

    #[test]
    fn remapping_replaces_one_topic_and_names_bad_rules() {
        let mut t = RobotTopics::default();
        t.remap("robot_pose=/franka/ee_pose").unwrap();
        assert_eq!(t.robot_pose.as_str(), "/franka/ee_pose");
        t.remap("robot_twist=none").unwrap();
        assert!(t.robot_twist.is_none());
        t.remap(" robot_twist = /franka/ee_twist ").unwrap();
        assert_eq!(t.robot_twist.unwrap().as_str(), "/franka/ee_twist");
        let e = RobotTopics::default()
            .remap("robot_posture=/x")
            .unwrap_err();
        assert!(e.to_string().contains("unknown key"), "{e}");
        let e = RobotTopics::default().remap("robot_pose").unwrap_err();
        assert!(e.to_string().contains("KEY=/topic/name"), "{e}");
        let e = RobotTopics::default()
            .remap("target_pose=relative")
            .unwrap_err();
        assert!(e.to_string().contains("target_pose"), "{e}");
    }

    #[test]
    fn qos_rules_change_their_kind_only_and_name_bad_kinds() {
        let (mut state, mut command) = (Qos::STREAM, Qos::STREAM);
        let rules = [
            "command=reliable".to_owned(),
            "state=keep-last-5".to_owned(),
        ];
        apply_qos_rules(
            &rules,
            &mut [("state", &mut state), ("command", &mut command)],
        )
        .unwrap();
        assert_eq!(state.to_string(), "best-effort,volatile,keep-last-5");
        assert_eq!(command.to_string(), "reliable,volatile,keep-last-1");
        let e = apply_qos_rules(&["model=reliable".to_owned()], &mut [("state", &mut state)])
            .unwrap_err();
        assert!(e.to_string().contains("expected one of state"), "{e}");
        let e = apply_qos_rules(&["state".to_owned()], &mut [("state", &mut state)]).unwrap_err();
        assert!(e.to_string().contains("KEY=/topic/name"), "{e}");
        let e =
            apply_qos_rules(&["state=fast".to_owned()], &mut [("state", &mut state)]).unwrap_err();
        assert!(e.to_string().contains("\"fast\""), "{e}");
    }

    #[test]
    fn theta_is_labelled_in_si_units() {
        let p = Parameters {
            header: Header::unstamped(0),
            model_id: 1,
            normal: Some(ParameterSet {
                sample_time_ns: 0,
                residual: 0.0,
                terms: ModelTerms::KelvinVoigt {
                    k_n_per_m: 500.0,
                    b_ns_per_m: 60.0,
                },
            }),
            tangential: Some(ParameterSet {
                sample_time_ns: 0,
                residual: 0.0,
                terms: ModelTerms::SlidingMass {
                    mass_kg: 1.0,
                    k_ground_n_per_m: None,
                    b_ground_ns_per_m: 60.0,
                    k_contact_n_per_m: 500.0,
                    b_contact_ns_per_m: 60.0,
                    coulomb_n: Some(0.05),
                },
            }),
        };
        let m = theta_message(&p);
        let labels: Vec<&str> = m.layout.dim.iter().map(|d| d.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "normal.k",
                "normal.b",
                "tangential.m",
                "tangential.b1",
                "tangential.k2",
                "tangential.b2",
                "tangential.Fc"
            ]
        );
        assert_eq!(m.data, [500.0, 60.0, 1.0, 60.0, 500.0, 60.0, 0.05]);
        assert!(m.layout.dim.iter().all(|d| d.size == 1 && d.stride == 1));
        let none = theta_message(&Parameters {
            normal: None,
            tangential: None,
            ..p
        });
        assert!(none.data.is_empty() && none.layout.dim.is_empty());
    }
}

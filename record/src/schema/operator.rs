//! Recorded forms of the operator side: one [`OperatorTick`] per haptic-loop tick and every
//! telerobot measurement received ([`MeasurementRec`]).

use metrics::networked::{MeasurementSample, TickSample};
use protocol::telerobot_to_operator::Measurement;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// One haptic-loop tick (or one operator tick of an experiment).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct OperatorTick {
    /// The session whose node rendered it (0 in an experiment).
    pub session: u64,
    /// Tick number.
    pub index: u64,
    /// The command's sample time: when the tick read the device [ns, operator clock] (after a
    /// stall, later than the tick's deadline; = the deadline in an experiment, and in recordings
    /// made before commands were stamped when the device was read).
    pub sample_time_ns: i64,
    /// When the tick actually started [ns, operator clock] (= `sample_time_ns` in an experiment).
    pub started_ns: i64,
    /// The device's measured position \[m\], device coordinates (scripted and replayed devices:
    /// world coordinates).
    pub device_position_m: [f64; 3],
    /// The device's measured velocity \[m/s\].
    pub device_velocity_m_per_s: [f64; 3],
    /// The commanded position \[m\], world frame (clutch, scale and origin applied).
    pub command_position_m: [f64; 3],
    /// The commanded velocity \[m/s\].
    pub command_velocity_m_per_s: [f64; 3],
    /// The force the model rendered \[N\], before the safety layer.
    pub force_rendered_n: [f64; 3],
    /// The force written to the device \[N\], after the safety layer (= rendered in an
    /// experiment).
    pub force_device_n: [f64; 3],
    /// The node is in contact (its own detector on the received cloud, or the telerobot's
    /// state).
    pub in_contact: bool,
    /// The node renders a model.
    pub rendering: bool,
    /// The model rendered is the telerobot's reduced first model (massless), not the whole
    /// structure. Absent from recordings made before it: false.
    #[serde(default)]
    pub reduced: bool,
    /// The operator's local proxy \[m\] (`None` before a cloud).
    pub proxy_m: Option<[f64; 3]>,
    /// The safety rules acting this tick.
    pub safety: SafetyFlags,
    /// Device faults so far.
    pub device_faults: u64,
    /// Experiments: the shadow node's force (contact from the telerobot's state only) \[N\].
    pub remote_force_n: Option<[f64; 3]>,
    /// Experiments: the shadow node is in contact.
    pub remote_in_contact: Option<bool>,
    /// Experiments: the operator's contact deflection and mass velocity per tangent, after the
    /// tick (sliding mass only).
    pub tangential_state: [Option<[f64; 2]>; 2],
}

impl OperatorTick {
    /// What the report needs of it.
    pub fn sample(&self) -> TickSample {
        TickSample {
            index: self.index,
            sample_time_ns: Some(self.sample_time_ns),
            position_m: self.command_position_m,
            force_n: self.force_rendered_n,
            in_contact: self.in_contact,
            rendering: self.rendering,
            reduced: self.reduced,
        }
    }
}

/// The safety layer's rules acting at one tick, one bit each (`bits`), and how many act.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub struct SafetyFlags {
    /// One bit per rule, in the order of [`SafetyFlags::NAMES`].
    pub bits: u32,
}

impl SafetyFlags {
    /// The rules, by bit.
    pub const NAMES: [&'static str; 11] = [
        "non-finite force",
        "non-finite position",
        "non-finite velocity",
        "force saturated",
        "force rate limited",
        "workspace spring",
        "loop overrun",
        "stale parameters",
        "watchdog fading",
        "clutch",
        "passivity controller",
    ];

    /// The rules that started (`rose`) and stopped (`fell`) acting between `self` and `next`.
    pub fn edges(self, next: SafetyFlags) -> impl Iterator<Item = (&'static str, bool)> {
        let changed = self.bits ^ next.bits;
        Self::NAMES
            .iter()
            .enumerate()
            .filter(move |(i, _)| changed & (1 << i) != 0)
            .map(move |(i, name)| (*name, next.bits & (1 << i) != 0))
    }
}

/// A telerobot measurement as the operator received it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MeasurementRec {
    /// The session.
    pub session: u64,
    /// When it arrived [ns, operator clock].
    pub received_ns: i64,
    /// The clock-offset estimate when it was taken (telerobot − operator) \[ns\].
    pub offset_ns: Option<i64>,
    /// Its one-way trip: receipt − send time mapped with the offset \[ms\] (the link delay).
    pub latency_ms: Option<f64>,
    /// The datagram's sequence number.
    pub seq: u64,
    /// Sensor time [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// Send time [ns, telerobot clock].
    pub send_time_ns: i64,
    /// The command being executed [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// Measured tool position \[m\].
    pub position_m: [f64; 3],
    /// Measured tool velocity \[m/s\].
    pub velocity_m_per_s: [f64; 3],
    /// Force the environment exerts on the tool \[N\].
    pub force_on_tool_n: [f64; 3],
    /// The telerobot's tracked contact.
    pub in_contact: bool,
    /// Its estimators all pass every gate.
    pub estimator_stable: bool,
    /// `[Σ y², Σ (y − ψᵀθ̂)²]` of the tick while learning and confident.
    pub reconstruction: Option<[f64; 2]>,
}

impl MeasurementRec {
    /// From the wire message.
    pub fn new(session: u64, m: &Measurement, received_ns: i64, offset_ns: Option<i64>) -> Self {
        let latency_ms =
            offset_ns.map(|o| (received_ns - (m.header.send_time_ns - o)) as f64 / 1e6);
        MeasurementRec {
            session,
            received_ns,
            offset_ns,
            latency_ms,
            seq: m.header.seq,
            sample_time_ns: m.header.sample_time_ns,
            send_time_ns: m.header.send_time_ns,
            command_sample_time_ns: m.command_sample_time_ns,
            position_m: m.position_m,
            velocity_m_per_s: m.velocity_m_per_s,
            force_on_tool_n: m.force_on_tool_n,
            in_contact: m.in_contact,
            estimator_stable: m.estimator_stable,
            reconstruction: m.reconstruction,
        }
    }

    /// What the report needs of it.
    pub fn sample(&self) -> MeasurementSample {
        MeasurementSample {
            sample_time_ns: self.sample_time_ns,
            send_time_ns: self.send_time_ns,
            command_sample_time_ns: self.command_sample_time_ns,
            force_on_tool_n: self.force_on_tool_n,
            in_contact: self.in_contact,
            estimator_stable: self.estimator_stable,
            reconstruction: self.reconstruction,
            received_ns: self.received_ns,
            offset_ns: self.offset_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn safety_edges_name_the_rules_that_changed() {
        let before = SafetyFlags { bits: 0b1001 };
        let after = SafetyFlags { bits: 0b0011 };
        let edges: Vec<_> = before.edges(after).collect();
        assert_eq!(
            edges,
            [("non-finite position", true), ("force saturated", false)]
        );
        assert_eq!(before.edges(before).count(), 0);
    }
}

//! Playing a recording back: the replay robot bridge (`DESIGN.md` §12: a recorded telerobot
//! measurement stream behind the same `RobotBridge` trait as the simulated and real robots), and
//! the operator's device trajectory.

use std::sync::Arc;

use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::CloudIndex;
use node::{BridgeSample, RobotBridge, Target};

use crate::read::Recording;
use crate::schema::{Side, TelerobotTick};

/// A robot that plays a recorded measurement stream back, one recorded tick per step, whatever
/// the target (a recording cannot be steered). After the last tick it repeats the last
/// measurement; [`ReplayBridge::finished`] says so.
#[derive(Clone, Debug)]
pub struct ReplayBridge {
    ticks: Vec<TelerobotTick>,
    next: usize,
}

impl ReplayBridge {
    /// Plays `ticks` in order.
    pub fn new(ticks: Vec<TelerobotTick>) -> ReplayBridge {
        ReplayBridge { ticks, next: 0 }
    }

    /// The recorded tick the next step plays.
    pub fn peek(&self) -> Option<&TelerobotTick> {
        self.ticks.get(self.next)
    }

    /// Every recorded tick was played.
    pub fn finished(&self) -> bool {
        self.next >= self.ticks.len()
    }

    /// Recorded ticks.
    pub fn len(&self) -> usize {
        self.ticks.len()
    }

    /// No recorded tick.
    pub fn is_empty(&self) -> bool {
        self.ticks.is_empty()
    }
}

impl RobotBridge for ReplayBridge {
    fn tool_m(&self) -> Option<[f64; 3]> {
        Some(
            self.ticks
                .get(self.next.min(self.ticks.len().saturating_sub(1)))
                .map_or([0.0; 3], |t| t.tool_m),
        )
    }

    fn step(&mut self, _now_ns: i64, _target: Option<&Target>) -> BridgeSample {
        let Some(t) = self.ticks.get(self.next).or(self.ticks.last()) else {
            return BridgeSample::default();
        };
        self.next = (self.next + 1).min(self.ticks.len());
        BridgeSample {
            measured: t.sample(),
            tool_m: t.tool_m,
            object_slide_m: t.object_slide_m,
            // Replayed as the simulator read it: in the tick.
            reading: node::Reading::ThisTick,
        }
    }
}

/// The telerobot's camera frames of a recording, indexed, by capture time: what the replayed
/// node installs at the tick the live one did. Frames that cannot be indexed are left out.
pub fn telerobot_clouds(rec: &Recording) -> Vec<(i64, Arc<CloudIndex>)> {
    rec.clouds
        .iter()
        .filter(|(side, _)| *side == Side::Telerobot)
        .filter_map(|(_, c)| {
            let frame = CloudFrame::new(c.points.to_vec(), c.timestamp_ns, Pose::default()).ok()?;
            Some((c.timestamp_ns, Arc::new(CloudIndex::build(&frame).ok()?)))
        })
        .collect()
}

/// One sample of the operator's device: time since tick 0 \[s\], position \[m\], velocity
/// \[m/s\].
pub type DeviceSample = (f64, [f64; 3], [f64; 3]);

/// The operator's device trajectory of a recording: the measured device position and velocity
/// of every recorded haptic tick, timed from tick 0.
pub fn device_trajectory(rec: &Recording) -> Vec<DeviceSample> {
    let start = rec
        .run(Side::Operator)
        .map(|r| r.start_ns)
        .or(rec.operator_ticks.first().map(|t| t.sample_time_ns))
        .unwrap_or(0);
    rec.operator_ticks
        .iter()
        .map(|t| {
            (
                // Widened: a damaged file's extreme times must not overflow (the replay device
                // then refuses the times as out of order or not finite).
                (i128::from(t.sample_time_ns) - i128::from(start)) as f64 * 1e-9,
                t.device_position_m,
                t.device_velocity_m_per_s,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schema::OperatorTick;

    /// Suspected by the fuzz campaign: extreme tick times in a damaged file overflowed the
    /// subtraction (a panic with overflow checks on, a wrong time without).
    #[test]
    fn extreme_tick_times_give_finite_far_times_not_an_overflow() {
        let tick = |t| OperatorTick {
            sample_time_ns: t,
            ..OperatorTick::default()
        };
        let rec = Recording {
            operator_ticks: vec![tick(i64::MIN), tick(i64::MAX)],
            ..Recording::default()
        };
        let samples = device_trajectory(&rec);
        assert_eq!(samples[0].0, 0.0);
        assert!(
            (samples[1].0 - u64::MAX as f64 * 1e-9).abs() < 1e3,
            "{}",
            samples[1].0
        );
    }
}

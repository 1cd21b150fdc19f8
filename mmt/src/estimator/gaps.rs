//! Samples that do not come one sample period apart: a robot's state stream over best-effort DDS
//! loses about 1 % of its samples, one to a few in a row (the test arm over loopback: 990.9 Hz
//! effective, gaps to 11 ms). Each sample is taken at its own time, and the filters are stepped
//! over the periods with none on the input interpolated between the samples either side; the
//! RLS learns from the real samples only. Stepped once per sample instead, the filters
//! compressed time by a period at each lost sample, and the new-object detector reset the
//! covariance five times in 60 s at 1 % loss (`lab` test
//! `estimator::samples_lost_in_transport_are_not_a_new_object`). Samples whose positions
//! contradict their velocities ([`MOTION_TOLERANCE_M`]: a stop hidden in a gap, or a jump), or
//! that end a gap over which the speed changed enough for a stop to hide in it, are not learnt
//! from until the filters have settled ([`SETTLE_CUTOFF_PERIODS`]); a gap over which the speed
//! changed more than the straight fill follows mutes the new-object detector ([`GAP_MUTE_M`]).

use super::{AxisSample, Estimator, MAX_AXES, Phase};
use crate::filter::RegressorFilter;

/// Longest gap in the samples, in sample periods, that the filters are stepped over with the
/// input interpolated between the samples either side (a robot's state stream over best-effort
/// DDS loses about 1 % of its samples, one to a few in a row). A longer gap restarts the
/// filters at the next sample (a robot bridge stops estimating after 50 ms without a state).
pub const MAX_FILLED_PERIODS: u32 = 50;

/// How far \[m\] a sample may be from where the last one and the two measured velocities can put
/// it (between the lower and the higher velocity times the interval: any velocity moving
/// monotonically from one to the other) before the samples are taken to contradict a motion: over
/// a gap in the samples the robot stopped dead for want of commands held up on the same link as
/// its states (the ROS 2 test arm on a loaded machine), or the tool jumped between two samples
/// (the same arm catching up with its targets). The filters, stepped over a gap in a straight
/// line or across a jump, then carry a motion that never happened. 0.1 mm: a stop of 2 ms at 5
/// cm/s; an arm's position and velocity noise is micrometres, and gaps of 4–13 ms over the exp-1
/// motion never came near it (`lab` test below): a smooth motion whose velocity peaks inside a
/// gap leaves the bounds by about jerk·Δt³/12. The same tolerance bounds how far a velocity
/// moving between the two measured ones may take the motion off the straight fill over a gap
/// (`|Δv|·Δt/4`): 1–3 of about 70 such gaps of 6–13 ms at the exp-1 motion's peak acceleration
/// pass it.
pub const MOTION_TOLERANCE_M: f64 = 1e-4;

/// After samples that contradict a motion, learning waits this many periods of the filter's
/// cut-off (0.6 s at 5 Hz) and the new-object detector is muted
/// ([`super::Estimator::mute_new_object_detector`]): the filtered regressors carry the
/// difference between the fill and the real motion for that long (an 8 ms stop at the exp-1
/// object's speeds: 0.5 N of filtered force 150 ms after, 0.02 N 400 ms after). Learning from
/// them biased the mass by +28–80 % and the contact stiffness by +61–78 % (`lab` test
/// `estimator::a_robot_stopped_while_its_states_were_lost_is_not_a_new_object`).
pub const SETTLE_CUTOFF_PERIODS: f64 = 3.0;

/// How far \[m\] a gap's straight fill may be from a motion that changed speed at a constant
/// acceleration between the two measured velocities (`|Δv|·Δt/8`) before the new-object detector
/// is muted ([`super::Estimator::mute_new_object_detector`]): 10 µm, e.g. 10 mm/s of change
/// over an 8 ms gap. The force over such a gap is not the straight line the fill puts there
/// either (the object answers a change of speed within its own time constant), and the
/// prediction error that follows looked like a new object: the ROS 2 test arm, stopping at 10
/// m/s² when its targets stall beyond its 10 ms extrapolation, its states over the stall lost
/// on the same link, reset the model 3–8 times a minute (`lab` test
/// `estimator::an_arm_that_stops_for_want_of_targets_while_its_states_are_lost_is_not_a_new_object`).
/// Learning goes on: only the detector is muted.
pub const GAP_MUTE_M: f64 = 1e-5;

/// The last sample, for covering the next gap and checking the motion across it.
#[derive(Clone, Copy, Debug)]
pub(super) struct LastSample {
    /// Its time \[s\].
    pub(super) t_s: f64,
    /// Each axis's tared input `(x, F)`.
    pub(super) inputs: [(f64, f64); MAX_AXES],
    /// Each axis's measured velocity \[m/s\].
    pub(super) velocities: [f64; MAX_AXES],
}

/// How a sample's motion since the last stands against the fill ([`Estimator::across`]).
enum Across {
    /// The fill holds.
    Fits,
    /// The fill misses a change of speed: the new-object detector is muted.
    Mute,
    /// A stop or a jump may be hidden: learning waits the filters out.
    Settle,
}

impl Estimator {
    /// What the gap before the sample at `now_s` (`missed` periods) asks: too long to fill, the
    /// filters restart; while learning, a motion the samples contradict is waited out
    /// ([`Self::settle`]), and a change of speed the fill does not follow mutes the detector.
    pub(super) fn check_gap(&mut self, now_s: f64, samples: &[AxisSample], missed: u32) {
        if missed > MAX_FILLED_PERIODS {
            self.restart_after_gap(now_s);
            return;
        }
        if self.phase != Phase::Learning {
            return;
        }
        match self.across(now_s, samples, missed) {
            Across::Fits => {}
            Across::Mute => {
                self.stats.gap_mutes += 1;
                self.mute_new_object_detector();
            }
            Across::Settle => self.settle(now_s),
        }
    }

    /// Whole sample periods between the last sample and `now_s` with no sample (0 for the
    /// first sample, for one a period after the last, and for a repeated or earlier time).
    pub(super) fn missed_periods(&self, now_s: f64) -> u32 {
        let Some(last) = &self.last_sample else {
            return 0;
        };
        let periods = ((now_s - last.t_s) / self.config.filter.svf.sample_period_s).round();
        if periods.is_finite() && periods > 1.0 {
            periods.min(f64::from(u32::MAX)) as u32 - 1
        } else {
            0
        }
    }

    /// How the motion from the last sample to this one (at `now_s`, `missed` periods between)
    /// stands against the fill, on the worst axis:
    /// - [`Across::Settle`] when the sample is further than [`MOTION_TOLERANCE_M`] from where the
    ///   last position and the two velocities can put it (with the velocity moving monotonically
    ///   from one to the other, the displacement lies between the lower and the higher velocity
    ///   times the interval: outside, the robot stopped or jumped in between), or, over a gap,
    ///   when the two velocities are so far apart that a velocity moving between them may leave
    ///   the straight fill by more than that tolerance (`|Δv|·Δt/4`, a step at mid-gap: a stop may
    ///   hide there; the test arm, stopping for 1–30 ms of a 12–42 ms gap, biased the mass by up
    ///   to −37 % when learnt through);
    /// - [`Across::Mute`] when, over a gap, a constant acceleration between the two velocities
    ///   leaves the fill by more than [`GAP_MUTE_M`] (`|Δv|·Δt/8`);
    /// - [`Across::Fits`] otherwise.
    fn across(&self, now_s: f64, samples: &[AxisSample], missed: u32) -> Across {
        let Some(last) = &self.last_sample else {
            return Across::Fits;
        };
        let dt = now_s - last.t_s;
        let mut verdict = Across::Fits;
        for ((s, (x0, _)), v0) in samples.iter().zip(&last.inputs).zip(&last.velocities) {
            let (lo, hi) = (v0.min(s.velocity_m_per_s), v0.max(s.velocity_m_per_s));
            let moved = s.position_m - x0;
            let within =
                moved >= lo * dt - MOTION_TOLERANCE_M && moved <= hi * dt + MOTION_TOLERANCE_M;
            let change = if missed > 0 { (hi - lo) * dt } else { 0.0 };
            if !within || change / 4.0 > MOTION_TOLERANCE_M {
                return Across::Settle;
            }
            if change / 8.0 > GAP_MUTE_M {
                verdict = Across::Mute;
            }
        }
        verdict
    }

    /// Keeps the sample at `now_s` (its tared inputs `(x, F)` and velocities) for the next gap
    /// and the next motion check.
    pub(super) fn remember(
        &mut self,
        now_s: f64,
        inputs: [(f64, f64); MAX_AXES],
        samples: &[AxisSample],
    ) {
        let mut velocities = [0.0; MAX_AXES];
        for (v, s) in velocities.iter_mut().zip(samples) {
            *v = s.velocity_m_per_s;
        }
        self.last_sample = Some(LastSample {
            t_s: now_s,
            inputs,
            velocities,
        });
    }

    /// The samples contradict a motion: the filters' regressors carry the difference for a few
    /// of their time constants; learning waits them out and the new-object detector is muted.
    fn settle(&mut self, now_s: f64) {
        self.stats.motion_settles += 1;
        self.settle_until_s = now_s + SETTLE_CUTOFF_PERIODS / self.config.filter.svf.cutoff_hz;
        self.mute_new_object_detector();
    }

    /// A gap too long to fill: the filters restart at this sample (in [`Self::step`]) and, in
    /// contact, the onset guard runs again so that their transient is not learnt; the detector
    /// is muted again when the guard ends.
    fn restart_after_gap(&mut self, now_s: f64) {
        self.stats.gap_restarts += 1;
        if self.phase != Phase::Free {
            self.phase = Phase::Guard;
            self.contact_since_s = now_s;
        }
    }

    /// Steps axis `i`'s filter to sample `s` (its tared force `f`), over the `missed` periods
    /// before it, and keeps the regression.
    pub(super) fn filter_axis(&mut self, i: usize, s: &AxisSample, f: f64, missed: u32) {
        let first = !self.tared && self.phase == Phase::Free;
        let restart = missed > MAX_FILLED_PERIODS;
        if first || restart {
            // First sample, or after a long gap: start the filter in the steady state instead of
            // ringing from 0 or from where the gap began.
            self.filters[i].reset_steady(s.position_m, s.velocity_m_per_s, f);
        }
        let dt = self.config.filter.svf.sample_period_s;
        let elapsed = dt * f64::from(missed.min(MAX_FILLED_PERIODS) + 1);
        let filter = &self.filters[i];
        let shape = self
            .observed
            .and_then(|o| self.observers[i].step(&o, f, elapsed))
            .unwrap_or_else(|| filter.smooth_sign(s.velocity_m_per_s));
        if let Some(last) = self.last_sample.filter(|_| !restart) {
            fill(
                &mut self.filters[i],
                last.inputs[i],
                (s.position_m, f),
                shape,
                missed,
            );
        }
        self.regressions[i] = self.filters[i]
            .step_with_shape(s.position_m, f, shape)
            .with_constant(i);
    }
}

/// Steps `filter` over the `missed` sample periods before a sample at `to` = `(x, F)`, the last
/// one having been at `from`, with the input interpolated linearly between them and the
/// friction shape held at the new sample's.
fn fill(filter: &mut RegressorFilter, from: (f64, f64), to: (f64, f64), shape: f64, missed: u32) {
    let steps = f64::from(missed + 1);
    for j in 1..=missed {
        let a = f64::from(j) / steps;
        filter.step_with_shape(
            from.0 + a * (to.0 - from.0),
            from.1 + a * (to.1 - from.1),
            shape,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EstimatorConfig, MAX_FILLED_PERIODS};
    use super::*;
    use crate::model::Structure;

    fn sample(t: f64) -> AxisSample {
        // Linear in time: the interpolation over a gap is then the very input that was lost.
        AxisSample {
            position_m: 0.01 + 0.02 * t,
            velocity_m_per_s: 0.02,
            force_n: 0.5 + 1.5 * t,
        }
    }

    fn estimator() -> Estimator {
        Estimator::new(EstimatorConfig::new(Structure::KelvinVoigt, 1)).unwrap()
    }

    /// Against the exact answer: over a gap in a linear input, the filters end where every
    /// sample would have put them; the gap is counted; a gap too long restarts them.
    #[test]
    fn a_gap_in_a_linear_input_leaves_the_filters_where_every_sample_would() {
        let (mut every, mut gappy) = (estimator(), estimator());
        for k in 0..200 {
            let t = k as f64 * 1e-3;
            every.step(t, &[sample(t)], true);
            if !(100..104).contains(&k) {
                gappy.step(t, &[sample(t)], true);
            }
        }
        let (a, b) = (every.regressions()[0], gappy.regressions()[0]);
        for (x, y) in a.psi.iter().zip(&b.psi).chain([(&a.y, &b.y)]) {
            assert!((x - y).abs() <= 1e-12 * x.abs().max(1e-6), "{a:?}\n{b:?}");
        }
        assert_eq!(gappy.stats().filled_samples, 4);
        assert_eq!(gappy.stats().gap_restarts, 0);
        let t = 0.2 + f64::from(MAX_FILLED_PERIODS + 2) * 1e-3;
        gappy.step(t, &[sample(t)], true);
        assert_eq!(gappy.stats().gap_restarts, 1);
        assert_eq!(gappy.phase(), Phase::Guard);
        // Repeated and earlier times are not gaps.
        assert_eq!(gappy.missed_periods(t), 0);
        assert_eq!(gappy.missed_periods(t - 1.0), 0);
    }
}

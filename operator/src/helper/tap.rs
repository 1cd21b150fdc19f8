//! The helper's tap: every tick and measurement sample, and each new model id, handed to a
//! consumer as the run goes (the soak's per-minute figures), one batch per helper round.

use std::sync::Arc;

use metrics::networked::{MeasurementSample, TickSample};

/// A consumer of every tick and measurement sample as the run goes (the soak's per-minute
/// figures), and how many of them the run's own recording keeps (its report covers those).
#[derive(Clone, Debug)]
pub struct Tap {
    /// Where the batches go: one per helper round that took something, after the run's
    /// [`Tapped::Start`].
    pub to: std::sync::mpsc::Sender<Tapped>,
    /// Most ticks (and measurements) the run's recording keeps.
    pub keep_ticks: usize,
}

/// What a [`Tap`] receives.
#[derive(Clone, Debug)]
pub enum Tapped {
    /// The haptic loop's schedule and timing counters, before its first tick.
    Start {
        /// Tick 0's time [ns].
        start_ns: i64,
        /// Tick period \[ns\].
        period_ns: i64,
        /// The loop's timing counters (overruns, skipped ticks), live.
        timing: Arc<rt::LoopTiming>,
    },
    /// The samples one helper round took.
    Batch {
        /// Tick samples, in tick order.
        ticks: Vec<TickSample>,
        /// Measurements in arrival order.
        measurements: Vec<MeasurementSample>,
        /// `(tick, model id)` of each tick that took parameters of a model id other than the
        /// last one's: the telerobot started a new model (a first contact, or its estimator
        /// reset after a new object).
        models: Vec<(u64, u32)>,
    },
}

/// The tap and what the current round has for it.
#[derive(Debug)]
pub(super) struct TapRound {
    to: std::sync::mpsc::Sender<Tapped>,
    ticks: Vec<TickSample>,
    measurements: Vec<MeasurementSample>,
    models: Vec<(u64, u32)>,
    /// The model id of the last parameters taken.
    model: Option<u32>,
}

impl TapRound {
    pub(super) fn new(tap: Tap) -> TapRound {
        TapRound {
            to: tap.to,
            ticks: Vec::new(),
            measurements: Vec::new(),
            models: Vec::new(),
            model: None,
        }
    }

    /// A tick's sample, and the model id of the parameters it took, if it took any.
    pub(super) fn tick(&mut self, sample: TickSample, model_id: Option<u32>) {
        if let Some(id) = model_id
            && self.model != Some(id)
        {
            self.model = Some(id);
            self.models.push((sample.index, id));
        }
        self.ticks.push(sample);
    }

    /// A measurement's sample.
    pub(super) fn measurement(&mut self, sample: MeasurementSample) {
        self.measurements.push(sample);
    }

    /// Sends the round's batch, if it took anything; false when the consumer is gone.
    pub(super) fn send(&mut self) -> bool {
        if self.ticks.is_empty() && self.measurements.is_empty() {
            return true;
        }
        let batch = Tapped::Batch {
            ticks: std::mem::take(&mut self.ticks),
            measurements: std::mem::take(&mut self.measurements),
            models: std::mem::take(&mut self.models),
        };
        self.to.send(batch).is_ok()
    }
}

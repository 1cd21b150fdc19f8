//! What a run records: one row per operator tick, measured and rendered force aligned by the
//! command's sample time (its CSV form: `csv`).

use node::operator::OperatorOutput;

/// The time series of a run, indexed by operator tick (= command sample time / period).
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// Tick period [ns].
    pub period_ns: i64,
    /// The scene's second tangent: the thesis's "y" axis, for plots.
    pub axis: [f64; 3],
    /// The scene's surface normal, for plots.
    pub normal: [f64; 3],
    /// Device position [m].
    pub position: Vec<[f64; 3]>,
    /// Force rendered by the operator node [N].
    pub rendered: Vec<[f64; 3]>,
    /// Force rendered by the shadow node (remote contact only) [N].
    pub rendered_remote: Vec<[f64; 3]>,
    /// Operator in contact (local detection).
    pub contact_local: Vec<bool>,
    /// Shadow node in contact (the telerobot's state).
    pub contact_remote: Vec<bool>,
    /// The operator renders a model.
    pub rendering: Vec<bool>,
    /// The model the operator renders is the telerobot's reduced first model (massless), not
    /// the whole structure.
    pub reduced: Vec<bool>,
    /// Operator's contact deflection and mass velocity per tangent (sliding mass only).
    pub operator_state: Vec<[Option<(f64, f64)>; 2]>,
    /// Force on the tool the telerobot's sensor measured while executing the command of this
    /// tick [N]: noise and bias included, as on a real robot (the reference of every error).
    pub measured: Vec<Option<[f64; 3]>>,
    /// The true force of the same tick [N], where a simulator knows it (else all `None`).
    pub true_force: Vec<Option<[f64; 3]>>,
    /// True contact while executing the command of this tick.
    pub contact_true: Vec<Option<bool>>,
    /// True contact deflection and mass velocity per tangent, same alignment.
    pub true_state: Vec<Option<[(f64, f64); 2]>>,
    /// Telerobot's parameters pass every gate (by telerobot tick).
    pub stable: Vec<bool>,
    /// Σ y² and Σ (y − ψᵀθ̂)² of the tangential estimator while confident.
    pub reconstruction: (f64, f64),
}

impl Series {
    /// An empty series for `n` ticks of `period_ns`; `axis` is the tangent plotted as the
    /// thesis's "y".
    pub fn with_capacity(n: usize, axis: [f64; 3], normal: [f64; 3], period_ns: i64) -> Self {
        Series {
            period_ns,
            axis,
            normal,
            position: Vec::with_capacity(n),
            rendered: Vec::with_capacity(n),
            rendered_remote: Vec::with_capacity(n),
            contact_local: Vec::with_capacity(n),
            contact_remote: Vec::with_capacity(n),
            rendering: Vec::with_capacity(n),
            reduced: Vec::with_capacity(n),
            operator_state: Vec::with_capacity(n),
            measured: vec![None; n],
            true_force: vec![None; n],
            contact_true: vec![None; n],
            true_state: vec![None; n],
            stable: Vec::with_capacity(n),
            reconstruction: (0.0, 0.0),
        }
    }

    /// Records an operator tick (and the shadow node's, when there is one: pass the same output
    /// twice otherwise).
    pub fn push_operator(
        &mut self,
        position: [f64; 3],
        out: &OperatorOutput,
        remote: &OperatorOutput,
    ) {
        self.position.push(position);
        self.rendered.push(out.force_n);
        self.rendered_remote.push(remote.force_n);
        self.contact_local.push(out.in_contact);
        self.contact_remote.push(remote.in_contact);
        self.rendering.push(out.rendering);
        self.reduced.push(out.rendering && out.reduced);
    }

    /// The first tick the operator renders a whole model (not the reduced first model): where
    /// the figures "after stable" start.
    pub fn whole_model_start(&self) -> Option<usize> {
        (0..self.rendering.len())
            .position(|i| self.rendering[i] && !self.reduced.get(i).copied().unwrap_or(false))
    }

    /// Records what the telerobot measured while executing the command sampled at
    /// `command_time_ns` (the first report for a command counts), its stability and the
    /// reconstruction sums of its tick, and the operator's tangential state of the same tick.
    #[allow(clippy::too_many_arguments)]
    pub fn push_telerobot(
        &mut self,
        command_time_ns: i64,
        force: [f64; 3],
        in_contact: bool,
        stable: bool,
        reconstruction: Option<(f64, f64)>,
        true_state: [(f64, f64); 2],
        operator_state: [Option<(f64, f64)>; 2],
    ) {
        self.stable.push(stable);
        self.operator_state.push(operator_state);
        if let Some((y2, e2)) = reconstruction {
            self.reconstruction.0 += y2;
            self.reconstruction.1 += e2;
        }
        let idx = command_time_ns / self.period_ns;
        if command_time_ns < 0 || idx as usize >= self.measured.len() {
            return;
        }
        let i = idx as usize;
        if self.measured[i].is_none() {
            self.measured[i] = Some(force);
            self.contact_true[i] = Some(in_contact);
            self.true_state[i] = Some(true_state);
        }
    }

    /// Records the true force while executing the command sampled at `command_time_ns` (the
    /// first for a command counts): simulation only.
    pub fn push_true_force(&mut self, command_time_ns: i64, force: [f64; 3]) {
        let idx = command_time_ns / self.period_ns;
        if command_time_ns < 0 || idx as usize >= self.true_force.len() {
            return;
        }
        self.true_force[idx as usize].get_or_insert(force);
    }

    /// Tick period [s].
    pub fn dt_s(&self) -> f64 {
        self.period_ns as f64 * 1e-9
    }

    /// Number of operator ticks.
    pub fn len(&self) -> usize {
        self.rendered.len()
    }

    /// No ticks.
    pub fn is_empty(&self) -> bool {
        self.rendered.is_empty()
    }
}

//! Structure from the data (issue 12, item 5): which of the structures inside a scene's the
//! estimator's own fit supports, by the Bayesian information criterion.
//!
//! Holding a structure's missing coefficients `O` at 0 and refitting the others on the same
//! data costs `ΔJ = θ̂_Oᵀ P_OO⁻¹ θ̂_O` of forgotten squared prediction error
//! ([`Information::omission_cost`]). With σ² the output noise's variance per independent sample,
//! `ΔJ/σ²` is twice the log-likelihood the structure gives up against the whole one, so
//!
//! ```text
//! BIC(S) = ΔJ_S / σ² + p_S · ln n
//! ```
//!
//! with `p_S` the structure's coefficients and `n` the independent samples behind the estimate:
//! a term is kept when it explains more than `ln n` per coefficient of what the noise cannot.
//! The regression is filtered, so consecutive samples are not independent: the caller counts
//! the forgotten samples over the filter's correlation length, and `σ²` is the error power
//! times that length ([`Information::noise_variance`]), consistently.
//!
//! The statistical criterion keeps what is significant, which is not always what can be felt:
//! a structure whose missing terms add less than [`NEGLIGIBLE`] of the RMS force is enough
//! whatever the criterion says ([`Selection::choice`]).
//!
//! The candidates are the scene's structure and those it contains: a sliding mass with or
//! without its ground spring and with or without friction. A Kelvin–Voigt contact is the
//! normal axis's structure and has nothing inside it. The tangential renderer is chosen by the
//! scene at the session's start, so a Kelvin–Voigt contact is not a candidate on a sliding
//! axis.

use super::backsolve::Information;
use super::{Columns, Structure, Theta};

/// Most candidates: the four sliding-mass structures.
pub const MAX_CANDIDATES: usize = 4;

/// A structure whose missing terms cost less than this RMS prediction error, relative to the
/// RMS force, is enough whatever the criterion says: 1 % of the force cannot be felt (the
/// rendered force's error after stable is 2.6 % on the exp-1 object). The statistical
/// criterion alone keeps what is significant, not what matters: on `mmt benchmark --seed 1`
/// (exp-1 motion) leaving out a free object's ground spring cost 0.1–0.6 % yet 2–8 noise units
/// against a penalty of 5 (it switched 26 times in a run), while leaving it out of a
/// spring-mounted object cost 31–57 %; 0.03 N of friction cost 0.2 %, 1 N 3–23 %.
pub const NEGLIGIBLE: f64 = 0.01;

/// Hysteresis: a smaller structure in use stays while its cost is below `RELAX × NEGLIGIBLE` or
/// its criterion within [`SWITCH_MARGIN`] of the best; a near tie does not switch the published
/// set's terms back and forth.
pub const RELAX: f64 = 2.0;

/// Independent samples below which the estimator selects nothing (the whole structure stays):
/// 1 s of learning on two axes filtered at 5 Hz (`n = t · 2 f_c · axes`). Earlier, a term's cost
/// is as noisy as the estimate. A forgetting memory too short ever to reach it lowers it to
/// 90 % of what the memory holds (`Estimator`'s selection).
pub const MIN_SAMPLES: f64 = 20.0;

/// A structure is taken only after being chosen this long in a row [s]: the published set's
/// terms change at most once per this time.
pub const DWELL_S: f64 = 0.5;

/// A criterion difference that is "positive evidence" on the Kass–Raftery scale.
pub const SWITCH_MARGIN: f64 = 2.0;

/// One candidate structure's score.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// The structure.
    pub structure: Structure,
    /// `ΔJ/σ²`: the fit it gives up against the whole structure, in noise units.
    pub misfit: f64,
    /// `√(ΔJ / Σλᵏyₖ²)`: the RMS prediction error it adds, relative to the RMS force [1].
    pub relative: f64,
    /// `BIC`: the misfit plus `p · ln n`. Lower is better.
    pub criterion: f64,
}

impl Candidate {
    fn terms(&self) -> usize {
        self.structure.columns().len()
    }
}

/// The candidates' scores.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Selection {
    candidates: [Option<Candidate>; MAX_CANDIDATES],
    /// The independent samples `n` the penalty used.
    pub samples: f64,
}

impl Selection {
    /// The scored candidates, the whole structure first.
    pub fn candidates(&self) -> impl Iterator<Item = &Candidate> {
        self.candidates.iter().flatten()
    }

    /// The candidate with the lowest criterion (the smaller structure on a tie).
    pub fn best(&self) -> Candidate {
        let mut best = self.candidates[0].expect("a selection has the whole structure");
        for c in self.candidates() {
            if c.criterion < best.criterion
                || (c.criterion == best.criterion && c.terms() < best.terms())
            {
                best = *c;
            }
        }
        best
    }

    /// The smallest structure that is enough — its missing terms cannot be felt (their cost is
    /// below [`NEGLIGIBLE`]) or the criterion prefers it ([`Self::best`]) — the lower criterion
    /// among equally small ones.
    pub fn choice(&self) -> Candidate {
        let best = self.best();
        let mut choice = best;
        for c in self.candidates().filter(|c| c.relative <= NEGLIGIBLE) {
            let smaller = c.terms() < choice.terms();
            if smaller || (c.terms() == choice.terms() && c.criterion < choice.criterion) {
                choice = *c;
            }
        }
        choice
    }

    /// The score of `structure`, if it is a candidate.
    pub fn of(&self, structure: Structure) -> Option<Candidate> {
        self.candidates()
            .find(|c| c.structure == structure)
            .copied()
    }

    /// The structure to use next when `current` is in use: [`Self::choice`], except that a
    /// smaller `current` is kept while it is still enough with hysteresis ([`RELAX`],
    /// [`SWITCH_MARGIN`]).
    pub fn next(&self, current: Structure) -> Structure {
        let choice = self.choice();
        match self.of(current) {
            Some(c)
                if choice.terms() > c.terms()
                    && (c.relative <= RELAX * NEGLIGIBLE
                        || c.criterion - self.best().criterion < SWITCH_MARGIN) =>
            {
                current
            }
            _ => choice.structure,
        }
    }
}

/// The structures inside `whole`, `whole` first.
pub fn candidates(whole: Structure) -> impl Iterator<Item = Structure> {
    let mut out = [None; MAX_CANDIDATES];
    out[0] = Some(whole);
    if let Structure::SlidingMass {
        ground_spring,
        friction,
    } = whole
    {
        // From the most terms down, so `whole` (the most) is the first of them.
        let inside = [(true, true), (true, false), (false, true), (false, false)]
            .into_iter()
            .filter(|&(g, f)| (!g || ground_spring) && (!f || friction));
        for (slot, (ground_spring, friction)) in out.iter_mut().zip(inside) {
            *slot = Some(Structure::SlidingMass {
                ground_spring,
                friction,
            });
        }
    }
    out.into_iter().flatten()
}

/// Scores every structure inside `whole` ([`candidates`]) on the estimate `theta` of the whole
/// structure, its `information` and `samples` independent samples. `None` when the noise
/// variance is not positive (nothing to measure a misfit against), `samples` is below 2 (no
/// penalty: `ln n` < 0.7), or an
/// omission cost cannot be computed (a number is not finite, the covariance is not positive).
pub fn select(
    whole: Structure,
    theta: &Theta,
    information: &Information,
    samples: f64,
) -> Option<Selection> {
    let sigma2 = information.noise_variance();
    if !(sigma2 > 0.0 && sigma2.is_finite() && samples >= 2.0 && samples.is_finite()) {
        return None;
    }
    let penalty = samples.ln();
    let energy = information.output_energy();
    let all = whole.columns();
    let mut selection = Selection {
        candidates: [None; MAX_CANDIDATES],
        samples,
    };
    for (slot, structure) in selection.candidates.iter_mut().zip(candidates(whole)) {
        let kept = structure.columns();
        let omitted =
            all.indices().fold(
                Columns::NONE,
                |o, i| {
                    if kept.contains(i) { o } else { o.with(i) }
                },
            );
        let cost = information.omission_cost(&theta.0, omitted)?;
        let misfit = cost / sigma2;
        *slot = Some(Candidate {
            structure,
            misfit,
            relative: (cost / energy).sqrt(),
            criterion: misfit + kept.len() as f64 * penalty,
        });
    }
    Some(selection)
}

#[cfg(test)]
mod tests;

//! The state-variable filter (SVF): one low-pass `1/Λ(s)` whose states are the filtered signal
//! and its first `n − 1` derivatives (P. C. Young, "Parameter estimation for continuous-time
//! models — a survey", Automatica 17(1):23–39, 1981; Garnier & Wang, *Identification of
//! Continuous-time Models from Sampled Data*, 2008). Numerics notes §7.
//!
//! # Realisation
//!
//! `Λ(s) = B_n(s/ω_c)` is the n-th order Butterworth polynomial, `B_n(p) = Σ α_k p^k` with
//! `α_0 = α_n = 1`, so the DC gain is exactly 1. The controllable canonical form with the plain
//! states `z_k = u_f^(k)` has entries up to `ω_c^n` (6e10 at 6th order, 10 Hz). With the
//! **time-scaled** states `z̃_k = z_k / ω_c^k` it becomes
//!
//! ```text
//! d z̃_k/dt     = ω_c z̃_{k+1}                         (k < n − 1)
//! d z̃_{n−1}/dt = ω_c (u − Σ_{k<n} α_k z̃_k)
//! ```
//!
//! i.e. `Ã = ω_c·C(α)`, `b̃ = ω_c·e_{n−1}` with the companion matrix `C` of the normalised
//! Butterworth polynomial: every entry is `O(ω_c)` and the states have comparable size.
//!
//! # Discretisation and hold
//!
//! Discretised exactly once at construction with a **first-order hold** on the input
//! ([`Foh`]): the input is taken as linear between consecutive samples, so
//! `z̃_{k+1} = Φ z̃_k + (Γ_hold − Γ_ramp) u_k + Γ_ramp u_{k+1}`. Why not ZOH: a zero-order hold
//! delays the input by half a sample, a phase error of `ωh/2` (3e-3 rad at 1 Hz, 1 kHz) in every
//! state; the FOH error is `O((ωh)²)` (below 1e-4 relative at 5 Hz). For the regression itself
//! the hold hardly matters (all channels share it), but the derivative states are meant to be
//! the derivatives of the filtered measured signal, and the FOH state at tick `k` is consistent
//! with the sample at tick `k`. Cost: one extra multiply-add per state. The test
//! `zoh_lags_half_a_sample_foh_does_not` shows the difference.

use nalgebra::DMatrix;

use super::expm::Foh;
use super::{FilterError, MAX_ORDER, MIN_ORDER};

/// Configuration of a state-variable filter.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SvfConfig {
    /// Butterworth cut-off `f_c` [Hz]. Default 10 Hz (thesis §D.2). A scene parameter: about
    /// 7 Hz is better for the exp-1 scene (`DESIGN.md` §11.2; 5–7 Hz best, 20 Hz fails). Must be
    /// finite, > 0 and at most a tenth of the sample rate, so the derivative states do not alias.
    pub cutoff_hz: f64,
    /// Order `n` of `Λ(s)`. Default 6. Must be in `4..=8`: the x‴ state rolls off as
    /// `s³/Λ(s)`, i.e. at `(n − 3)·20` dB/decade, so `n ≥ 4`.
    pub order: usize,
    /// Sample period `h` [s]. Default 1 ms (the telerobot's 1 kHz loop).
    pub sample_period_s: f64,
}

impl Default for SvfConfig {
    fn default() -> Self {
        SvfConfig {
            cutoff_hz: 10.0,
            order: 6,
            sample_period_s: 1e-3,
        }
    }
}

impl SvfConfig {
    /// Checks every field; the error names the field, the value and the allowed range.
    pub fn validate(&self) -> Result<(), FilterError> {
        if !(MIN_ORDER..=MAX_ORDER).contains(&self.order) {
            return Err(FilterError::Order { order: self.order });
        }
        if !(self.sample_period_s.is_finite() && self.sample_period_s > 0.0) {
            return Err(FilterError::SamplePeriod {
                period_s: self.sample_period_s,
            });
        }
        let max_hz = 0.1 / self.sample_period_s;
        if !(self.cutoff_hz.is_finite() && self.cutoff_hz > 0.0 && self.cutoff_hz <= max_hz) {
            return Err(FilterError::Cutoff {
                cutoff_hz: self.cutoff_hz,
                max_hz,
            });
        }
        Ok(())
    }

    /// `ω_c = 2π f_c` [rad/s].
    pub fn cutoff_rad_s(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.cutoff_hz
    }
}

/// Coefficients `[α_0, …, α_n]` of the normalised n-th order Butterworth polynomial
/// `B_n(p) = Π_k (p² − 2 cos((2k + n − 1)π/(2n)) p + 1)` (times `(p + 1)` for odd `n`),
/// `k = 1 … ⌊n/2⌋`. `α_0 = α_n = 1`. Entries past `n` are zero.
pub fn butterworth_polynomial(order: usize) -> [f64; MAX_ORDER + 1] {
    let mut c = [0.0; MAX_ORDER + 1];
    c[0] = 1.0;
    let mut deg = 0;
    let multiply = |c: &mut [f64; MAX_ORDER + 1], deg: &mut usize, factor: &[f64]| {
        let mut out = [0.0; MAX_ORDER + 1];
        for (i, ci) in c.iter().enumerate().take(*deg + 1) {
            for (j, fj) in factor.iter().enumerate() {
                if i + j <= MAX_ORDER {
                    out[i + j] += ci * fj;
                }
            }
        }
        *c = out;
        *deg += factor.len() - 1;
    };
    if order % 2 == 1 {
        multiply(&mut c, &mut deg, &[1.0, 1.0]);
    }
    let n = order as f64;
    for k in 1..=order / 2 {
        let angle = (2.0 * k as f64 + n - 1.0) * std::f64::consts::PI / (2.0 * n);
        multiply(&mut c, &mut deg, &[1.0, -2.0 * angle.cos(), 1.0]);
    }
    c
}

/// The discretised filter, shared by every channel that must see the same `Λ(s)`.
/// Fixed-size storage: stepping never allocates.
#[derive(Clone, Debug, PartialEq)]
pub struct Discretisation {
    order: usize,
    /// `Φ` of the time-scaled states.
    phi: [[f64; MAX_ORDER]; MAX_ORDER],
    /// `Γ_hold − Γ_ramp`: weight of the previous input sample.
    g_prev: [f64; MAX_ORDER],
    /// `Γ_ramp`: weight of the current input sample.
    g_now: [f64; MAX_ORDER],
    /// `ω_c^k`: time-scaled state `k` → k-th derivative.
    unscale: [f64; MAX_ORDER],
    config: SvfConfig,
}

impl Discretisation {
    /// Builds and discretises the filter (allocates; call at start-up only).
    pub fn new(config: SvfConfig) -> Result<Discretisation, FilterError> {
        config.validate()?;
        let n = config.order;
        let wc = config.cutoff_rad_s();
        let (a, b) = scaled_realisation(n, wc);
        let d = Foh::new(&a, &b, config.sample_period_s)?;
        let mut phi = [[0.0; MAX_ORDER]; MAX_ORDER];
        let mut g_prev = [0.0; MAX_ORDER];
        let mut g_now = [0.0; MAX_ORDER];
        let mut unscale = [0.0; MAX_ORDER];
        for i in 0..n {
            for (j, p) in phi[i].iter_mut().enumerate().take(n) {
                *p = d.phi[(i, j)];
            }
            g_now[i] = d.gamma_ramp[(i, 0)];
            g_prev[i] = d.gamma_hold[(i, 0)] - d.gamma_ramp[(i, 0)];
            unscale[i] = wc.powi(i as i32);
        }
        Ok(Discretisation {
            order: n,
            phi,
            g_prev,
            g_now,
            unscale,
            config,
        })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &SvfConfig {
        &self.config
    }

    /// Filter order `n` (number of states).
    pub fn order(&self) -> usize {
        self.order
    }

    /// Advances `K` channels that share this filter by one sample: `u[c]` is channel `c`'s input
    /// at the new tick. One pass over `Φ` for all channels.
    #[inline]
    pub fn advance<const K: usize>(&self, states: &mut [SvfState; K], u: [f64; K]) {
        let n = self.order;
        let old: [[f64; MAX_ORDER]; K] = std::array::from_fn(|c| states[c].z);
        for i in 0..n {
            let row = &self.phi[i];
            let mut acc: [f64; K] =
                std::array::from_fn(|c| self.g_prev[i] * states[c].u_prev + self.g_now[i] * u[c]);
            for j in 0..n {
                for c in 0..K {
                    acc[c] += row[j] * old[c][j];
                }
            }
            for c in 0..K {
                states[c].z[i] = acc[c];
            }
        }
        for c in 0..K {
            states[c].u_prev = u[c];
        }
    }

    /// The k-th derivative of the filtered signal held in `state` (`k < order`), in the unit of
    /// the input per second^k. Past the order it reads 0; it panics for `k ≥ MAX_ORDER` (a
    /// programming error, not a data error).
    #[inline]
    pub fn derivative(&self, state: &SvfState, k: usize) -> f64 {
        state.z[k] * self.unscale[k]
    }

    /// `Φ` of the time-scaled states as an n×n matrix (for analysis and tests).
    pub fn phi_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_fn(self.order, self.order, |i, j| self.phi[i][j])
    }
}

/// The time-scaled continuous realisation `(Ã, b̃)` (module docs).
pub fn scaled_realisation(order: usize, cutoff_rad_s: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let alpha = butterworth_polynomial(order);
    let mut a = DMatrix::<f64>::zeros(order, order);
    for k in 0..order - 1 {
        a[(k, k + 1)] = cutoff_rad_s;
    }
    for k in 0..order {
        a[(order - 1, k)] = -cutoff_rad_s * alpha[k];
    }
    let mut b = DMatrix::<f64>::zeros(order, 1);
    b[(order - 1, 0)] = cutoff_rad_s;
    (a, b)
}

/// The state of one filtered channel: time-scaled states and the previous input sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SvfState {
    z: [f64; MAX_ORDER],
    u_prev: f64,
}

impl SvfState {
    /// The steady state for a constant input `u`: `u_f = u` (unity DC gain), all derivatives 0.
    pub fn steady(u: f64) -> SvfState {
        let mut z = [0.0; MAX_ORDER];
        z[0] = u;
        SvfState { z, u_prev: u }
    }
}

/// A single-channel state-variable filter.
#[derive(Clone, Debug, PartialEq)]
pub struct Svf {
    disc: Discretisation,
    state: [SvfState; 1],
}

impl Svf {
    /// A filter at rest at zero.
    pub fn new(config: SvfConfig) -> Result<Svf, FilterError> {
        Ok(Svf {
            disc: Discretisation::new(config)?,
            state: [SvfState::default()],
        })
    }

    /// Feeds the input sample of the new tick.
    #[inline]
    pub fn step(&mut self, u: f64) {
        self.disc.advance(&mut self.state, [u]);
    }

    /// `u_f^(k)`, the k-th derivative of the filtered input [input unit / s^k]; `None` for
    /// `k ≥ order`.
    pub fn derivative(&self, k: usize) -> Option<f64> {
        (k < self.disc.order()).then(|| self.disc.derivative(&self.state[0], k))
    }

    /// Puts the filter in the steady state of a constant input `u`.
    pub fn reset_steady(&mut self, u: f64) {
        self.state = [SvfState::steady(u)];
    }

    /// The shared discretisation.
    pub fn discretisation(&self) -> &Discretisation {
        &self.disc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{PhasorCheck, fit_phasor, max_abs_rel};
    use num_complex::Complex64;

    fn lambda(alpha: &[f64], order: usize, p: Complex64) -> Complex64 {
        (0..=order).map(|k| p.powi(k as i32) * alpha[k]).sum()
    }

    #[test]
    fn butterworth_coefficients() {
        let want6 = [
            1.0,
            3.863_703_305,
            7.464_101_615,
            9.141_620_173,
            7.464_101_615,
            3.863_703_305,
            1.0,
        ];
        let got = butterworth_polynomial(6);
        assert!(max_abs_rel(&got[..7], &want6) < 1e-9);
        let want5 = [
            1.0,
            3.236_067_977,
            5.236_067_977,
            5.236_067_977,
            3.236_067_977,
            1.0,
        ];
        assert!(max_abs_rel(&butterworth_polynomial(5)[..6], &want5) < 1e-9);
        // |B_n(iΩ)|² = 1 + Ω^{2n} for every order.
        for n in MIN_ORDER..=MAX_ORDER {
            let a = butterworth_polynomial(n);
            for w in [0.3, 1.0, 2.7] {
                let mag2 = lambda(&a, n, Complex64::new(0.0, w)).norm_sqr();
                assert!((mag2 - (1.0 + w.powi(2 * n as i32))).abs() < 1e-12 * mag2);
            }
        }
    }

    /// Runs a sampled `cos(ωt)` through the filter and returns the steady-state phasor of every
    /// derivative state (fitted over whole periods after the transient).
    fn measured_response(cfg: SvfConfig, f_hz: f64) -> Vec<Complex64> {
        let mut svf = Svf::new(cfg).unwrap();
        let h = cfg.sample_period_s;
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let settle = (3.0 / h) as usize;
        let window = (2.0 / h) as usize; // 2 s: whole periods for f·2 ∈ ℕ
        let mut states = vec![Vec::with_capacity(window); cfg.order];
        for k in 0..settle + window {
            svf.step((w * k as f64 * h).cos());
            if k >= settle {
                for (i, s) in states.iter_mut().enumerate() {
                    s.push(svf.derivative(i).unwrap());
                }
            }
        }
        states.iter().map(|s| fit_phasor(s, w, h, settle)).collect()
    }

    /// Each state `k` against the exact `(iω)^k / Λ(iω)`: amplitude and phase within 1e-3
    /// relative, from 0.5 Hz to half the cut-off. Measured: the FOH factor `1 − (ωh)²/12`, common
    /// to every state (8.2e-5 at 5 Hz), except for the highest state at the lowest frequency,
    /// 6.7e-4 at 0.5 Hz — where its own response `ω⁵/|Λ|` is smallest and its filter (rolling
    /// off at only 20 dB/decade) passes most of what the linear interpolation leaves near the
    /// sample rate (our reading; it is not a discretisation error of `Φ`).
    #[test]
    fn transfer_function_of_every_state() {
        let cfg = SvfConfig::default();
        let alpha = butterworth_polynomial(cfg.order);
        let mut check = PhasorCheck::default();
        for f_hz in [0.5, 1.0, 2.0, 3.5, 5.0] {
            let iw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
            let lam = lambda(&alpha, cfg.order, iw / cfg.cutoff_rad_s());
            for (k, got) in measured_response(cfg, f_hz).into_iter().enumerate() {
                let want = iw.powi(k as i32) / lam;
                check.check(got, want, 1e-3, &format!("{f_hz} Hz, state {k}"));
            }
        }
        eprintln!(
            "SVF transfer-function worst relative error (0.5–5 Hz, 6 states): {:.2e}",
            check.worst
        );
    }

    /// ZOH would be off by the half-sample delay `ωh/2`; the FOH used here is not.
    #[test]
    fn zoh_lags_half_a_sample_foh_does_not() {
        let cfg = SvfConfig::default();
        let f_hz = 2.0;
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let alpha = butterworth_polynomial(cfg.order);
        let iw = Complex64::new(0.0, w);
        let want = Complex64::new(1.0, 0.0) / lambda(&alpha, cfg.order, iw / cfg.cutoff_rad_s());
        let foh = measured_response(cfg, f_hz)[0];
        // ZOH response of the same realisation: Φ z + Γ_hold u_k.
        let (a, b) = scaled_realisation(cfg.order, cfg.cutoff_rad_s());
        let d = Foh::new(&a, &b, cfg.sample_period_s).unwrap();
        let h = cfg.sample_period_s;
        let mut z = nalgebra::DVector::<f64>::zeros(cfg.order);
        let mut out = Vec::new();
        let (settle, window) = (3000, 2000);
        for k in 0..settle + window {
            let u_prev = (w * (k as f64 - 1.0) * h).cos();
            z = &d.phi * &z + d.gamma_hold.column(0) * u_prev;
            if k >= settle {
                out.push(z[0]);
            }
        }
        let zoh = fit_phasor(&out, w, h, settle);
        let zoh_err = (zoh - want).norm() / want.norm();
        let foh_err = (foh - want).norm() / want.norm();
        assert!(foh_err < 1e-4, "FOH {foh_err:e}");
        // The ZOH lag: ωh/2 = 6.3e-3 rad.
        assert!(zoh_err > 5e-3, "ZOH {zoh_err:e}");
    }

    #[test]
    fn unity_dc_gain_and_steady_reset() {
        let cfg = SvfConfig::default();
        let mut svf = Svf::new(cfg).unwrap();
        for _ in 0..5000 {
            svf.step(0.37);
        }
        assert!((svf.derivative(0).unwrap() - 0.37).abs() < 1e-12);
        for k in 1..cfg.order {
            assert!(svf.derivative(k).unwrap().abs() < 1e-9, "state {k}");
        }
        assert_eq!(svf.derivative(cfg.order), None);
        // The steady state is a fixed point of the discrete map: exact DC gain.
        svf.reset_steady(-2.5);
        let before = svf.clone();
        svf.step(-2.5);
        for k in 0..cfg.order {
            let (a, b) = (svf.derivative(k).unwrap(), before.derivative(k).unwrap());
            assert!(
                (a - b).abs() < 1e-13 * 2.5 * cfg.cutoff_rad_s().powi(k as i32),
                "state {k}"
            );
        }
    }

    /// The time-scaled realisation keeps Φ well conditioned at 6th order; the plain companion
    /// form's Φ is the same map under the similarity `diag(ω_c^k)` and is numerically singular in
    /// f64 (condition beyond 1e16; the assertion asks for > 1e12).
    #[test]
    fn time_scaling_keeps_phi_well_conditioned() {
        let cfg = SvfConfig::default();
        let d = Discretisation::new(cfg).unwrap();
        let phi = d.phi_matrix();
        let cond = |m: &DMatrix<f64>| {
            let sv = m.clone().svd(false, false).singular_values;
            sv.max() / sv.min()
        };
        let scaled = cond(&phi);
        assert!(scaled < 5.0, "cond Φ̃ = {scaled}");
        let s = DMatrix::from_fn(cfg.order, cfg.order, |i, j| {
            if i == j {
                cfg.cutoff_rad_s().powi(i as i32)
            } else {
                0.0
            }
        });
        let s_inv = s.clone().try_inverse().unwrap();
        let plain = &s * &phi * &s_inv;
        eprintln!(
            "cond Φ̃ (time-scaled) = {scaled:.2}, cond Φ (plain) = {:.1e}",
            cond(&plain)
        );
        assert!(cond(&plain) > 1e12, "cond Φ = {:e}", cond(&plain));
        // And the scaled input vector is O(1) too.
        assert!((0..cfg.order).all(|i| d.g_now[i].abs() < 1.0 && d.g_prev[i].abs() < 1.0));
    }

    #[test]
    fn invalid_configs_are_named() {
        let bad = |c: SvfConfig| Svf::new(c).unwrap_err();
        let base = SvfConfig::default();
        assert_eq!(
            bad(SvfConfig { order: 3, ..base }),
            FilterError::Order { order: 3 }
        );
        assert_eq!(
            bad(SvfConfig { order: 9, ..base }),
            FilterError::Order { order: 9 }
        );
        assert!(matches!(
            bad(SvfConfig {
                cutoff_hz: 0.0,
                ..base
            }),
            FilterError::Cutoff { .. }
        ));
        assert!(matches!(
            bad(SvfConfig {
                cutoff_hz: 150.0,
                ..base
            }),
            FilterError::Cutoff { .. }
        ));
        assert!(matches!(
            bad(SvfConfig {
                cutoff_hz: f64::NAN,
                ..base
            }),
            FilterError::Cutoff { .. }
        ));
        assert!(matches!(
            bad(SvfConfig {
                sample_period_s: -1e-3,
                ..base
            }),
            FilterError::SamplePeriod { .. }
        ));
        let msg = bad(SvfConfig { order: 3, ..base }).to_string();
        assert!(
            msg.contains("order") && msg.contains('3') && msg.contains("4..=8"),
            "{msg}"
        );
    }
}

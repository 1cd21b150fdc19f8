//! "New object" detector: a one-sided CUSUM (E. S. Page, "Continuous inspection schemes",
//! Biometrika 41:100–115, 1954) on the normalised a-priori prediction error of the RLS.
//!
//! When the tool touches a different object, the error of the *old* parameters jumps by an order
//! of magnitude and stays up; friction reversals and noise make short bursts. The statistic
//!
//! ```text
//! z_k = min(e_k² / max(r_k, (ε·y_rms,k)²), z_max)          normalised error power
//! S_k = max(0, S_{k−1} + z_k − ν)                          Page's CUSUM, drift ν
//! alarm when S_k > h                                        (then S ← 0, re-learn r)
//! ```
//!
//! accumulates only a sustained excess: with the defaults an error 5× the usual RMS alarms in
//! `h/(z_max − ν)` ≈ 48 samples, while a burst must last that long at that size to alarm. `r_k`
//! is an EWMA of `e²` (the usual error power; during the hold-off after a start, reset or alarm a
//! running mean, so it is re-learned from the new situation) and `ε·y_rms` a floor, so a
//! near-perfect fit on clean data does not make every tiny change an alarm (`DESIGN.md` §11.3).

/// Tuning of the detector. Sample counts are RLS updates (1 ms each at 1 kHz).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CusumConfig {
    /// Time constant of the reference error power `r` and of the output power [updates].
    /// Default 2000 (2 s): long against the 1 s memory of the estimator, so a new object shows
    /// as a jump against it.
    pub reference_samples: f64,
    /// Floor `ε` of the reference RMS error relative to the RMS output [1]. Default 0.02: errors
    /// below about `√ν·ε` = 4 % of the force never accumulate, whatever the fit was.
    pub floor_relative: f64,
    /// Drift `ν` [1, in units of the reference power]. Default 4: an error RMS up to twice the
    /// usual does not accumulate.
    pub drift: f64,
    /// Clip `z_max` of one sample's normalised power [1]. Default 25 (an error 5× the usual): one
    /// outlier cannot alarm by itself.
    pub clip: f64,
    /// Alarm threshold `h` [1]. Default 1000: ≈ 48 updates of a ≥ 5× error.
    pub threshold: f64,
    /// Updates after a start, reset or alarm before the detector arms [updates]. Default 1000
    /// (1 s): the estimator re-converges and `r` is re-learned meanwhile.
    pub holdoff_samples: u32,
}

impl Default for CusumConfig {
    fn default() -> Self {
        CusumConfig {
            reference_samples: 2000.0,
            floor_relative: 0.02,
            drift: 4.0,
            clip: 25.0,
            threshold: 1000.0,
            holdoff_samples: 1000,
        }
    }
}

impl CusumConfig {
    /// Name, value and expectation of the first invalid field, if any.
    pub fn invalid_field(&self) -> Option<(&'static str, f64, &'static str)> {
        let checks = [
            (
                "cusum.reference_samples",
                self.reference_samples,
                self.reference_samples >= 1.0,
            ),
            (
                "cusum.floor_relative",
                self.floor_relative,
                self.floor_relative >= 0.0,
            ),
            ("cusum.drift", self.drift, self.drift > 0.0),
            ("cusum.clip", self.clip, self.clip > self.drift),
            ("cusum.threshold", self.threshold, self.threshold > 0.0),
        ];
        checks
            .into_iter()
            .find(|(_, v, ok)| !(v.is_finite() && *ok))
            .map(|(name, v, _)| {
                (
                    name,
                    v,
                    "finite; reference ≥ 1, floor ≥ 0, drift > 0, clip > drift, threshold > 0",
                )
            })
    }
}

/// The detector's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cusum {
    config: CusumConfig,
    /// `r`: reference error power [N²].
    reference: f64,
    /// Output power [N²].
    output: f64,
    /// `S`.
    statistic: f64,
    /// Updates since the last start, reset or alarm.
    since_reset: u64,
    /// Updates left during which the detector neither accumulates nor learns its reference.
    muted: u32,
}

impl Cusum {
    /// A detector in its initial hold-off.
    pub fn new(config: CusumConfig) -> Cusum {
        Cusum {
            config,
            reference: 0.0,
            output: 0.0,
            statistic: 0.0,
            since_reset: 0,
            muted: 0,
        }
    }

    /// Ignores the next `samples` errors (no accumulation, reference untouched), e.g. while the
    /// filters' switching transient after a contact onset passes; the statistic restarts from 0.
    pub fn mute(&mut self, samples: u32) {
        self.muted = samples;
        self.statistic = 0.0;
    }

    /// Starts a new hold-off and re-learns the reference (after a covariance reset or an alarm).
    pub fn restart(&mut self) {
        *self = Cusum::new(self.config);
    }

    /// The current statistic `S` (0 while disarmed).
    pub fn statistic(&self) -> f64 {
        self.statistic
    }

    /// Feeds one a-priori error `e` [N] and output `y` [N]; true on an alarm (the detector then
    /// restarts its hold-off).
    pub fn update(&mut self, e: f64, y: f64) -> bool {
        if self.muted > 0 {
            self.muted -= 1;
            return false;
        }
        let c = &self.config;
        self.since_reset += 1;
        // EWMA with a running-mean start: weight max(1/τ, 1/k).
        let w = (1.0 / c.reference_samples).max(1.0 / self.since_reset as f64);
        let e2 = e * e;
        let armed = self.since_reset > u64::from(c.holdoff_samples);
        if armed {
            let floor = c.floor_relative * c.floor_relative * self.output;
            let z = (e2 / self.reference.max(floor).max(f64::MIN_POSITIVE)).min(c.clip);
            self.statistic = (self.statistic + z - c.drift).max(0.0);
            if self.statistic > c.threshold {
                self.restart();
                return true;
            }
        }
        self.reference += w * (e2 - self.reference);
        self.output += w * (y * y - self.output);
        false
    }
}

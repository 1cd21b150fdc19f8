//! Loss models: none, Bernoulli, and netem's Gilbert–Elliott (`loss gemodel p r 1-h 1-k`).
//!
//! Gilbert–Elliott follows `loss_gilb_ell` in `sch_netem.c` (model from Salsano, Ludovici,
//! Ordine, "NetemCLG"): two states, Good and Bad. For each packet one draw decides the move to the
//! next state (Good→Bad with probability `p`, Bad→Good with `r`) and a second draw decides the loss
//! with the loss probability of the state the packet found (`1−k` in Good, `1−h` in Bad). The
//! special cases: Simple Gilbert (`1−h` = 1, `1−k` = 0), Gilbert (`1−k` = 0) and Bernoulli
//! (`r` = 1 − `p`, `1−h` = 1, `1−k` = 0; [`Loss::Random`] is the direct form).
//!
//! Stationary loss rate ([`Loss::mean_rate`]): π_B = p/(p+r), loss = (1−k)(1−π_B) + (1−h)π_B.

use rand::RngCore;

/// How packets are lost. Probabilities are fractions in `0..=1` (1 % = 0.01).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Loss {
    /// No loss.
    #[default]
    None,
    /// Each packet is lost independently with `probability` (netem `loss random P`).
    Random {
        /// Loss probability, `0..=1`.
        probability: f64,
    },
    /// Gilbert–Elliott (netem `loss gemodel p r 1-h 1-k`).
    GilbertElliott {
        /// Good→Bad transition probability per packet, `0..=1`.
        p: f64,
        /// Bad→Good transition probability per packet, `0..=1`. `tc`'s default: 1.
        r: f64,
        /// Loss probability in the Bad state, `0..=1`. `tc`'s default: 1.
        one_minus_h: f64,
        /// Loss probability in the Good state, `0..=1`. `tc`'s default: 0.
        one_minus_k: f64,
    },
}

impl Loss {
    /// The long-run fraction of packets lost.
    pub fn mean_rate(&self) -> f64 {
        match *self {
            Loss::None => 0.0,
            Loss::Random { probability } => probability,
            Loss::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => {
                if p + r == 0.0 {
                    // Never leaves the Good state it starts in.
                    return one_minus_k;
                }
                let bad = p / (p + r);
                one_minus_k * (1.0 - bad) + one_minus_h * bad
            }
        }
    }

    /// Each probability with its field name, for validation.
    pub(crate) fn probabilities(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Loss::None => Vec::new(),
            Loss::Random { probability } => vec![("loss.probability", probability)],
            Loss::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => vec![
                ("loss.p", p),
                ("loss.r", r),
                ("loss.one_minus_h", one_minus_h),
                ("loss.one_minus_k", one_minus_k),
            ],
        }
    }
}

/// A probability turned into a threshold on a uniform `u32` draw: `P(hit) = threshold / 2³²`,
/// exact for 0 and 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Threshold(u64);

impl Threshold {
    pub(crate) fn new(probability: f64) -> Self {
        Self((probability.clamp(0.0, 1.0) * 4_294_967_296.0).round() as u64)
    }

    pub(crate) fn is_zero(self) -> bool {
        self.0 == 0
    }

    pub(crate) fn hit(self, rnd: u32) -> bool {
        u64::from(rnd) < self.0
    }
}

/// The loss model with its state (the Gilbert–Elliott chain's current state).
#[derive(Clone, Debug)]
pub(crate) struct LossState {
    model: Compiled,
    bad: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Compiled {
    None,
    Random(Threshold),
    GilbertElliott {
        to_bad: Threshold,
        to_good: Threshold,
        loss_bad: Threshold,
        loss_good: Threshold,
    },
}

impl LossState {
    pub(crate) fn new(loss: &Loss) -> Self {
        Self {
            model: compile(loss),
            bad: false,
        }
    }

    /// Changes the model; the chain keeps its state if it is still Gilbert–Elliott.
    pub(crate) fn reconfigure(&mut self, loss: &Loss) {
        self.model = compile(loss);
        if !matches!(self.model, Compiled::GilbertElliott { .. }) {
            self.bad = false;
        }
    }

    /// Draws the loss decision for one packet (netem `loss_event`).
    pub(crate) fn lose(&mut self, rng: &mut impl RngCore) -> bool {
        match self.model {
            Compiled::None => false,
            Compiled::Random(threshold) => !threshold.is_zero() && threshold.hit(rng.next_u32()),
            Compiled::GilbertElliott {
                to_bad,
                to_good,
                loss_bad,
                loss_good,
            } => {
                let was_bad = self.bad;
                if was_bad {
                    if to_good.hit(rng.next_u32()) {
                        self.bad = false;
                    }
                    loss_bad.hit(rng.next_u32())
                } else {
                    if to_bad.hit(rng.next_u32()) {
                        self.bad = true;
                    }
                    loss_good.hit(rng.next_u32())
                }
            }
        }
    }
}

fn compile(loss: &Loss) -> Compiled {
    match *loss {
        Loss::None => Compiled::None,
        Loss::Random { probability } => Compiled::Random(Threshold::new(probability)),
        Loss::GilbertElliott {
            p,
            r,
            one_minus_h,
            one_minus_k,
        } => Compiled::GilbertElliott {
            to_bad: Threshold::new(p),
            to_good: Threshold::new(r),
            loss_bad: Threshold::new(one_minus_h),
            loss_good: Threshold::new(one_minus_k),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn thresholds_are_exact_at_the_ends() {
        assert!(!Threshold::new(0.0).hit(0));
        assert!(Threshold::new(1.0).hit(u32::MAX));
        assert!(Threshold::new(0.5).hit(u32::MAX / 2));
        assert!(!Threshold::new(0.5).hit(1 << 31));
    }

    #[test]
    fn gilbert_elliott_matches_the_closed_form() {
        let loss = Loss::GilbertElliott {
            p: 0.01,
            r: 0.3,
            one_minus_h: 0.8,
            one_minus_k: 0.005,
        };
        // π_B = 0.01/0.31; rate = 0.005·0.3/0.31 + 0.8·0.01/0.31 = 0.030645…
        let expected = loss.mean_rate();
        assert!((expected - 0.0095 / 0.31).abs() < 1e-12);
        let mut state = LossState::new(&loss);
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let n = 2_000_000;
        let lost = (0..n).filter(|_| state.lose(&mut rng)).count();
        let rate = lost as f64 / f64::from(n);
        // Losses come in bursts (mean 1/r ≈ 3.3 packets), so the spread is wider than binomial:
        // σ ≈ √(rate·burst·(1+1/p·…)/n) ≈ 0.0004 here; 3 % relative is > 2σ.
        assert!(
            (rate / expected - 1.0).abs() < 0.03,
            "rate {rate}, closed form {expected}"
        );
    }

    #[test]
    fn simple_gilbert_loses_in_bursts() {
        let loss = Loss::GilbertElliott {
            p: 0.02,
            r: 0.25,
            one_minus_h: 1.0,
            one_minus_k: 0.0,
        };
        let mut state = LossState::new(&loss);
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        let fates: Vec<bool> = (0..500_000).map(|_| state.lose(&mut rng)).collect();
        let bursts = fates.windows(2).filter(|w| !w[0] && w[1]).count();
        let lost = fates.iter().filter(|&&l| l).count();
        let mean_burst = lost as f64 / bursts as f64;
        // In the Bad state every packet is lost; the state lasts 1/r = 4 packets on average.
        assert!((mean_burst - 4.0).abs() < 0.2, "mean burst {mean_burst}");
    }
}

//! Karnopp stick–slip friction between the object and the table (D. Karnopp, "Computer
//! simulation of stick-slip friction in mechanical dynamic systems", ASME J. Dyn. Sys. Meas.
//! Control 107(1):100–103, 1985; numerics notes §8), evaluated once per simulator sub-step with
//! the friction force held over the sub-step.
//!
//! Karnopp's regimes and levels are kept — sliding at `F_d`, sticking up to `F_s`, breaking
//! away from rest at `F_s` — but the stick is computed the way fixed-step friction solvers do it
//! (the implicit projection of R. Kikuuwe et al., "Fixed-step friction simulation: from
//! classical Coulomb model to modern continuous models", IROS 2005; Moreau–Jean time stepping):
//! the stick force is the force that brings the mass **exactly to rest at the end of the
//! sub-step**, computed from the exact discrete response, and the mass sticks when that force is
//! within `±F_s`. This removes the two pitfalls of the textbook form (numerics notes §8, 1 and
//! 2): the velocity cannot jump across zero and chatter (a slip step whose friction would reverse
//! the velocity goes to the stick test, however narrow the band), and a stuck mass does not creep
//! (textbook Karnopp sets the net force to zero and keeps whatever velocity the mass had in the
//! band). Per sub-step, with `f*` the force that ends the sub-step at rest:
//!
//! ```text
//! |v| ≥ v_d and −F_d sgn v does not reverse v      slip:  f = −F_d sgn v
//! otherwise, |f*| ≤ F_s                           stick: f = f*, v⁺ = 0
//! otherwise, v = 0                                break-away: f = F_s sgn f*
//! otherwise (moving in the band, or reversing)    slip:  f = F_d sgn f*  (against the motion)
//! ```
//!
//! The band `v_d` thus only decides where the stick test is tried besides reversals; since the
//! stick test includes the momentum `m v/h`, a mass moving faster than about `F_s h/m` cannot
//! stick in one sub-step anyway, so `v_d` hardly changes the result (unlike textbook Karnopp,
//! where it sets the creep and the break-away timing).

/// Karnopp friction levels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Karnopp {
    /// Static (break-away) level `F_s` [N], ≥ `F_d`. Exp-1: 0.1 N (thesis §4.1).
    pub static_n: f64,
    /// Dynamic (Coulomb) level `F_d` [N]. Exp-1: 0.05 N.
    pub dynamic_n: f64,
    /// Stick band `v_d` [m/s]: below it the mass may stick. Exp-1: 0.005 m/s.
    pub band_m_per_s: f64,
}

/// Which branch of the law applied over a sub-step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Stuck: the friction force (|f| ≤ F_s) holds the mass at rest at the end of the sub-step.
    Stick,
    /// Sliding at `F_d`.
    Slip,
    /// At rest, but holding it would take more than `F_s`: friction at `F_s`, the mass starts.
    BreakAway,
}

impl Karnopp {
    /// The friction force on the mass over one sub-step and the branch taken.
    ///
    /// `v` is the mass velocity at the start of the sub-step, `v_free` the velocity it would have
    /// at the end without friction, and `c_v` > 0 the end velocity per newton of friction held
    /// over the sub-step (so the end velocity is `v_free + c_v·f`).
    pub fn force(&self, v: f64, v_free: f64, c_v: f64) -> (f64, Phase) {
        if v.abs() >= self.band_m_per_s {
            let f = -self.dynamic_n * v.signum();
            // Slip unless this friction alone would carry the velocity through zero.
            if (v_free + c_v * f) * v > 0.0 {
                return (f, Phase::Slip);
            }
        }
        let hold = -v_free / c_v;
        if hold.abs() <= self.static_n {
            (hold, Phase::Stick)
        } else if v == 0.0 {
            (self.static_n * hold.signum(), Phase::BreakAway)
        } else {
            (self.dynamic_n * hold.signum(), Phase::Slip)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: Karnopp = Karnopp {
        static_n: 0.1,
        dynamic_n: 0.05,
        band_m_per_s: 0.005,
    };

    #[test]
    fn branches() {
        let c_v = 1e-4; // 1 kg, 0.1 ms
        // At rest, applied force 0.08 N (v_free = c_v·0.08): held.
        let (f, p) = K.force(0.0, c_v * 0.08, c_v);
        assert_eq!(p, Phase::Stick);
        assert!((f + 0.08).abs() < 1e-15);
        // At rest, 0.12 N: breaks away against F_s.
        assert_eq!(K.force(0.0, c_v * 0.12, c_v), (-0.1, Phase::BreakAway));
        // Sliding: F_d against the motion.
        assert_eq!(K.force(0.01, 0.0101, c_v), (-0.05, Phase::Slip));
        assert_eq!(K.force(-0.01, -0.0099, c_v), (0.05, Phase::Slip));
        // Sliding with a tiny remaining velocity: F_d would reverse it, so it sticks.
        let (_, p) = K.force(0.006, 2e-6, c_v);
        assert_eq!(p, Phase::Stick);
        // Moving in the band, pushed by more than F_s: slides at F_d (not F_s, which would only
        // let it approach the F_s balance asymptotically and never stick).
        assert_eq!(K.force(1e-3, 1e-3 + c_v * 0.3, c_v), (-0.05, Phase::Slip));
        // Reversing through zero under a large force: F_d against the new motion.
        assert_eq!(K.force(0.01, -0.01, c_v), (0.05, Phase::Slip));
    }
}

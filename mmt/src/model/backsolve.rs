//! Back-solve θ → φ (numerics notes §2). Written next.

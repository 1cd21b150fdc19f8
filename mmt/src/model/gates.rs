//! Gates a parameter set must pass before it is rendered (numerics notes §2.6). Written next.

//! Behaviour and accuracy of the proxy contact detector (issue 3): the figures as tests.
//! Speed is measured by `mmt contact-bench` and `benches/contact.rs`, never here.

// Test helpers unwrap like the tests themselves (clippy only exempts `#[test]` functions).
#![allow(clippy::unwrap_used)]

mod determinism;
mod figures;
mod frames;
mod holes;
mod moving;
mod support;

//! # mmt — the model-mediated teleoperation numerical core
//!
//! What it is: the environment model and its sign convention ([`model`], with the back-solve
//! and the gates), the state-variable filters ([`filter`]), the RLS estimator ([`rls`],
//! [`estimator`]), the renderer and its exact transfer characteristic ([`render`]), the proxy
//! contact detector and its cloud index ([`contact`]), and point-cloud frames ([`cloud`]).
//!
//! What it is not: no clock, thread, file, socket, plot or wire type. Time and randomness are
//! arguments, so a run with the same inputs gives the same bits. The nodes that step this core
//! are the `node` crate's, the simulated world is `sim`'s, PLY/PCD files are `cloud-io`'s, and
//! the experiments, reports and plots are `lab`'s. A test checks that this crate never depends
//! on tokio, quinn, rustls, plotters, clap, libc or netem.

pub mod cloud;
pub mod contact;
pub mod estimator;
pub mod filter;
pub mod model;
pub mod render;
pub mod rls;
pub mod vec3;

/// Test helpers shared with the crates whose tests drive this core (exact excitation data,
/// phasor fits, reference least squares). Compiled for this crate's tests and with the
/// `testutil` feature; not part of the API.
#[cfg(any(test, feature = "testutil"))]
#[doc(hidden)]
pub mod testutil;

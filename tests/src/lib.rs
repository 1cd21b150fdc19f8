//! # tests — the end-to-end tests
//!
//! What it is: the tests in `tests/tests/` — the real daemons over loopback QUIC through the
//! netem shim (`e2e.rs`), the loops' allocation check (`no_alloc.rs`), and the workspace's
//! layout (which crates may depend on what, file and function sizes). Their scaffolding is the
//! `testkit` crate's, shared with every other test package.
//!
//! What it is not: a library; this file only holds the package's documentation.

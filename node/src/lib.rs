//! # node — the telerobot and operator nodes
//!
//! What it is: the two nodes of the system (`DESIGN.md` §3), plain structs stepped with `now`
//! and their inputs, producing outputs and `protocol` datagrams. The networked daemons run
//! exactly these nodes; the in-process experiment harness (`lab::experiment`) runs them over the
//! `netem` link model, through the same header path (the nodes emit payloads whose headers carry
//! only the sample time; one `protocol::session::Session` per endpoint stamps the rest).
//!
//! - [`telerobot::TelerobotNode`]: a robot sample ([`RobotSample`], from any [`RobotBridge`]) →
//!   contact on the live cloud → estimators → gates → parameter, contact, state-sync and
//!   measurement datagrams; commands played out in order behind a jitter buffer.
//! - [`operator::OperatorNode`]: device position → contact on the latest received cloud (remote
//!   contact as fallback) → renderers with the latest accepted parameters → force and a command;
//!   a short history to rewind and replay.
//! - [`guard`]: the motion guard every robot bridge goes through ([`Guarded`]): no command
//!   before the robot's first state, hold on a stale state, a workspace box, a largest step and
//!   speed, faults on non-finite readings, checks at each session.
//! - Settings: [`TelerobotSettings`] from the telerobot's scene, [`OperatorSettings`] from the
//!   `Welcome` alone; conversions between the core's types and the wire's.
//!
//! Both decide contact the same way ([`ContactTracker`]): the proxy touches the cloud **and** the
//! tool is below the locally fitted surface. The proxy says which surface the tool is at, and its
//! orientation; the plane test says whether the tool is actually pressing into it (the proxy alone
//! reports contact up to `r2` before the surface). The surface frame is frozen for a contact
//! episode: a frame that wobbled with cloud noise would turn a 5 cm tangential displacement into
//! millimetres of spurious motion on the other axes.
//!
//! What it is not: no clock, thread or socket (time is an argument), no simulator (the `sim`
//! crate is one [`RobotBridge`]), no numerics of its own (`mmt`'s).

mod bridge;
mod continuity;
pub mod guard;
mod history;
mod observer;
pub mod operator;
mod playout;
mod settings;
pub mod telerobot;
mod tracker;
mod wire;

pub use bridge::{BridgeSample, Reading, RobotBridge, RobotSample, Target};
pub use guard::{GuardStats, Guarded, MotionGuard, MotionLimits};
pub use settings::{
    KnownSurface, OperatorSettings, RATE_RANGE_HZ, SettingsError, TelerobotSettings,
};
pub use tracker::{ContactTracker, Tracked};
pub use wire::{
    cloud_to_wire, contact_state_to_wire, gated_from_wire, parameter_set, prior_from_wire,
    prior_to_wire, structure_from_wire, structure_to_wire, surface_frame_from_wire,
    surface_frame_to_wire,
};

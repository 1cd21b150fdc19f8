//! # sim — the simulated world
//!
//! What it is: the ground truth the telerobot's default robot bridge drives and the in-process
//! experiments run against (thesis set-up 1, §4.1 and §F.3.1; `DESIGN.md` §5, §9):
//! - [`object`]: the sliding flexible object on one tangential axis, integrated exactly at
//!   ≥ 10 kHz with Karnopp stick–slip friction ([`friction`]) and sensor noise ([`noise`]);
//! - [`world`]: the object in 3-D — a surface frame, the normal contact and two tangential
//!   axes — as the robot meets it;
//! - [`camera`]: the simulated depth camera over the scene's surface, with a real camera's
//!   clustered holes and depth-dependent noise ([`holes`]), and [`synthetic`] clouds (planes,
//!   boxes, spheres with noise, dropout and motion);
//! - [`scene`]: scenes (TOML, every field validated, errors naming the field, the value and the
//!   range), and [`trajectory`]: the scripted tool trajectories of the experiments;
//! - [`workload`]: the standard contact workload the contact benchmarks measure.
//!
//! What it is not: no clock, thread, socket or file (scenes are parsed from text; the callers
//! read the files). Time and randomness are arguments: the same seed gives the same bits. The
//! estimation, rendering and contact logic is `mmt`'s; the nodes are `node`'s.

pub mod bridge;
pub mod camera;
pub mod follower;
pub mod friction;
pub mod holes;
pub mod noise;
pub mod object;
pub mod scene;
pub mod synthetic;
pub mod trajectory;
pub mod workload;
pub mod world;

pub use bridge::SimBridge;
pub use follower::Follower;
pub use friction::{Karnopp, Phase};
pub use noise::{Measurement, SensorNoise, Sensors};
pub use object::{FrictionStats, SimConfig, SimError, SimSample, SlidingObjectSim};

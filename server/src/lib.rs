//! The highway-arena server: the PettingZoo-style env built on the simulation
//! (`arena-sim`) and its Zenoh transport.
//!
//! `env` -> `transport`: the env owns an episode's semantics, the transport serves envs.
#![warn(missing_docs)]

pub mod env;
pub mod transport;

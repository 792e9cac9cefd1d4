//! The highway-arena server: a multi-lane highway world whose vehicles follow the
//! integrated driver + bicycle model of Hang et al. (paper §III), the drivers that steer
//! them, the PettingZoo-style env built on the world, and its Zenoh transport.
//!
//! The modules follow the data, one concern each:
//! `road` -> `dynamics` -> `traffic` / `av` -> `world` -> `scenario` -> `env` -> `transport`.
#![warn(missing_docs)]

pub mod av;
pub mod dynamics;
pub mod env;
pub mod paper;
pub mod road;
pub mod scenario;
pub mod traffic;
pub mod transport;
pub mod world;

//! The highway-arena simulation: a multi-lane highway whose vehicles follow the
//! integrated driver + bicycle model of Hang et al. (paper §III), the drivers that steer
//! them (IDM + MOBIL traffic, learners' commands, the paper's game-theoretic AV), and
//! the scenario files that set a world up. No networking here: the env and its Zenoh
//! server (`arena-server`) and the paper harness (`arena-paper`) build on this crate.
//!
//! The modules follow the data, one concern each:
//! `road` -> `dynamics` -> `scene` -> `traffic` / `gt` -> `world` -> `preset` -> `scenario`.
#![warn(missing_docs)]

pub mod dynamics;
pub mod gt;
pub mod preset;
pub mod road;
pub mod scenario;
pub mod scene;
pub mod traffic;
pub mod world;

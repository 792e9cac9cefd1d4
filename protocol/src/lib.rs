//! The wire protocol of highway-arena: every request and reply a client and an
//! `arena-server` exchange over Zenoh, the codec that turns them into bytes, the key
//! expressions they travel on, and the space specs that map one-to-one onto Gymnasium
//! spaces. It depends on nothing of the server; a client needs only this crate (and
//! docs/protocol.md describes the same bytes for clients in other languages).
//!
//! - [`Request`] / [`Reply`]: envelopes that carry [`PROTOCOL_VERSION`] first, then a
//!   [`RequestBody`] (server info, create, reset, step, step batch, render, state,
//!   specs, close) or a [`ReplyBody`].
//! - [`encode`] / [`decode`] / [`peek_version`]: the only place bytes are made (bincode
//!   2, standard config, with a [`MAX_MESSAGE_BYTES`] limit), so the codec is one file to
//!   change; [`DecodeError`] says whether bytes were too large, trailing or malformed.
//! - [`keys`]: key-expression builders and parsers; nothing else formats keys.
//! - [`info`]: the keys, types and order of every agent's info, and [`EndReason`].
//! - [`CreateOptions`] and [`CREATE_OPTIONS`]: an env's options, declared once; the table
//!   says how clients take each and what it does (docs/protocol.md's list is written from it).
//! - [`MetaAction`], [`ActionType`], [`ObservationKind`], [`Style`], [`Game`]: closed
//!   sets of choices, each with `ALL`, `name`, `Display` and `FromStr`.
//! - [`palette`]: the colours of every picture of a world (frames, recordings).
//! - [`bounds`]: the size of every string and list a request may carry.
//! - [`Space`]: Box, Discrete and Dict specs, with checks for observations and actions.
//! - [`WorldStart`] / [`WorldFrame`]: the world as a recording sees it (road geometry in
//!   world coordinates, every vehicle per control period), carried while recording is on.
//! - [`DecisionExplained`]: a game-theoretic car's decision with the game it played, carried
//!   with `CreateOptions::explain`.
//! - [`ErrorReply`]: a stable [`ErrorCode`], a message for people, and whether the env
//!   survives.
//! - `session` (feature `session`): connection flags turned into a `zenoh::Config`.
//!
//! ```
//! use arena_protocol::{Action, ClientId, EnvId, Request, RequestBody, decode, encode, keys, peek_version};
//!
//! let rpc = keys::server_rpc(keys::DEFAULT_PREFIX, "0123abcd").unwrap();
//! assert_eq!(rpc, "arena/0123abcd/rpc");
//!
//! let step = RequestBody::Step { env: EnvId(7), seq: 1, actions: vec![("ego".into(), Action::Meta(3))] };
//! let request = Request::new(ClientId(1), step);
//! let bytes = encode(&request); // the payload of a Zenoh `get` on `rpc`
//! assert_eq!(peek_version(&bytes), Some(arena_protocol::PROTOCOL_VERSION));
//! assert_eq!(decode::<Request>(&bytes), Ok(request));
//! assert!(decode::<Request>(&bytes[..3]).is_err());
//! ```
#![warn(missing_docs)]

pub mod bounds;
mod codec;
mod error;
mod explain;
pub mod info;
pub mod keys;
mod messages;
mod names;
mod options;
pub mod palette;
#[cfg(feature = "session")]
pub mod session;
mod spaces;
mod world;

pub use codec::{MAX_MESSAGE_BYTES, decode, encode, peek_client, peek_version};
pub use error::{DecodeError, ErrorCode, ErrorReply, KeyError};
pub use explain::{DecisionExplained, GameTable, PathPoint};
pub use info::{EndReason, Info, InfoKind, InfoValue};
pub use messages::*;
pub use names::UnknownName;
pub use options::{CREATE_OPTIONS, CreateOption, CreateOptions, Given, OptionKind};
pub use spaces::{DType, Space};
pub use world::{
    CollisionEvent, DriverInfo, Fault, GtRole, LaneGeometry, RoadGeometry, VehicleFrame, VehicleInfo, WorldFrame,
    WorldStart,
};

/// The protocol version every message carries first; bumped on any incompatible change
/// (3: client liveliness tokens carry `ClientId::tag`, and the server id is its Zenoh id;
/// 4: `ServerInfo::yours`, and requests of a named user travel on `keys::user_rpc`;
/// 5: one row per agent in step and reset replies, `ResetOptions`, infos of one fixed
/// schema with no strings, `info::SCHEMA`; 6: `collision_with`, `at_fault` and the jerk
/// figures in infos; 7: recordings, `CreateOptions::record`, `RequestBody::Record`, the
/// world in reset and step replies, `world`; 8: `CreateOptions::explain`,
/// `StepReply::explain`; 9: `Render::follow`, `RequestBody::Statistics`; 10:
/// `CreateOptions::render_window`, and a snapshot holds the env's and the world's state as
/// they are, without the scene drivers read; 11: a snapshot's vehicles carry the lanes their
/// bodies are in and the gap behind each as they entered it, and its collisions the
/// lane-entry rule's verdict beside `at_fault`'s; 12: `CreateOptions::info_keys`).
pub const PROTOCOL_VERSION: u16 = 12;

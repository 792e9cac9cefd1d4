//! The wire protocol of highway-arena: every request and reply a client and an
//! `arena-server` exchange over Zenoh, the codec that turns them into bytes, the key
//! expressions they travel on, and the space specs that map one-to-one onto Gymnasium
//! spaces.
//!
//! - [`Request`] / [`Reply`]: envelopes that carry [`PROTOCOL_VERSION`] first, then a
//!   [`RequestBody`] or [`ReplyBody`].
//! - [`encode`] / [`decode`]: the only place bytes are made (bincode 2, standard config,
//!   with a size limit), so the codec is one file to change.
//! - [`keys`]: key-expression builders; nothing else formats keys.
//! - [`Space`]: Box, Discrete and Dict specs, with checks for observations and actions.
//! - [`ErrorReply`]: a coded error, a message for people, and whether the env survives.
//!
//! ```
//! use arena_protocol::{ClientId, PROTOCOL_VERSION, Request, RequestBody, decode, encode};
//! let request = Request { version: PROTOCOL_VERSION, client: ClientId(1), body: RequestBody::ServerInfo };
//! let bytes = encode(&request);
//! assert_eq!(decode::<Request>(&bytes).unwrap(), request);
//! ```
#![warn(missing_docs)]

mod codec;
mod error;
pub mod keys;
mod messages;
#[cfg(feature = "session")]
pub mod session;
mod spaces;

pub use codec::{DecodeError, MAX_MESSAGE_BYTES, decode, encode, peek_version};
pub use error::{ErrorCode, ErrorReply};
pub use messages::*;
pub use spaces::{DType, Space};

/// The protocol version every message carries; bumped on any incompatible change.
pub const PROTOCOL_VERSION: u16 = 1;

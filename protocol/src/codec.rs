//! Bytes <-> messages. bincode 2 (standard config: little-endian, variable-length
//! integers) behind these functions only: bincode is unmaintained (RUSTSEC-2025-0141,
//! informational), so swapping it means changing this file alone.

use std::fmt;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Largest message either side accepts (bytes).
pub const MAX_MESSAGE_BYTES: usize = 16 * 1024 * 1024;

fn config() -> bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Varint,
    bincode::config::Limit<MAX_MESSAGE_BYTES>,
> {
    bincode::config::standard().with_limit::<MAX_MESSAGE_BYTES>()
}

/// Occurs when bytes are not a message of this protocol.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Occurs when the payload is larger than `MAX_MESSAGE_BYTES`.
    TooLarge {
        /// Payload length.
        len: usize,
    },
    /// Occurs when a message decoded but bytes were left over.
    TrailingBytes {
        /// Bytes the message used.
        used: usize,
        /// Bytes received.
        len: usize,
    },
    /// Occurs when the bytes do not decode (truncated, garbage, wrong types).
    Invalid(String),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::TooLarge { len } => {
                write!(f, "message of {len} bytes exceeds the limit of {MAX_MESSAGE_BYTES}")
            }
            DecodeError::TrailingBytes { used, len } => {
                write!(f, "message ends after {used} bytes but {len} were sent; is the other side another version?")
            }
            DecodeError::Invalid(reason) => write!(f, "not a valid message: {reason}"),
        }
    }
}

impl std::error::Error for DecodeError {}

/// Encodes a message. Our own types always serialize, so this cannot fail.
pub fn encode<T: Serialize>(value: &T) -> Vec<u8> {
    bincode::serde::encode_to_vec(value, bincode::config::standard()).unwrap_or_else(|e| {
        // Only reachable through a Serialize impl that errors; ours never do.
        panic!("encoding a protocol message failed: {e}")
    })
}

/// Decodes a whole message, refusing oversized, truncated, trailing and garbage bytes.
pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, DecodeError> {
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(DecodeError::TooLarge { len: bytes.len() });
    }
    let (value, used) =
        bincode::serde::decode_from_slice(bytes, config()).map_err(|e| DecodeError::Invalid(e.to_string()))?;
    if used != bytes.len() {
        return Err(DecodeError::TrailingBytes { used, len: bytes.len() });
    }
    Ok(value)
}

/// The protocol version at the front of an envelope, when the rest does not decode
/// (a message from another version), so the reply can say "wrong version".
pub fn peek_version(bytes: &[u8]) -> Option<u16> {
    bincode::serde::decode_from_slice::<u16, _>(bytes, config()).ok().map(|(version, _)| version)
}

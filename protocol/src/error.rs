//! Errors: the coded error a server replies with, and the local errors of decoding bytes
//! and of building key expressions.

use std::fmt;

use serde::{Deserialize, Serialize};

/// What went wrong, stable across versions: clients branch on these numbers.
///
/// On the wire a code is its number (an enum variant index, which is the declaration
/// order); `as_u16` gives the same number. New codes are only ever appended.
#[repr(u16)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ErrorCode {
    /// 0: the bytes are not a request (garbage, truncated, trailing bytes).
    MalformedRequest = 0,
    /// 1: the request speaks another protocol version.
    WrongVersion = 1,
    /// 2: the request exceeds `MAX_MESSAGE_BYTES`, or one of its strings or lists its
    /// bound (`bounds`).
    PayloadTooLarge = 2,
    /// 3: no env with that id belongs to this client on this server.
    UnknownEnv = 3,
    /// 4: an action names an agent the env does not have.
    UnknownAgent = 4,
    /// 5: an action is outside its space (range, NaN, two actions for one agent).
    InvalidAction = 5,
    /// 6: a meta action for a continuous agent or the other way round.
    WrongActionType = 6,
    /// 7: step, state or render before the first reset.
    NotReset = 7,
    /// 8: the env was closed (by its client, idleness or the client leaving).
    EnvClosed = 8,
    /// 9: the server has no scenario of that name.
    UnknownScenario = 9,
    /// 10: the scenario (file, inline text or overrides) does not validate.
    InvalidScenario = 10,
    /// 11: the server holds its maximum number of envs.
    TooManyEnvs = 11,
    /// 12: a sequence number older than the env's last one.
    StaleSequence = 12,
    /// 13: a bug on the server side.
    Internal = 13,
    /// 14: an action for an agent that finished its episode, or a step with none live.
    AgentNotLive = 14,
    /// 15: a reset option the env does not know (the reset options are
    /// `overrides.<dotted scenario key>`).
    InvalidOption = 15,
    /// The server is shutting down: it answers the requests it had begun and refuses new
    /// ones; its envs end with it.
    ShuttingDown = 16,
    /// 17: a snapshot given to `Restore` is not one this env can take: not a snapshot,
    /// truncated or corrupted, of another protocol version, scenario or env options
    /// (version 7).
    InvalidSnapshot = 17,
}

impl ErrorCode {
    /// Every code, in number order.
    pub const ALL: [ErrorCode; 18] = [
        ErrorCode::MalformedRequest,
        ErrorCode::WrongVersion,
        ErrorCode::PayloadTooLarge,
        ErrorCode::UnknownEnv,
        ErrorCode::UnknownAgent,
        ErrorCode::InvalidAction,
        ErrorCode::WrongActionType,
        ErrorCode::NotReset,
        ErrorCode::EnvClosed,
        ErrorCode::UnknownScenario,
        ErrorCode::InvalidScenario,
        ErrorCode::TooManyEnvs,
        ErrorCode::StaleSequence,
        ErrorCode::Internal,
        ErrorCode::AgentNotLive,
        ErrorCode::InvalidOption,
        ErrorCode::ShuttingDown,
        ErrorCode::InvalidSnapshot,
    ];

    /// The stable number of the code, as on the wire.
    pub fn as_u16(self) -> u16 {
        self as u16
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// An error reply: a code, what happened in words, and whether the env can go on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorReply {
    /// What went wrong.
    pub code: ErrorCode,
    /// What went wrong and what to do, for people.
    pub message: String,
    /// Whether the env this request addressed can still be used.
    pub env_usable: bool,
}

impl fmt::Display for ErrorReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.code, self.message)
    }
}

impl std::error::Error for ErrorReply {}

/// Why bytes are not a message of this protocol.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Occurs when the payload is larger than the limit; nothing was decoded.
    TooLarge {
        /// Payload length (bytes).
        len: usize,
        /// The limit, `MAX_MESSAGE_BYTES`.
        limit: usize,
    },
    /// Occurs when a whole message decoded but bytes were left over, as when the other
    /// side speaks a newer protocol that appended a field.
    TrailingBytes {
        /// Bytes the message used.
        used: usize,
        /// Bytes received.
        len: usize,
    },
    /// Occurs when the bytes do not decode: truncated, garbage, an unknown enum variant,
    /// or lengths that claim more than the limit.
    Invalid(String),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::TooLarge { len, limit } => {
                write!(f, "message too large: {len} bytes, the limit is {limit}")
            }
            DecodeError::TrailingBytes { used, len } => write!(
                f,
                "trailing bytes: the message ends after {used} of {len} bytes (is the sender another protocol version?)"
            ),
            DecodeError::Invalid(reason) => write!(f, "malformed message: {reason}"),
        }
    }
}

impl std::error::Error for DecodeError {}

/// Occurs when a prefix or id cannot be part of a key expression.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyError {
    /// The offending text.
    pub text: String,
    /// Why it cannot be used.
    pub reason: String,
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "'{}' cannot be used in a key expression: {}", self.text, self.reason)
    }
}

impl std::error::Error for KeyError {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{decode, encode};

    #[test]
    fn codes_keep_their_numbers_on_the_wire() {
        for (number, code) in ErrorCode::ALL.into_iter().enumerate() {
            assert_eq!(code.as_u16() as usize, number, "{code}");
            // One-byte varint of the variant index: the wire number is `as_u16`.
            assert_eq!(encode(&code), [number as u8], "{code}");
            assert_eq!(decode::<ErrorCode>(&[number as u8]), Ok(code));
        }
        assert_eq!(ErrorCode::TooManyEnvs.as_u16(), 11);
        assert_eq!(ErrorCode::AgentNotLive.as_u16(), 14);
        assert_eq!(ErrorCode::InvalidOption.as_u16(), 15);
        assert_eq!(ErrorCode::ShuttingDown.as_u16(), 16);
        assert_eq!(ErrorCode::InvalidSnapshot.as_u16(), 17);
        assert!(decode::<ErrorCode>(&[18]).is_err(), "no code 18 yet");
    }

    #[test]
    fn errors_display_what_went_wrong() {
        let reply = ErrorReply { code: ErrorCode::StaleSequence, message: "seq 3 < 4".into(), env_usable: true };
        assert_eq!(reply.to_string(), "StaleSequence: seq 3 < 4");
        assert_eq!(
            DecodeError::TooLarge { len: 20, limit: 10 }.to_string(),
            "message too large: 20 bytes, the limit is 10"
        );
        assert!(DecodeError::TrailingBytes { used: 4, len: 6 }.to_string().starts_with("trailing bytes"));
        assert_eq!(DecodeError::Invalid("x".into()).to_string(), "malformed message: x");
    }
}

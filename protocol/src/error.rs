//! Coded errors a server replies with.

use std::fmt;

use serde::{Deserialize, Serialize};

/// What went wrong, stable across versions: clients branch on these.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ErrorCode {
    /// 0: the bytes are not a request (garbage, truncated, trailing bytes).
    MalformedRequest,
    /// 1: the request speaks another protocol version.
    WrongVersion,
    /// 2: the request exceeds `MAX_MESSAGE_BYTES`.
    PayloadTooLarge,
    /// 3: no env with that id belongs to this client on this server.
    UnknownEnv,
    /// 4: an action names an agent the env does not have.
    UnknownAgent,
    /// 5: an action is outside its space (range, NaN, two actions for one agent).
    InvalidAction,
    /// 6: a meta action for a continuous agent or the other way round.
    WrongActionType,
    /// 7: step, state or render before the first reset.
    NotReset,
    /// 8: the env was closed (by its client, idleness or the client leaving).
    EnvClosed,
    /// 9: the server has no scenario of that name.
    UnknownScenario,
    /// 10: the scenario (file, inline text or overrides) does not validate.
    InvalidScenario,
    /// 11: the server holds its maximum number of envs.
    TooManyEnvs,
    /// 12: a sequence number older than the env's last one.
    StaleSequence,
    /// 13: a bug on the server side.
    Internal,
    /// 14: an action for an agent that finished its episode, or a step with none live.
    AgentNotLive,
}

impl ErrorCode {
    /// The stable number of the code (its declaration index, as on the wire).
    pub fn as_u16(self) -> u16 {
        self as u16
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
        write!(f, "{:?}: {}", self.code, self.message)
    }
}

impl std::error::Error for ErrorReply {}

//! How much a server takes on, and who an env counts against: the server's limits, and
//! the shares of its places each party holds. An open server cannot tell parties apart
//! better than by client id (ids cost nothing); under a site's access control the key a
//! request came on names its user, whom the router vouches for (docs/reliability.md).

use std::collections::HashMap;
use std::time::Duration;

use arena_protocol::{ClientId, ErrorCode, ErrorReply};

/// How much a server takes on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Most envs alive at once.
    pub max_envs: usize,
    /// Most envs one party may hold at once: an authenticated user (the user named by the
    /// key a request came on), else a client id.
    pub max_envs_per_client: usize,
    /// An env nobody touched for this long is closed.
    pub idle_timeout: Duration,
}

/// The most memory one env keeps between requests, by construction (MiB): the largest
/// inline file and its overrides held by the scenario and the episode (24 MiB measured,
/// `worst_requests`), a cached reply with a step's recorded frames (8 MiB) and the jerks
/// of the longest episode (8 MiB, `MAX_AGENT_PERIODS`). The default `max_envs` times this
/// is 20 GiB: within a 24 GiB machine (docs/reliability.md, "Bounded cost").
pub const ENV_KEPT_MIB_AT_MOST: usize = 40;

impl Default for Limits {
    fn default() -> Self {
        Limits { max_envs: 512, max_envs_per_client: 256, idle_timeout: Duration::from_secs(600) }
    }
}

/// How long an env's owner may be without a liveliness token on the server: after its
/// create (the token is on its way), or after the token went (its link dropped, and Zenoh
/// reconnects it); envs of a client without one this long are closed (`reclaim_orphans`).
pub const ORPHAN_GRACE: Duration = Duration::from_secs(3);

/// Who an env counts against in `Limits::max_envs_per_client`: the user a site's access
/// control let the request through as (the last chunk of its key), else its client id.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Party {
    /// A logged-in user.
    User(String),
    /// A client id.
    Client(ClientId),
}

impl Party {
    /// The party of a request from `client` on a key naming `user`.
    pub fn of(user: Option<&str>, client: ClientId) -> Party {
        user.map_or(Party::Client(client), |user| Party::User(user.to_string()))
    }
}

/// How many envs each party holds.
#[derive(Debug, Default)]
pub struct Shares {
    held: HashMap<Party, usize>,
}

impl Shares {
    /// Envs `party` holds.
    pub fn of(&self, party: &Party) -> usize {
        self.held.get(party).copied().unwrap_or(0)
    }

    /// Whether one more env fits a server holding `open` and `party`'s share.
    pub fn room(&self, limits: &Limits, open: usize, party: &Party) -> Result<(), ErrorReply> {
        let refuse = |message: String| Err(ErrorReply { code: ErrorCode::TooManyEnvs, message, env_usable: true });
        if open >= limits.max_envs {
            return refuse(format!(
                "this server holds its limit of {} envs; close one or use another server",
                limits.max_envs
            ));
        }
        if self.of(party) >= limits.max_envs_per_client {
            let who = match party {
                Party::User(user) => format!("user '{user}'"),
                Party::Client(_) => "this client".to_string(),
            };
            return refuse(format!(
                "{who} holds its limit of {} envs on this server (--max-envs-per-client); close one first",
                limits.max_envs_per_client
            ));
        }
        Ok(())
    }

    /// Counts one more env of `party`.
    pub fn take(&mut self, party: &Party) {
        *self.held.entry(party.clone()).or_default() += 1;
    }

    /// Counts one env of `party` as gone.
    pub fn release(&mut self, party: &Party) {
        if let Some(count) = self.held.get_mut(party) {
            *count -= 1;
            if *count == 0 {
                self.held.remove(party);
            }
        }
    }
}

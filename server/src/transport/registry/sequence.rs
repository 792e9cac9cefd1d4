//! What makes retries safe and late requests understood: each env's last mutating reply,
//! kept under its sequence number, and the ids of envs closed recently.

use std::collections::{HashMap, VecDeque};

use arena_protocol::{ClientId, EnvId, ErrorCode, ErrorReply, ReplyBody};

/// An env's last mutating request's sequence number and its reply.
#[derive(Debug, Default)]
pub struct ReplyCache {
    last: Option<(u64, ReplyBody)>,
}

impl ReplyCache {
    /// Runs a mutating request once per sequence number: a retry of the last one gets
    /// the cached reply, an older one is refused; an error the request ends in is its
    /// reply too (a refused step used its `seq`).
    pub fn once(
        &mut self,
        seq: u64,
        run: impl FnOnce() -> Result<ReplyBody, ErrorReply>,
    ) -> Result<ReplyBody, ErrorReply> {
        match &self.last {
            Some((last, cached)) if *last == seq => return Ok(cached.clone()),
            Some((last, _)) if seq < *last => {
                return Err(ErrorReply {
                    code: ErrorCode::StaleSequence,
                    message: format!("sequence number {seq} is older than the last one, {last}"),
                    env_usable: true,
                });
            }
            _ => {}
        }
        let body = run().unwrap_or_else(ReplyBody::Error);
        self.last = Some((seq, body.clone()));
        Ok(body)
    }
}

/// Ids of recently closed envs, so a late request gets `EnvClosed` rather than
/// `UnknownEnv`; bounded, oldest forgotten first, so a long-lived server does not grow.
#[derive(Default)]
pub struct Tombstones {
    owners: HashMap<EnvId, ClientId>,
    order: VecDeque<EnvId>,
}

impl Tombstones {
    const CAPACITY: usize = 1 << 16;

    /// Remembers that `id`, an env of `owner`, was closed.
    pub fn insert(&mut self, id: EnvId, owner: ClientId) {
        if self.owners.insert(id, owner).is_none() {
            self.order.push_back(id);
        }
        while self.order.len() > Self::CAPACITY {
            if let Some(old) = self.order.pop_front() {
                self.owners.remove(&old);
            }
        }
    }

    /// Whether `id` was an env of `client` that has been closed.
    pub fn closed_for(&self, id: &EnvId, client: ClientId) -> bool {
        self.owners.get(id) == Some(&client)
    }
}

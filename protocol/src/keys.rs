//! Key expressions, built here and nowhere else.
//!
//! - `<prefix>/servers/<server_id>`: liveliness token of each server (discovery);
//! - `<prefix>/clients/<client_id>`: liveliness token of each client (a server closes
//!   the envs of a client whose token disappears);
//! - `<prefix>/<server_id>/rpc`: the queryable that answers every `Request`;
//! - `<prefix>/<server_id>/echo`: replies with as many bytes as asked (benchmarks).

use std::fmt;

/// The prefix used when none is given.
pub const DEFAULT_PREFIX: &str = "arena";

/// Occurs when a prefix or id cannot be part of a key expression.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyError {
    /// The offending text.
    pub text: String,
    /// Why it cannot be used.
    pub reason: &'static str,
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "'{}' cannot be used in a key expression: {}", self.text, self.reason)
    }
}

impl std::error::Error for KeyError {}

fn check(text: &str, allow_slash: bool) -> Result<(), KeyError> {
    let fail = |reason| Err(KeyError { text: text.to_string(), reason });
    if text.is_empty() {
        return fail("it is empty");
    }
    if text.contains(['*', '$', '#', '?']) {
        return fail("it contains one of * $ # ?");
    }
    if text.starts_with('/') || text.ends_with('/') || text.contains("//") {
        return fail("it has an empty chunk ('/' at an end or doubled)");
    }
    if !allow_slash && text.contains('/') {
        return fail("ids cannot contain '/'");
    }
    Ok(())
}

/// Checks a prefix (may contain '/').
pub fn check_prefix(prefix: &str) -> Result<(), KeyError> {
    check(prefix, true)
}

fn join(prefix: &str, parts: &[&str]) -> Result<String, KeyError> {
    check_prefix(prefix)?;
    let mut key = prefix.to_string();
    for part in parts {
        check(part, false)?;
        key.push('/');
        key.push_str(part);
    }
    Ok(key)
}

/// `<prefix>/servers/<server_id>`.
pub fn server_liveliness(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &["servers", server_id])
}

/// `<prefix>/servers/*`.
pub fn servers_liveliness_wildcard(prefix: &str) -> Result<String, KeyError> {
    Ok(join(prefix, &["servers"])? + "/*")
}

/// `<prefix>/clients/<client_id>`.
pub fn client_liveliness(prefix: &str, client_id: &str) -> Result<String, KeyError> {
    join(prefix, &["clients", client_id])
}

/// `<prefix>/clients/*`.
pub fn clients_liveliness_wildcard(prefix: &str) -> Result<String, KeyError> {
    Ok(join(prefix, &["clients"])? + "/*")
}

/// `<prefix>/<server_id>/rpc`.
pub fn server_rpc(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &[server_id, "rpc"])
}

/// `<prefix>/<server_id>/echo`.
pub fn server_echo(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &[server_id, "echo"])
}

fn id_after(prefix: &str, kind: &str, key: &str) -> Option<String> {
    let rest = key.strip_prefix(prefix)?.strip_prefix('/')?.strip_prefix(kind)?.strip_prefix('/')?;
    check(rest, false).ok().map(|_| rest.to_string())
}

/// The server id of a `<prefix>/servers/<server_id>` key.
pub fn server_id_from_liveliness(prefix: &str, key: &str) -> Option<String> {
    id_after(prefix, "servers", key)
}

/// The client id of a `<prefix>/clients/<client_id>` key.
pub fn client_id_from_liveliness(prefix: &str, key: &str) -> Option<String> {
    id_after(prefix, "clients", key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builders_and_parsers_agree() {
        assert_eq!(server_liveliness("arena", "ab12").unwrap(), "arena/servers/ab12");
        assert_eq!(server_rpc("site/a", "ab12").unwrap(), "site/a/ab12/rpc");
        assert_eq!(servers_liveliness_wildcard("arena").unwrap(), "arena/servers/*");
        assert_eq!(server_id_from_liveliness("arena", "arena/servers/ab12").as_deref(), Some("ab12"));
        assert_eq!(client_id_from_liveliness("arena", "arena/clients/77").as_deref(), Some("77"));
        assert_eq!(server_id_from_liveliness("arena", "other/servers/ab12"), None);
        assert_eq!(server_id_from_liveliness("arena", "arena/servers/a/b"), None);
    }

    #[test]
    fn bad_prefixes_and_ids_are_refused_with_a_reason() {
        for (prefix, reason) in [("", "empty"), ("a*", "* $ # ?"), ("/a", "empty chunk"), ("a//b", "empty chunk")] {
            let err = server_rpc(prefix, "x").unwrap_err();
            assert!(err.to_string().contains(reason), "{prefix}: {err}");
        }
        assert!(server_rpc("arena", "a/b").unwrap_err().to_string().contains("'/'"));
    }
}

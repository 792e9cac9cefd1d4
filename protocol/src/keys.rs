//! Key expressions, built here and nowhere else.
//!
//! - `<prefix>/servers/<server_id>`: liveliness token of each server (discovery);
//! - `<prefix>/clients/<client_tag>`: liveliness token of each client, under its public
//!   tag (a server closes the envs of a client whose token disappears);
//! - `<prefix>/<server_id>/rpc`: the queryable that answers every `Request`;
//! - `<prefix>/<server_id>/rpc/<user>`: the same, asked by a client logged in as `user`
//!   (a site's access control lets user U ask only on keys ending in `/U`, so the key
//!   names the user the server counts the env against);
//! - `<prefix>/<server_id>/echo`: replies with as many bytes as asked (benchmarks).
//!
//! A prefix is one or more non-empty chunks separated by '/' (`arena`, `site/a`); an id
//! is one chunk. Neither may contain Zenoh's special characters `*`, `$`, `#`, `?`.

use crate::error::KeyError;

/// The prefix used when none is given.
pub const DEFAULT_PREFIX: &str = "arena";

fn check(text: &str, what: &str, allow_slash: bool) -> Result<(), KeyError> {
    let fail = |reason: String| Err(KeyError { text: text.to_string(), reason });
    if text.is_empty() {
        return fail(format!("the {what} is empty"));
    }
    if let Some(c) = text.chars().find(|c| matches!(c, '*' | '$' | '#' | '?')) {
        return fail(format!("the {what} contains '{c}', which Zenoh reserves for wildcards"));
    }
    if !allow_slash && text.contains('/') {
        return fail(format!("the {what} contains '/'; an id is a single chunk"));
    }
    if text.starts_with('/') || text.ends_with('/') || text.contains("//") {
        return fail(format!("the {what} has an empty chunk (a '/' at either end, or '//')"));
    }
    Ok(())
}

/// Checks a prefix: non-empty chunks separated by '/', no `* $ # ?`.
pub fn check_prefix(prefix: &str) -> Result<(), KeyError> {
    check(prefix, "prefix", true)
}

/// Checks an id (server or client): one non-empty chunk, no `/ * $ # ?`.
pub fn check_id(id: &str) -> Result<(), KeyError> {
    check(id, "id", false)
}

fn join(prefix: &str, parts: &[&str]) -> Result<String, KeyError> {
    check_prefix(prefix)?;
    let mut key = prefix.to_string();
    for part in parts {
        check_id(part)?;
        key.push('/');
        key.push_str(part);
    }
    Ok(key)
}

/// `<prefix>/servers/<server_id>`.
pub fn server_liveliness(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &["servers", server_id])
}

/// `<prefix>/servers/*`: every server's liveliness token.
pub fn servers_liveliness_wildcard(prefix: &str) -> Result<String, KeyError> {
    Ok(join(prefix, &["servers"])? + "/*")
}

/// `<prefix>/clients/<client_tag>`.
pub fn client_liveliness(prefix: &str, client_tag: &str) -> Result<String, KeyError> {
    join(prefix, &["clients", client_tag])
}

/// `<prefix>/clients/*`: every client's liveliness token.
pub fn clients_liveliness_wildcard(prefix: &str) -> Result<String, KeyError> {
    Ok(join(prefix, &["clients"])? + "/*")
}

/// `<prefix>/<server_id>/rpc`: the queryable that answers every `Request`.
pub fn server_rpc(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &[server_id, "rpc"])
}

/// `<prefix>/<server_id>/rpc/<user>`: the request key of a client logged in as `user`.
pub fn user_rpc(prefix: &str, server_id: &str, user: &str) -> Result<String, KeyError> {
    join(prefix, &[server_id, "rpc", user])
}

/// `<prefix>/<server_id>/rpc/**`: what the server's queryable is declared on, so it
/// answers `server_rpc` and every `user_rpc`.
pub fn server_rpc_queryable(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    Ok(server_rpc(prefix, server_id)? + "/**")
}

/// The user a request key names (`user_rpc`), `None` for `server_rpc` itself or any
/// other key.
pub fn rpc_user(prefix: &str, server_id: &str, key: &str) -> Option<String> {
    let rest = key.strip_prefix(prefix)?.strip_prefix('/')?.strip_prefix(server_id)?.strip_prefix("/rpc/")?;
    check_id(rest).ok().map(|()| rest.to_string())
}

/// `<prefix>/<server_id>/echo`: raw replies of a requested size, for benchmarks.
pub fn server_echo(prefix: &str, server_id: &str) -> Result<String, KeyError> {
    join(prefix, &[server_id, "echo"])
}

fn id_after(prefix: &str, kind: &str, key: &str) -> Option<String> {
    let rest = key.strip_prefix(prefix)?.strip_prefix('/')?.strip_prefix(kind)?.strip_prefix('/')?;
    check_id(rest).ok().map(|()| rest.to_string())
}

/// The server id of a `<prefix>/servers/<server_id>` key, or `None` for any other key.
pub fn server_id_from_liveliness(prefix: &str, key: &str) -> Option<String> {
    id_after(prefix, "servers", key)
}

/// The client tag of a `<prefix>/clients/<client_tag>` key, or `None` for any other key.
pub fn client_tag_from_liveliness(prefix: &str, key: &str) -> Option<String> {
    id_after(prefix, "clients", key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builders_make_the_documented_keys() {
        assert_eq!(server_liveliness(DEFAULT_PREFIX, "ab12").unwrap(), "arena/servers/ab12");
        assert_eq!(servers_liveliness_wildcard("arena").unwrap(), "arena/servers/*");
        assert_eq!(client_liveliness("arena", "77").unwrap(), "arena/clients/77");
        assert_eq!(clients_liveliness_wildcard("site/a").unwrap(), "site/a/clients/*");
        assert_eq!(server_rpc("site/a", "ab12").unwrap(), "site/a/ab12/rpc");
        assert_eq!(server_echo("arena", "ab12").unwrap(), "arena/ab12/echo");
        assert_eq!(user_rpc("site/a", "ab12", "alice").unwrap(), "site/a/ab12/rpc/alice");
        assert_eq!(server_rpc_queryable("arena", "ab12").unwrap(), "arena/ab12/rpc/**");
        assert!(user_rpc("arena", "ab12", "a/b").is_err() && user_rpc("arena", "ab12", "*").is_err());
    }

    #[test]
    fn the_user_of_a_request_key_is_its_last_chunk_after_rpc() {
        assert_eq!(rpc_user("arena", "ab12", "arena/ab12/rpc/alice").as_deref(), Some("alice"));
        for key in ["arena/ab12/rpc", "arena/ab12/rpc/", "arena/ab12/rpc/a/b", "arena/cd34/rpc/alice", "x/ab12/rpc/a"] {
            assert_eq!(rpc_user("arena", "ab12", key), None, "{key}");
        }
    }

    #[test]
    fn parsers_invert_the_builders_and_refuse_other_keys() {
        let key = server_liveliness("site/a", "ab12").unwrap();
        assert_eq!(server_id_from_liveliness("site/a", &key).as_deref(), Some("ab12"));
        assert_eq!(client_tag_from_liveliness("arena", "arena/clients/77").as_deref(), Some("77"));
        for key in [
            "other/servers/ab12",
            "arenax/servers/ab12",
            "arena/clients/ab12",
            "arena/servers/a/b",
            "arena/servers/",
            "arena/servers",
            "arena/servers/*",
        ] {
            assert_eq!(server_id_from_liveliness("arena", key), None, "{key}");
        }
    }

    #[test]
    fn bad_prefixes_and_ids_are_refused_with_a_reason() {
        for (prefix, reason) in [
            ("", "the prefix is empty"),
            ("a*", "contains '*'"),
            ("a$b", "contains '$'"),
            ("#", "contains '#'"),
            ("a?", "contains '?'"),
            ("/a", "empty chunk"),
            ("a/", "empty chunk"),
            ("a//b", "empty chunk"),
        ] {
            let err = server_rpc(prefix, "x").unwrap_err();
            assert!(err.to_string().contains(reason), "{prefix}: {err}");
            assert_eq!(err.text, prefix);
        }
        for (id, reason) in [("", "the id is empty"), ("a/b", "contains '/'"), ("*", "contains '*'")] {
            let err = server_liveliness("arena", id).unwrap_err();
            assert!(err.to_string().contains(reason), "{id}: {err}");
        }
        assert!(check_prefix("site/a").is_ok() && check_id("0123abcd").is_ok());
    }
}

//! Connection flags shared by the server, the CLI, the Python package and the tests,
//! turned into a `zenoh::Config` in this one place (enabled by the `session` feature).

use std::path::PathBuf;
use std::time::Duration;

/// The endpoint a server listens on and a client connects to when none is given.
pub const DEFAULT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// Seconds each attempt of a call waits for its reply by default, in every client (Rust,
/// CLI, Python); a call that got none is resent `retries` times (default 2).
pub const DEFAULT_TIMEOUT: f64 = 10.0;

/// Seconds a Python client waits for a server to appear when it connects, by default:
/// a loopback port where nothing listens fails within 2 s, session set-up included.
pub const DEFAULT_CONNECT_TIMEOUT: f64 = 1.0;

/// Whether `endpoint` has the form Zenoh needs, `<protocol>/<address>` (metadata and
/// config suffixes allowed), so a typo gets one plain line rather than Zenoh's parser
/// error.
fn is_endpoint(endpoint: &str) -> bool {
    match endpoint.split_once('/') {
        Some((protocol, address)) => {
            protocol.starts_with(|c: char| c.is_ascii_alphabetic())
                && protocol.chars().all(|c| c.is_ascii_alphanumeric() || "_+-".contains(c))
                && !address.is_empty()
                && !address.contains(char::is_whitespace)
        }
        None => false,
    }
}

/// Which side of the connection a process is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Listens on `DEFAULT_ENDPOINT` unless told otherwise.
    Server,
    /// Connects to `DEFAULT_ENDPOINT` unless told otherwise.
    Client,
}

/// Zenoh's session modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Mode {
    /// Talks to other peers directly (the default).
    #[default]
    Peer,
    /// Routes for others (an arena-server can be the router of a site).
    Router,
    /// Talks only through the router or peer it connects to.
    Client,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Router => "router",
            Mode::Client => "client",
        }
    }
}

/// How to reach the Zenoh network.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct ConnectionFlags {
    /// Zenoh session mode [default: peer, or the --zenoh-config file's].
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
    /// Endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable). A server with neither
    /// --listen nor --connect listens on tcp/127.0.0.1:7447, or where its --zenoh-config
    /// file says; a client listens only where told by this flag.
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Endpoint to connect to (repeatable). A client with neither --listen nor --connect
    /// connects to tcp/127.0.0.1:7447.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Key-expression prefix every server and client of one deployment shares.
    #[arg(long, default_value = crate::keys::DEFAULT_PREFIX)]
    pub prefix: String,
    /// A Zenoh configuration file (JSON5: credentials, access control, TLS; see deploy/);
    /// the flags given are applied on top of it.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Turn on multicast and gossip scouting, to find peers on the LAN without endpoints.
    #[arg(long)]
    pub scout: bool,
    /// Seconds a client waits for each reply before retrying.
    #[arg(long, default_value_t = DEFAULT_TIMEOUT, value_name = "SECONDS")]
    pub timeout: f64,
    /// How many times a client resends a request that timed out (steps keep their
    /// sequence number, so a retry never steps twice).
    #[arg(long, default_value_t = 2)]
    pub retries: u32,
}

impl Default for ConnectionFlags {
    fn default() -> Self {
        ConnectionFlags {
            mode: None,
            listen: Vec::new(),
            connect: Vec::new(),
            prefix: crate::keys::DEFAULT_PREFIX.to_string(),
            zenoh_config: None,
            scout: false,
            timeout: DEFAULT_TIMEOUT,
            retries: 2,
        }
    }
}

/// Whether a config file names endpoints to connect to.
fn file_connects(config: &zenoh::Config) -> bool {
    config.get_json("connect/endpoints").is_ok_and(|json| json.contains('/'))
}

/// Access control for a server that is its clients' only meeting point (a peer, the
/// default): every other session may do only what a client does — ask on the servers'
/// `rpc` and `echo` keys, announce itself under `clients/`, look for servers — and
/// nothing else; everything this server sends is allowed. Zenoh applies a rule to a
/// declaration whose key expression the rule's *includes*, so a deny list on the prefix
/// would let `**` or `*/*/rpc` through; an allow list with everything else denied stops
/// every expression that is not one of these. (A router of a site gets its rules from
/// deploy/auth/router.json5.)
pub fn guard_server_keys(config: &mut zenoh::Config, prefix: &str) -> Result<(), String> {
    crate::keys::check_prefix(prefix).map_err(|e| e.to_string())?;
    let rules = format!(
        r#"{{
            enabled: true,
            default_permission: "deny",
            rules: [
                {{ id: "clients-ask", permission: "allow", flows: ["ingress"], messages: ["query"],
                   key_exprs: ["{prefix}/*/rpc", "{prefix}/*/rpc/*", "{prefix}/*/echo"] }},
                {{ id: "clients-announce", permission: "allow", flows: ["ingress"], messages: ["liveliness_token"],
                   key_exprs: ["{prefix}/clients/*"] }},
                {{ id: "clients-find-servers", permission: "allow", flows: ["ingress"],
                   messages: ["liveliness_query", "declare_liveliness_subscriber"], key_exprs: ["{prefix}/servers/*"] }},
                {{ id: "server-speaks", permission: "allow", flows: ["egress"],
                   messages: ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
                              "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"],
                   key_exprs: ["**"] }},
            ],
            subjects: [{{ id: "every-session" }}],
            policies: [{{ rules: ["clients-ask", "clients-announce", "clients-find-servers", "server-speaks"],
                          subjects: ["every-session"] }}],
        }}"#
    );
    config.insert_json5("access_control", &rules).map_err(|e| format!("invalid access control: {e}"))
}

/// The user a Zenoh config logs in as (`transport/auth/usrpwd/user`), if any.
pub fn login_user(config: &zenoh::Config) -> Option<String> {
    let json = config.get_json("transport/auth/usrpwd/user").ok()?;
    let user = json.trim().strip_prefix('"')?.strip_suffix('"')?;
    (!user.is_empty()).then(|| user.to_string())
}

impl ConnectionFlags {
    /// Flags for a client connecting to `endpoint`.
    pub fn connecting_to(endpoint: &str) -> ConnectionFlags {
        ConnectionFlags { connect: vec![endpoint.to_string()], ..ConnectionFlags::default() }
    }

    /// The per-attempt reply timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_secs_f64(if self.timeout.is_finite() && self.timeout > 0.0 {
            self.timeout
        } else {
            DEFAULT_TIMEOUT
        })
    }

    /// The endpoints the session will listen on (server) or connect to (client), as the
    /// flags give them (a server's config file may add its own).
    pub fn endpoints(&self, role: Role) -> Vec<String> {
        match role {
            Role::Server if self.zenoh_config.is_none() && self.listen.is_empty() && self.connect.is_empty() => {
                vec![DEFAULT_ENDPOINT.to_string()]
            }
            Role::Server => self.listen.clone(),
            Role::Client if self.listen.is_empty() && self.connect.is_empty() => vec![DEFAULT_ENDPOINT.to_string()],
            Role::Client => self.connect.clone(),
        }
    }

    /// The Zenoh configuration these flags describe, or what is wrong with them.
    pub fn zenoh_config(&self, role: Role) -> Result<zenoh::Config, String> {
        crate::keys::check_prefix(&self.prefix).map_err(|e| e.to_string())?;
        let mut config = match &self.zenoh_config {
            Some(path) => zenoh::Config::from_file(path)
                .map_err(|e| format!("cannot read Zenoh config {}: {e}", path.display()))?,
            None => zenoh::Config::default(),
        };
        let (mut listen, mut connect) = (self.listen.clone(), self.connect.clone());
        if let Some(bad) = listen.iter().chain(&connect).find(|endpoint| !is_endpoint(endpoint)) {
            return Err(format!("'{bad}' is not a Zenoh endpoint: write PROTOCOL/HOST:PORT, e.g. {DEFAULT_ENDPOINT}"));
        }
        let from_file = self.zenoh_config.is_some();
        if !from_file && listen.is_empty() && connect.is_empty() {
            match role {
                Role::Server => listen.push(DEFAULT_ENDPOINT.to_string()),
                Role::Client => connect.push(DEFAULT_ENDPOINT.to_string()),
            }
        }
        if from_file && role == Role::Client && connect.is_empty() && listen.is_empty() && !file_connects(&config) {
            connect.push(DEFAULT_ENDPOINT.to_string());
        }
        let set = |config: &mut zenoh::Config, key: &str, value: String| {
            config.insert_json5(key, &value).map_err(|e| format!("invalid Zenoh setting {key} = {value}: {e}"))
        };
        let quoted =
            |items: &[String]| format!("[{}]", items.iter().map(|e| format!("{e:?}")).collect::<Vec<_>>().join(","));
        match (self.mode, from_file) {
            (Some(mode), _) => set(&mut config, "mode", format!("{:?}", mode.name()))?,
            (None, false) => set(&mut config, "mode", format!("{:?}", Mode::Peer.name()))?,
            (None, true) => {}
        }
        // A process listens only where it is told: left to Zenoh, a peer listens on every
        // interface and clients connect to each other over them. A client listens only
        // where --listen says, whatever a config file holds; a server keeps its file's
        // endpoints unless --listen replaces them.
        if role == Role::Client || !listen.is_empty() || !from_file {
            set(&mut config, "listen/endpoints", quoted(&listen))?;
        }
        if !connect.is_empty() {
            set(&mut config, "connect/endpoints", quoted(&connect))?;
        }
        set(&mut config, "scouting/multicast/enabled", self.scout.to_string())?;
        // No gossip either: a session talks to the endpoints it was given, not to the
        // peers other sessions know of (--scout turns discovery back on).
        set(&mut config, "scouting/gossip/enabled", self.scout.to_string())?;
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_malformed_endpoint_is_one_plain_line_naming_it_and_the_form() {
        for bad in ["nonsense", "tcp/", "/127.0.0.1:7447", "tcp/127.0.0.1: 7447"] {
            let error = ConnectionFlags::connecting_to(bad).zenoh_config(Role::Client).unwrap_err();
            assert!(error.contains(&format!("'{bad}' is not a Zenoh endpoint")), "{error}");
            assert!(error.contains("e.g. tcp/127.0.0.1:7447") && !error.contains(".rs:"), "{error}");
        }
        assert!(ConnectionFlags::connecting_to("tcp/127.0.0.1:7447").zenoh_config(Role::Client).is_ok());
    }
}

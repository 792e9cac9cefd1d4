//! Zenoh's runtime threads live in the process that started them: a child made by
//! `fork()` inherits the runtime's state without its threads, so a session opened or used
//! there waits for ever. The first process to open a session is recorded here; in any
//! other (a forked child of it) connecting and every call of the blocking client fail at
//! once with `ClientError::Forked`, and dropping a client leaks it rather than waiting on
//! threads that do not exist.

use std::sync::OnceLock;

use crate::{ClientError, Result};

/// The process that started Zenoh's runtime with this copy of the library.
static ZENOH_PROCESS: OnceLock<u32> = OnceLock::new();

/// `Forked` if Zenoh's runtime was started by another process than this one.
pub(crate) fn check() -> Result<()> {
    match ZENOH_PROCESS.get() {
        Some(&parent) if parent != std::process::id() => Err(ClientError::Forked { parent, child: std::process::id() }),
        _ => Ok(()),
    }
}

/// Records this process as Zenoh's, once it may start Zenoh's runtime (`check` passed).
pub(crate) fn starting_zenoh() -> Result<()> {
    check()?;
    ZENOH_PROCESS.get_or_init(std::process::id);
    Ok(())
}

/// Whether this process is a forked child of the one that started Zenoh's runtime (in
/// this copy of the library): then no session can be opened or used here.
pub fn forked() -> bool {
    check().is_err()
}

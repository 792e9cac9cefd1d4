//! The server process's memory: what it holds (for `ServerInfo::rss_bytes`, read by soak
//! runs) and handing back what closed envs and departed sessions freed, to mimalloc, the
//! allocator the `arena-server` binary runs on (its main.rs says why).

/// This process's resident memory (Linux: /proc/self/statm's second field, in pages of
/// 4 KiB); 0 elsewhere.
pub fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    statm.split_whitespace().nth(1).and_then(|pages| pages.parse::<u64>().ok()).map_or(0, |pages| pages * 4096)
}

/// Hands back to the system the memory freed by closed envs and departed sessions, which
/// the allocator would otherwise keep in its per-thread pages for a while.
pub fn return_freed_memory() {
    // SAFETY: mi_collect takes no pointers; it only frees and returns the allocator's
    // unused pages.
    unsafe {
        libmimalloc_sys::mi_collect(true);
    }
}

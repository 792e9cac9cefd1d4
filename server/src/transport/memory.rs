//! The server process's memory: what it holds (for `ServerInfo::rss_bytes`, read by soak
//! runs) and handing back what closed envs and departed sessions freed.

/// This process's resident memory (Linux: /proc/self/statm's second field, in pages of
/// 4 KiB); 0 elsewhere.
pub fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    statm.split_whitespace().nth(1).and_then(|pages| pages.parse::<u64>().ok()).map_or(0, |pages| pages * 4096)
}

/// Hands back to the system the memory freed by closed envs and departed sessions. glibc
/// keeps freed memory in its per-thread arenas, so without this a server's resident size
/// stays near its peak after clients leave.
pub fn return_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim takes no pointers; it only releases free pages of glibc's heaps.
    unsafe {
        libc::malloc_trim(0);
    }
}

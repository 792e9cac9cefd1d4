//! Rust client of highway-arena.

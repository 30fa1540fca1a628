//! What many of these tests share: the command, run as a user runs it.

#![allow(clippy::unwrap_used)] // a test fails by panicking

use std::process::{Command, Output};

/// `lssi ARGS`: its exit status, stdout and stderr.
pub fn lssi(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(args)
        .output()
        .unwrap()
}

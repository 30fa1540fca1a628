//! `lssi defmt -e ELF`: decodes a device's defmt log, as bytes on standard input (QEMU's
//! semihosting output, a probe's RTT dump), with the defmt tables of the firmware's ELF, and
//! prints one line a message (`INFO  lssi firmware up`), as `defmt-print -e ELF` does.
//!
//! It is the decoder `lssi log --elf` and `lssi monitor` use (the defmt-decoder crate), so the
//! firmware's QEMU scripts need no `cargo install defmt-print`: `scripts/ci-qemu.sh` puts
//! it on PATH as `defmt-print` when that is missing.

use std::io::Read;
use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;
use crate::telemetry::defmt::{DefmtLines, Tables};

/// Arguments of `lssi defmt`.
#[derive(Debug, Clone, Args)]
pub struct DefmtArgs {
    /// The firmware's ELF (its defmt tables).
    #[arg(short = 'e', long = "elf", value_name = "ELF")]
    pub elf: PathBuf,
}

/// Decodes standard input until it ends, printing each message once it is whole.
pub fn run(args: &DefmtArgs) -> Result<(), CliError> {
    let tables = Tables::load(&args.elf).map_err(|e| CliError::Input(format!("{e}.")))?;
    let mut lines = DefmtLines::new(Some(&tables));
    let mut stdin = std::io::stdin().lock();
    let mut buf = [0u8; 4096];
    loop {
        let n = match stdin.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                return Err(CliError::Input(format!(
                    "standard input cannot be read after the log so far: {e}."
                )));
            }
        };
        for line in lines.push(&buf[..n]) {
            crate::outln!("{line}");
        }
        crate::output::flush();
    }
}

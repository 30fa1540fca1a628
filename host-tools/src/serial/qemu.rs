//! QEMU as a device: the mps2-an386 board (Cortex-M4) running a firmware image, with its UART
//! on a pty (`lssi replay --qemu`, see [`DeviceProcess::qemu`]) or on a Unix socket
//! (`lssi monitor --qemu`, see [`crate::serial::monitor`]).
//!
//! [`DeviceProcess::qemu`]: crate::serial::device::DeviceProcess::qemu

use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use crate::error::CliError;
use crate::serial::device::find_on_path;

/// The QEMU executable.
pub const PROGRAM: &str = "qemu-system-arm";

/// The QEMU executable on the `PATH`.
pub fn find() -> Option<PathBuf> {
    find_on_path(PROGRAM)
}

/// `program` with the board, no monitor and the firmware's semihosting; the caller adds the
/// instruction count, the image and the UART.
pub fn command(program: &Path) -> Command {
    let mut command = Command::new(program);
    command
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"])
        .args(["-monitor", "none"])
        .args(["-semihosting-config", "enable=on,target=native"]);
    command
}

/// Connects to QEMU's UART socket (QEMU waits for it before starting the guest).
pub fn connect(socket: &Path, child: &mut Child) -> Result<UnixStream, CliError> {
    let started = Instant::now();
    loop {
        if let Ok(stream) = UnixStream::connect(socket) {
            return Ok(stream);
        }
        if let Ok(Some(status)) = child.try_wait() {
            let mut said = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = e.read_to_string(&mut said);
            }
            return Err(CliError::Device(format!(
                "qemu-system-arm exited ({status}) before its UART could be connected: {}.",
                said.trim()
            )));
        }
        if started.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            return Err(CliError::Device(format!(
                "QEMU's UART socket {} did not appear within 20 s.",
                socket.display()
            )));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The exit code of `child`, waiting up to `grace` (then killed: `None`).
pub fn wait(child: &mut Child, grace: Duration) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            return status.code();
        }
        if started.elapsed() > grace {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

//! Where `lssi replay`'s device comes from: `firmware-sim` on a pty, QEMU running the firmware
//! image on a pty, or a real port. The host then opens the pty exactly as it opens a board's
//! port.
//!
//! The child processes are killed when the [`DeviceProcess`] is dropped (after a grace period
//! in which `firmware-sim` exits by itself once the host has closed the port).
//!
//! **Finding `firmware-sim`.** In order: the `LSSI_FIRMWARE_SIM` environment variable (a path),
//! a `firmware-sim` next to the running executable (or one directory up, for a test binary
//! in `target/*/deps`), then the `PATH`. `cargo build --workspace` puts it next to `lssi`.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use crate::serial::qemu;

/// The environment variable that names the `firmware-sim` executable to run.
pub const SIM_ENV: &str = "LSSI_FIRMWARE_SIM";
/// The firmware image `--qemu` runs without `--firmware`, relative to the workspace.
pub const DEFAULT_FIRMWARE: &str =
    "crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-firmware";
/// Probability per byte that firmware-sim inserts a burst before it when `--burst` > 0 (its
/// default `--burst-rate`, which `lssi replay` leaves as it is: one burst per 4 KiB).
pub const BURST_RATE: f64 = 1.0 / 4096.0;
/// The longest burst firmware-sim takes (its `--burst` is a u16).
pub const MAX_BURST: u32 = u16::MAX as u32;
/// How long a child may take to announce its pty.
pub const STARTUP_TIMEOUT: Duration = Duration::from_secs(20);

/// Fault injection and pacing for `firmware-sim`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// The baud rate it paces the pty at.
    pub baud: u32,
    /// Probability per byte, each direction, of flipping one random bit of it
    /// (firmware-sim's `--flip-rate`).
    pub flip_rate: f64,
    /// Probability per byte, each direction, of dropping it (firmware-sim's `--drop-rate`).
    pub drop_rate: f64,
    /// Longest burst of random bytes inserted, each direction, before a byte with probability
    /// [`BURST_RATE`] (0: none; firmware-sim's `--burst`).
    pub burst: u32,
    /// Seed of the faults.
    pub seed: u64,
}

/// Why a device process could not be started.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct StartError(pub String);

/// A child process that plays the device, with the pty it serves.
#[derive(Debug)]
pub struct DeviceProcess {
    child: Child,
    pty: String,
    name: &'static str,
    stdout: Option<ChildStdout>,
    messages: Arc<Mutex<Vec<String>>>,
}

impl DeviceProcess {
    /// The pty to open.
    pub fn pty(&self) -> &str {
        &self.pty
    }

    /// The process id (to kill it in a test).
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// QEMU's standard output (the firmware's semihosting defmt bytes), taken once.
    pub fn take_stdout(&mut self) -> Option<ChildStdout> {
        self.stdout.take()
    }

    /// What the process has said on its stderr so far (firmware-sim's summary line), taken.
    pub fn take_messages(&self) -> Vec<String> {
        self.messages
            .lock()
            .map(|mut lines| std::mem::take(&mut *lines))
            .unwrap_or_default()
    }

    /// Whether the process has exited.
    pub fn exited(&mut self) -> bool {
        !matches!(self.child.try_wait(), Ok(None))
    }

    /// Starts `firmware-sim --pty` and reads the pty it announces (`pty: /dev/pts/N`).
    pub fn firmware_sim(options: &SimOptions) -> Result<Self, StartError> {
        let program = find_firmware_sim().ok_or_else(|| {
            StartError(format!(
                "firmware-sim was found neither next to this executable, nor on the PATH, nor in \
                 ${SIM_ENV}; build it with `cargo build --workspace` (or give --port or --qemu)"
            ))
        })?;
        let mut command = Command::new(&program);
        command
            .arg("--pty")
            .args(["--baud", &options.baud.to_string()])
            .args(["--flip-rate", &options.flip_rate.to_string()])
            .args(["--drop-rate", &options.drop_rate.to_string()])
            .args(["--burst", &options.burst.to_string()])
            .args(["--seed", &options.seed.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            // Its lines go to the telemetry log, not between the progress bar and the result.
            .stderr(Stdio::piped());
        let mut child = command.spawn().map_err(|e| {
            StartError(format!(
                "{}: cannot start firmware-sim: {e}",
                program.display()
            ))
        })?;
        let stdout = child.stdout.take();
        let messages = collect(child.stderr.take());
        let mut process = Self {
            child,
            pty: String::new(),
            name: "firmware-sim",
            stdout: None,
            messages,
        };
        let Some(stdout) = stdout else {
            return Err(StartError("firmware-sim's output could not be read".into()));
        };
        // The first line names the pty; the rest is drained so that the child never blocks.
        let lines = announce(BufReader::new(stdout), |line| {
            line.strip_prefix("pty: ").map(|p| p.trim().to_string())
        });
        process.pty = process.wait_for(lines, "`pty: PATH` on its first line")?;
        Ok(process)
    }

    /// Starts QEMU's mps2-an386 board with `firmware` and reads the pty its UART is on
    /// (`char device redirected to /dev/pts/N (label serial0)`, the first line of its
    /// standard output).
    pub fn qemu(firmware: &Path) -> Result<Self, StartError> {
        if !firmware.is_file() {
            return Err(StartError(format!(
                "{}: the firmware image does not exist; build it (cargo build --release in \
                 crates/lssi-firmware) or give --firmware",
                firmware.display()
            )));
        }
        let program = qemu::find().ok_or_else(|| {
            StartError(
                "qemu-system-arm is not installed (apt-get install qemu-system-arm), so --qemu \
                 cannot run the firmware"
                    .into(),
            )
        })?;
        let mut child = qemu::command(&program)
            .args(["-icount", "shift=0", "-serial", "pty", "-kernel"])
            .arg(firmware)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| StartError(format!("{}: cannot start QEMU: {e}", program.display())))?;
        // QEMU 7 announces the pty on its standard output, before the firmware's semihosting
        // bytes: read that line byte by byte (no buffering past it) on a thread, and hand the
        // pipe back for the defmt bytes that follow.
        let stdout = child.stdout.take();
        let messages = collect(child.stderr.take());
        let mut process = Self {
            child,
            pty: String::new(),
            name: "qemu-system-arm",
            stdout: None,
            messages,
        };
        let Some(mut stdout) = stdout else {
            return Err(StartError("QEMU's output could not be read".into()));
        };
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut line = Vec::new();
            let mut byte = [0u8; 1];
            loop {
                match stdout.read(&mut byte) {
                    Ok(1) if byte[0] == b'\n' => {
                        let text = String::from_utf8_lossy(&line).into_owned();
                        line.clear();
                        let pty = text
                            .split("redirected to ")
                            .nth(1)
                            .and_then(|rest| rest.split_whitespace().next())
                            .map(str::to_string);
                        if let Some(pty) = pty {
                            let _ = tx.send(Ok((pty, stdout)));
                            return;
                        }
                        let _ = tx.send(Err(text));
                    }
                    Ok(1) => line.push(byte[0]),
                    _ => return,
                }
            }
        });
        let started = Instant::now();
        let mut last = String::new();
        loop {
            let left = STARTUP_TIMEOUT.saturating_sub(started.elapsed());
            match rx.recv_timeout(left) {
                Ok(Ok((pty, stdout))) => {
                    process.pty = pty;
                    process.stdout = Some(stdout);
                    return Ok(process);
                }
                Ok(Err(line)) => last = line,
                Err(_) => {
                    let _ = process.child.kill();
                    let _ = process.child.wait();
                    std::thread::sleep(Duration::from_millis(50));
                    if let Some(line) = process.take_messages().pop() {
                        last = line;
                    }
                    let said = if last.is_empty() {
                        String::new()
                    } else {
                        format!("; its last line was {last:?}")
                    };
                    return Err(StartError(format!(
                        "qemu-system-arm was expected to print `char device redirected to \
                         /dev/pts/N`, but it did not within {} s{said}",
                        STARTUP_TIMEOUT.as_secs()
                    )));
                }
            }
        }
    }

    fn wait_for(
        &mut self,
        lines: mpsc::Receiver<Result<String, String>>,
        what: &str,
    ) -> Result<String, StartError> {
        let started = Instant::now();
        let mut last = self.take_messages().pop().unwrap_or_default();
        loop {
            let left = STARTUP_TIMEOUT.saturating_sub(started.elapsed());
            match lines.recv_timeout(left) {
                Ok(Ok(pty)) => return Ok(pty),
                Ok(Err(line)) => last = line,
                Err(_) => {
                    let _ = self.child.kill();
                    let status = self.child.wait().ok();
                    std::thread::sleep(Duration::from_millis(50));
                    if let Some(line) = self.take_messages().pop() {
                        last = line;
                    }
                    let why = match status {
                        Some(status) if started.elapsed() < STARTUP_TIMEOUT => {
                            format!("exited ({status})")
                        }
                        _ => format!("did not print it within {} s", STARTUP_TIMEOUT.as_secs()),
                    };
                    let said = if last.is_empty() {
                        String::new()
                    } else {
                        format!("; its last line was {last:?}")
                    };
                    return Err(StartError(format!(
                        "{} was expected to print {what}, but it {why}{said}",
                        self.name
                    )));
                }
            }
        }
    }

    /// Waits up to `grace` for the process to exit by itself, then kills it; returns what it
    /// said on stderr.
    pub fn finish(mut self, grace: Duration) -> Vec<String> {
        let started = Instant::now();
        while started.elapsed() < grace && !self.exited() {
            std::thread::sleep(Duration::from_millis(10));
        }
        if !self.exited() {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
        // Its stderr ends with it; give the collecting thread a moment to read the last line.
        std::thread::sleep(Duration::from_millis(20));
        self.take_messages()
    }
}

impl Drop for DeviceProcess {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

/// Collects the lines of a child's stderr on a thread.
fn collect(stderr: Option<std::process::ChildStderr>) -> Arc<Mutex<Vec<String>>> {
    let lines = Arc::new(Mutex::new(Vec::new()));
    if let Some(stderr) = stderr {
        let sink = Arc::clone(&lines);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines() {
                let Ok(line) = line else { break };
                if let Ok(mut lines) = sink.lock() {
                    lines.push(line);
                }
            }
        });
    }
    lines
}

/// Reads `source` line by line on a thread: sends `Ok(value)` for the first line `parse`
/// accepts, `Err(line)` for the lines before it, then drains the rest.
fn announce<R: Read + Send + 'static>(
    source: BufReader<R>,
    parse: impl Fn(&str) -> Option<String> + Send + 'static,
) -> mpsc::Receiver<Result<String, String>> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut found = false;
        for line in source.lines() {
            let Ok(line) = line else { break };
            if found {
                continue;
            }
            match parse(&line) {
                Some(value) => {
                    found = true;
                    let _ = tx.send(Ok(value));
                }
                None => {
                    let _ = tx.send(Err(line));
                }
            }
        }
    });
    rx
}

/// The `firmware-sim` to run; see the module docs for the order.
pub fn find_firmware_sim() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os(SIM_ENV).filter(|p| !p.is_empty()) {
        return Some(PathBuf::from(path));
    }
    let name = format!("firmware-sim{}", std::env::consts::EXE_SUFFIX);
    if let Ok(exe) = std::env::current_exe() {
        let mut dir = exe.parent();
        for _ in 0..2 {
            let Some(d) = dir else { break };
            let candidate = d.join(&name);
            if candidate.is_file() {
                return Some(candidate);
            }
            dir = d.parent();
        }
    }
    find_on_path(&name)
}

/// The first `name` in a directory of the `PATH`.
pub fn find_on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|candidate| candidate.is_file())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_firmware_image_is_named() {
        let error = DeviceProcess::qemu(Path::new("/nonexistent/lssi-firmware")).unwrap_err();
        assert!(
            error
                .0
                .starts_with("/nonexistent/lssi-firmware: the firmware image does not exist")
        );
    }

    #[test]
    fn announcements_are_parsed_from_the_first_matching_line() {
        let text = "qemu-system-arm: warning: x\nchar device redirected to /dev/pts/7 (label serial0)\nmore\n";
        let rx = announce(BufReader::new(text.as_bytes()), |line| {
            let rest = line.split("redirected to ").nth(1)?;
            rest.split_whitespace().next().map(str::to_string)
        });
        assert_eq!(
            rx.recv().unwrap(),
            Err("qemu-system-arm: warning: x".into())
        );
        assert_eq!(rx.recv().unwrap(), Ok("/dev/pts/7".into()));
    }
}

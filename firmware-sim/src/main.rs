//! firmware-sim: the lssi device application (`lssi-device`, f32, the firmware's capacities)
//! behind a simulated serial link — a pseudo-terminal or stdin/stdout — paced at a baud rate,
//! with seeded faults on both directions. See README.md for the contract.
//!
//! Three threads: the receiver reads the host's bytes, damages and paces them, and hands
//! them to the device; the device thread runs `Device::poll` exactly as the firmware's main
//! loop does; the transmitter damages, paces and writes the device's frames.

mod faults;

use clap::Parser;
use faults::{DEFAULT_BURST_RATE, Faults, Injector, Pacer};
use lssi_device::{CostMeter, CostUnit, Device, Transport};
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::process::ExitCode;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::thread;
use std::time::{Duration, Instant};

/// Runs the lssi device application behind a simulated serial link.
#[derive(Parser, Debug)]
#[command(name = "firmware-sim", version, about)]
struct Cli {
    /// Serve on a new pseudo-terminal and print `pty: PATH` as the only line on stdout (the default).
    #[arg(long, conflicts_with = "stdio")]
    pty: bool,
    /// Serve on stdin (host → device) and stdout (device → host) instead of a pty.
    #[arg(long)]
    stdio: bool,
    /// Line rate in bits per second, 8N1: baud/10 bytes per second in each direction.
    #[arg(long, value_name = "N", default_value_t = 921_600, value_parser = parse_baud, allow_hyphen_values = true)]
    baud: u32,
    /// Probability per byte, each direction, of flipping one random bit of it.
    #[arg(long, value_name = "R", default_value_t = 0.0, value_parser = parse_rate, allow_hyphen_values = true)]
    flip_rate: f64,
    /// Probability per byte, each direction, of dropping it.
    #[arg(long, value_name = "R", default_value_t = 0.0, value_parser = parse_rate, allow_hyphen_values = true)]
    drop_rate: f64,
    /// Insert bursts of 1..=N random bytes, each direction (0: none); see --burst-rate.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = parse_burst, allow_hyphen_values = true)]
    burst: u16,
    /// Probability per byte that a burst starts before it (default 1/4096).
    #[arg(long, value_name = "R", default_value_t = DEFAULT_BURST_RATE, value_parser = parse_rate, allow_hyphen_values = true)]
    burst_rate: f64,
    /// Seed of the fault pattern (each direction draws from its own stream).
    #[arg(long, value_name = "S", default_value_t = 1, value_parser = parse_seed, allow_hyphen_values = true)]
    seed: u64,
}

fn parse_rate(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if (0.0..=1.0).contains(&r) => Ok(r),
        _ => Err("expected a probability per byte between 0 and 1".into()),
    }
}

fn parse_burst(text: &str) -> Result<u16, String> {
    text.parse::<u16>()
        .map_err(|_| "expected a burst length between 0 and 65535 bytes".into())
}

fn parse_seed(text: &str) -> Result<u64, String> {
    text.parse::<u64>()
        .map_err(|_| "expected a whole number between 0 and 2^64 - 1".into())
}

fn parse_baud(text: &str) -> Result<u32, String> {
    match text.parse::<u32>() {
        Ok(b) if b > 0 => Ok(b),
        _ => Err("expected a positive whole number of bits per second".into()),
    }
}

/// What a direction of the link tells the device thread.
enum Rx {
    /// Bytes that came through the line.
    Bytes(Vec<u8>),
    /// The host closed its end (EOF or hangup).
    Closed,
}

/// Wall-clock nanoseconds: what a host process can measure.
struct WallClock;

impl CostMeter for WallClock {
    fn unit(&self) -> CostUnit {
        CostUnit::Nanoseconds
    }

    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        let start = Instant::now();
        let result = f();
        let nanos = start.elapsed().as_nanos();
        (result, u32::try_from(nanos).unwrap_or(u32::MAX))
    }
}

/// The link closed under the device.
#[derive(Debug)]
struct Closed;

/// The device's side of the simulated line: the platform's `Transport`.
struct SimLink {
    rx: Receiver<Rx>,
    pending: Vec<u8>,
    taken: usize,
    closed: bool,
    tx: Sender<Vec<u8>>,
}

impl SimLink {
    /// Blocks until bytes arrive (or `timeout` passes); a firmware would `wfi` here.
    fn wait(&mut self, timeout: Duration) {
        if self.taken < self.pending.len() || self.closed {
            return;
        }
        match self.rx.recv_timeout(timeout) {
            Ok(Rx::Bytes(bytes)) => self.stash(bytes),
            Ok(Rx::Closed) | Err(RecvTimeoutError::Disconnected) => self.closed = true,
            Err(RecvTimeoutError::Timeout) => {}
        }
    }

    fn stash(&mut self, bytes: Vec<u8>) {
        self.pending = bytes;
        self.taken = 0;
    }
}

impl Transport for SimLink {
    type Error = Closed;

    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Closed> {
        if self.taken >= self.pending.len() {
            match self.rx.try_recv() {
                Ok(Rx::Bytes(bytes)) => self.stash(bytes),
                Ok(Rx::Closed) | Err(TryRecvError::Disconnected) => self.closed = true,
                Err(TryRecvError::Empty) => {}
            }
        }
        let rest = self.pending.get(self.taken..).unwrap_or(&[]);
        if rest.is_empty() && self.closed {
            return Err(Closed);
        }
        let n = rest.len().min(buf.len());
        if let (Some(dst), Some(src)) = (buf.get_mut(..n), rest.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.taken += n;
        Ok(n)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Closed> {
        self.tx.send(bytes.to_vec()).map_err(|_| Closed)
    }
}

/// Host → device: read, damage, pace, deliver. Ends at EOF or on an error (hangup).
fn receiver(mut input: impl Read, mut injector: Injector, mut pacer: Pacer, to_device: Sender<Rx>) {
    let mut buffer = vec![0u8; pacer.slice()];
    let mut damaged = Vec::new();
    loop {
        let n = match input.read(&mut buffer) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        let Some(read) = buffer.get(..n) else { break };
        damaged.clear();
        injector.apply(read, &mut damaged);
        // The line carries the damaged stream (bursts take line time, drops none).
        pacer.wait(damaged.len());
        if to_device.send(Rx::Bytes(damaged.clone())).is_err() {
            return;
        }
    }
    let _ = to_device.send(Rx::Closed);
}

/// Device → host: damage, pace in slices of about a millisecond, write.
/// Ends when the device thread hangs up or the host stops reading; then says so on `done`.
fn transmitter(
    mut output: impl Write,
    mut injector: Injector,
    mut pacer: Pacer,
    from_device: Receiver<Vec<u8>>,
    done: Sender<()>,
) {
    transmit(&mut output, &mut injector, &mut pacer, &from_device);
    let _ = done.send(());
}

fn transmit(
    output: &mut impl Write,
    injector: &mut Injector,
    pacer: &mut Pacer,
    from_device: &Receiver<Vec<u8>>,
) {
    let slice = pacer.slice();
    let mut damaged = Vec::new();
    while let Ok(frame) = from_device.recv() {
        damaged.clear();
        injector.apply(&frame, &mut damaged);
        for piece in damaged.chunks(slice) {
            pacer.wait(piece.len());
            if output
                .write_all(piece)
                .and_then(|()| output.flush())
                .is_err()
            {
                return;
            }
        }
    }
}

/// A pseudo-terminal in raw mode, its slave side closed until the host opens it.
struct Pty {
    master: File,
    path: std::path::PathBuf,
}

fn open_pty() -> nix::Result<Pty> {
    use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};
    let pair = nix::pty::openpty(None, None)?;
    // Raw (no echo, no line editing, 8 bits) before the host ever sees it.
    let mut termios = tcgetattr(pair.slave.as_fd())?;
    cfmakeraw(&mut termios);
    tcsetattr(pair.slave.as_fd(), SetArg::TCSANOW, &termios)?;
    let path = nix::unistd::ttyname(pair.slave.as_fd())?;
    drop(pair.slave);
    Ok(Pty {
        master: File::from(pair.master),
        path,
    })
}

/// Waits until the host has opened the pty (the master no longer reports a hangup, or has
/// bytes). Returns false if the master fails.
fn wait_for_host(master: &File) -> bool {
    use nix::poll::{PollFd, PollFlags, poll};
    loop {
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        match poll(&mut fds, 100u16) {
            Ok(_) => {
                let events = fds[0].revents().unwrap_or(PollFlags::empty());
                if events.contains(PollFlags::POLLIN) || !events.contains(PollFlags::POLLHUP) {
                    return true;
                }
                // No slave open yet: poll returns at once with POLLHUP, so pause.
                thread::sleep(Duration::from_millis(20));
            }
            Err(nix::errno::Errno::EINTR) => {}
            Err(_) => return false,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let faults = Faults {
        flip_rate: cli.flip_rate,
        drop_rate: cli.drop_rate,
        burst: cli.burst,
        burst_rate: cli.burst_rate,
    };
    // Independent streams per direction: the pattern depends on the seed, not on timing.
    let host_to_device = Injector::new(faults, cli.seed ^ 0x5EED_0000_0000_0001);
    let device_to_host = Injector::new(faults, cli.seed ^ 0x5EED_0000_0000_0002);

    let (rx_send, rx_recv) = mpsc::channel();
    let (tx_send, tx_recv) = mpsc::channel();
    let (done_send, done_recv) = mpsc::channel();
    let baud = cli.baud;
    if cli.stdio {
        thread::spawn(move || {
            receiver(std::io::stdin(), host_to_device, Pacer::new(baud), rx_send);
        });
        thread::spawn(move || {
            let out = std::io::stdout();
            transmitter(out, device_to_host, Pacer::new(baud), tx_recv, done_send);
        });
    } else {
        let pty = match open_pty() {
            Ok(pty) => pty,
            Err(error) => {
                eprintln!("firmware-sim: cannot open a pseudo-terminal: {error}.");
                return ExitCode::FAILURE;
            }
        };
        let writer = match pty.master.try_clone() {
            Ok(writer) => writer,
            Err(error) => {
                eprintln!("firmware-sim: cannot duplicate the pty's descriptor: {error}.");
                return ExitCode::FAILURE;
            }
        };
        let mut stdout = std::io::stdout().lock();
        if writeln!(stdout, "pty: {}", pty.path.display())
            .and_then(|()| stdout.flush())
            .is_err()
        {
            return ExitCode::FAILURE;
        }
        drop(stdout);
        let master = pty.master;
        thread::spawn(move || {
            if wait_for_host(&master) {
                receiver(master, host_to_device, Pacer::new(baud), rx_send);
            } else {
                let _ = rx_send.send(Rx::Closed);
            }
        });
        thread::spawn(move || {
            transmitter(writer, device_to_host, Pacer::new(baud), tx_recv, done_send);
        });
    }

    let mut device: Box<Device> = Box::new(Device::new());
    let mut link = SimLink {
        rx: rx_recv,
        pending: Vec::new(),
        taken: 0,
        closed: false,
        tx: tx_send,
    };
    let mut meter = WallClock;
    loop {
        match device.poll(&mut link, &mut meter) {
            Ok(0) => link.wait(Duration::from_millis(50)),
            Ok(_) => {}
            Err(Closed) => break,
        }
    }
    // Let the replies already queued reach a host that still reads (a `--stdio` host may
    // close its output first), but never hang on one that does not.
    drop(link);
    let _ = done_recv.recv_timeout(Duration::from_secs(5));
    let stats = device.stats();
    eprintln!(
        "firmware-sim: the host closed the link; {} frames decoded, {} dropped for CRC/COBS, {} duplicate batches.",
        stats.frames_ok, stats.crc_errors, stats.duplicates
    );
    ExitCode::SUCCESS
}

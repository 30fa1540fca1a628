//! firmware-sim end to end: the binary on stdio and on a faulty pty, driven like a host.

use lssi_core::{Config, Identifier, Sample};
use lssi_device::wire::{config_to_wire, snapshot};
use lssi_device::{DEFAULT_TERMS, DEFAULT_WINDOW};
use lssi_proto::{
    CONTROL_SEQ, Channels, DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_BATCH, ModelSnapshot,
    PROTOCOL_VERSION, SampleBatch, SnapshotCause, WireSample, write_frame,
};
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_firmware-sim");

/// A host: writes frames, decodes replies from a reader thread, retries on timeouts.
struct Host<W: Write> {
    out: W,
    replies: Receiver<DeviceMsg>,
}

/// Decodes `input` on a thread. A read of 0 bytes ends it, unless `stop` is given: then
/// it is a read timeout, and the thread ends once `stop` is set.
fn spawn_reader(
    mut input: impl Read + Send + 'static,
    stop: Option<Arc<AtomicBool>>,
) -> (Receiver<DeviceMsg>, JoinHandle<()>) {
    let (send, recv) = mpsc::channel();
    let handle = std::thread::spawn(move || {
        let mut decoder = DeviceFrameDecoder::new();
        let mut buffer = [0u8; 256];
        while let Ok(n) = input.read(&mut buffer) {
            if n == 0 {
                match &stop {
                    Some(stop) if !stop.load(Ordering::Relaxed) => continue,
                    _ => break,
                }
            }
            for message in decoder.feed::<DeviceMsg>(&buffer[..n]).flatten() {
                if send.send(message).is_err() {
                    return;
                }
            }
        }
    });
    (recv, handle)
}

impl<W: Write> Host<W> {
    /// Sends `message` until a reply satisfies `accept`; returns every reply seen meanwhile.
    fn request(
        &mut self,
        message: &HostMsg,
        accept: impl Fn(&DeviceMsg) -> bool,
    ) -> Vec<DeviceMsg> {
        let mut seen = Vec::new();
        for _ in 0..100 {
            // A leading 0x00 flushes any half frame a fault left in the device's decoder.
            self.out.write_all(&[0]).expect("write");
            write_frame(&mut self.out, message).expect("write");
            self.out.flush().expect("flush");
            let deadline = Instant::now() + Duration::from_millis(300);
            while let Some(left) = deadline.checked_duration_since(Instant::now()) {
                match self.replies.recv_timeout(left) {
                    Ok(reply) => {
                        let done = accept(&reply);
                        seen.push(reply);
                        if done {
                            return seen;
                        }
                    }
                    Err(_) => break,
                }
            }
        }
        panic!("no accepted reply to {message:?} after 100 tries; saw {seen:?}");
    }
}

/// x'' = -400 x - 2 x' - 4e4 x³ + 60 cos(15 t), RK4, 1 kHz samples.
fn duffing(n: usize) -> Vec<(f64, f32)> {
    lssi_testkit::duffing(n)
        .into_iter()
        .map(|p| (p.t, p.x as f32))
        .collect()
}

fn config() -> Config {
    Config {
        sample_period: 1e-3,
        window: 31,
        omega: 15.0,
        screening_period: 1_000,
        ..Config::default()
    }
}

fn batches(samples: &[(f64, f32)]) -> Vec<SampleBatch> {
    samples
        .chunks(MAX_BATCH)
        .zip(0..)
        .map(|(chunk, seq)| {
            let mut batch = SampleBatch::new(seq, Channels::X);
            for &(t, x) in chunk {
                batch
                    .push(WireSample {
                        t,
                        x,
                        v: None,
                        u: None,
                    })
                    .expect("room");
            }
            batch
        })
        .collect()
}

/// What `lssi identify --f32 --no-refine` computes for the same samples and configuration.
fn direct(samples: &[(f64, f32)]) -> ModelSnapshot {
    let mut id: Identifier<f32, DEFAULT_WINDOW, DEFAULT_TERMS> =
        Identifier::new(config()).expect("valid");
    for &(t, x) in samples {
        let _ = id.push(Sample {
            t,
            x,
            v: None,
            u: None,
        });
    }
    id.screen();
    snapshot(id.model().expect("a model"), SnapshotCause::Query).expect("fits")
}

/// Handshake, configure, every batch exactly once, query: the final snapshot and health.
fn session<W: Write>(host: &mut Host<W>, samples: &[(f64, f32)]) -> (ModelSnapshot, DeviceMsg) {
    let hello = HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
    };
    host.request(&hello, |m| {
        matches!(
            m,
            DeviceMsg::HelloReply {
                protocol_version: PROTOCOL_VERSION,
                ..
            }
        )
    });
    let configure = HostMsg::Configure(config_to_wire(&config()).expect("fits"));
    host.request(&configure, |m| *m == DeviceMsg::Ack { seq: CONTROL_SEQ });
    for batch in batches(samples) {
        let seq = batch.seq;
        host.request(&HostMsg::Samples(batch), |m| *m == DeviceMsg::Ack { seq });
    }
    let mut model = None;
    loop {
        let seen = host.request(&HostMsg::Query, |m| matches!(m, DeviceMsg::Health { .. }));
        for reply in &seen {
            if let DeviceMsg::Model(m) = reply
                && m.cause == SnapshotCause::Query
            {
                model = Some(m.clone());
            }
        }
        if let (Some(model), Some(health)) = (&model, seen.last()) {
            return (model.clone(), health.clone());
        }
    }
}

fn health_samples(health: &DeviceMsg) -> u64 {
    match health {
        DeviceMsg::Health { samples, .. } => *samples,
        other => panic!("expected Health, got {other:?}"),
    }
}

fn wait_exit(child: &mut Child) -> i32 {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            return status.code().unwrap_or(-1);
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("firmware-sim did not exit after the host closed the link");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn stdio_session_matches_the_direct_identifier() {
    let mut child = Command::new(BIN)
        .args(["--stdio", "--baud", "921600"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn firmware-sim");
    let (replies, _reader) = spawn_reader(child.stdout.take().expect("stdout"), None);
    let mut host = Host {
        out: child.stdin.take().expect("stdin"),
        replies,
    };
    let samples = duffing(3_000);
    let (model, health) = session(&mut host, &samples);
    assert_eq!(health_samples(&health), samples.len() as u64);
    assert_eq!(model, direct(&samples));
    drop(host);
    assert_eq!(wait_exit(&mut child), 0);
}

#[test]
fn faulty_pty_session_applies_every_sample_exactly_once() {
    let mut child = Command::new(BIN)
        .args([
            "--flip-rate",
            "0.0005",
            "--drop-rate",
            "0.0005",
            "--burst",
            "6",
            "--burst-rate",
            "0.0005",
            "--seed",
            "3",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn firmware-sim");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("first line");
    let path = line
        .trim_end()
        .strip_prefix("pty: ")
        .expect("`pty: PATH`")
        .to_string();
    let port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .expect("open pty");
    let mut termios = nix::sys::termios::tcgetattr(&port).expect("termios");
    nix::sys::termios::cfmakeraw(&mut termios);
    // Reads time out after 0.1 s, so that the reader thread can be stopped.
    termios.control_chars[nix::sys::termios::SpecialCharacterIndices::VMIN as usize] = 0;
    termios.control_chars[nix::sys::termios::SpecialCharacterIndices::VTIME as usize] = 1;
    nix::sys::termios::tcsetattr(&port, nix::sys::termios::SetArg::TCSANOW, &termios).expect("raw");
    let stop = Arc::new(AtomicBool::new(false));
    let (replies, reader) = spawn_reader(port.try_clone().expect("clone"), Some(stop.clone()));
    let mut host = Host { out: port, replies };
    let samples = duffing(3_000);
    let (model, health) = session(&mut host, &samples);
    assert_eq!(health_samples(&health), samples.len() as u64);
    assert_eq!(model, direct(&samples));
    let DeviceMsg::Health {
        crc_errors,
        duplicates,
        ..
    } = health
    else {
        unreachable!()
    };
    eprintln!("faults seen by the device: {crc_errors} bad frames, {duplicates} duplicates");
    assert!(crc_errors > 0, "the faults were injected");
    // Close every descriptor of the pty's slave side: the hangup ends the simulator.
    stop.store(true, Ordering::Relaxed);
    reader.join().expect("reader");
    drop(host);
    assert_eq!(wait_exit(&mut child), 0);
}

#[test]
fn bad_flags_exit_2_naming_the_flag() {
    for (args, flag) in [
        (&["--drop-rate", "1.5"][..], "--drop-rate"),
        (&["--flip-rate", "x"][..], "--flip-rate"),
        (&["--baud", "0"][..], "--baud"),
        (&["--burst", "-1"][..], "--burst"),
        (&["--burst", "70000"][..], "--burst"),
        (&["--burst-rate", "nan"][..], "--burst-rate"),
        (&["--seed", "s"][..], "--seed"),
        (&["--stdio", "--pty"][..], "--pty"),
    ] {
        let output = Command::new(BIN).args(args).output().expect("run");
        assert_eq!(output.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(output.stdout.is_empty());
    }
}

//! The link client against the real device code (`lssi_device::Device`) in this process,
//! over a socket pair with faults injected on the way to the device: the bundled recording
//! replayed over the link gives exactly `lssi identify --f32 --no-refine`'s report, whatever the faults,
//! and a device that goes away gives an error naming the port with the log intact.
//!
//! firmware-sim does the same over a pty in `tests/tests/replay.rs` and `replay_cli.rs`; here
//! the faults are chosen per frame, so each test is deterministic and independent of the
//! simulator.

#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;
use std::time::Duration;

use lssi_device::{Device, NoCost, Transport};
use lssi_host::identify::identify_recording;
use lssi_host::identify::{self, Options};
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::serial::link::{Link, LinkError, LinkOptions, Quiet};
use lssi_host::serial::replay::{ReplayError, replay_over};
use lssi_host::telemetry::{RecordKind, TelemetryLog, read_log};

fn bundled() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/paper-eq17.csv")
}

/// What happens to the frames going to the device.
#[derive(Clone, Copy, Debug, Default)]
struct Faults {
    /// Drop every n-th frame (0: none).
    drop_every: u64,
    /// Flip one bit of every n-th frame (0: none).
    flip_every: u64,
    /// Drop this many frames in a row once, starting at frame `burst_at`.
    burst: u64,
    burst_at: u64,
    /// Stop (close the link) after this many frames (0: never).
    die_after: u64,
}

/// The device's end of the socket, as its transport.
struct Socket(UnixStream);

impl Transport for Socket {
    type Error = std::io::Error;

    fn read(&mut self, _buf: &mut [u8]) -> Result<usize, Self::Error> {
        Ok(0)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write_all(bytes)
    }
}

/// Runs a device with window capacity `W` and `C` channel rings on `stream` until the host
/// closes it.
fn device<const W: usize, const C: usize>(stream: UnixStream, faults: Faults) -> JoinHandle<()> {
    std::thread::Builder::new()
        .stack_size(8 << 20)
        .spawn(move || {
            let mut device: Box<Device<W, 24, C>> = Box::new(Device::new());
            let mut reader = stream.try_clone().unwrap();
            let mut link = Socket(stream);
            let mut frame = Vec::new();
            let mut index = 0u64;
            let mut buffer = [0u8; 4096];
            loop {
                let n = match reader.read(&mut buffer) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                for &byte in &buffer[..n] {
                    frame.push(byte);
                    if byte != 0 {
                        continue;
                    }
                    index += 1;
                    if faults.die_after > 0 && index > faults.die_after {
                        return;
                    }
                    let burst = faults.burst > 0
                        && (faults.burst_at..faults.burst_at + faults.burst).contains(&index);
                    let drop =
                        burst || (faults.drop_every > 0 && index.is_multiple_of(faults.drop_every));
                    if faults.flip_every > 0
                        && index.is_multiple_of(faults.flip_every)
                        && frame.len() > 2
                    {
                        let at = (index as usize * 7) % (frame.len() - 1);
                        frame[at] ^= 1 << (index % 8);
                    }
                    if !drop && device.receive(&frame, &mut link, &mut NoCost).is_err() {
                        return;
                    }
                    frame.clear();
                }
            }
        })
        .unwrap()
}

struct Outcome {
    result: Result<lssi_host::serial::replay::ReplayReport, ReplayError>,
    log: PathBuf,
    _dir: tempfile::TempDir,
}

fn replay<const W: usize>(recording: &Recording, faults: Faults) -> Outcome {
    replay_to::<W, 3>(recording, faults)
}

fn replay_to<const W: usize, const C: usize>(recording: &Recording, faults: Faults) -> Outcome {
    let (config, estimated) = identify::configure(recording, &Options::default()).unwrap();
    let (host, far) = UnixStream::pair().unwrap();
    let device = device::<W, C>(far, faults);
    host.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("replay.tlm");
    let mut log = TelemetryLog::open(&path).unwrap();
    let mut quiet = Quiet;
    let mut options = LinkOptions::for_baud(921_600);
    options.silence = Duration::from_secs(5);
    let result = {
        let mut link = Link::new(
            "socket",
            Box::new(host.try_clone().unwrap()),
            Box::new(host.try_clone().unwrap()),
            &mut log,
            &mut quiet,
            options,
        );
        replay_over(&mut link, recording, &config, estimated)
    };
    host.shutdown(std::net::Shutdown::Both).unwrap();
    device.join().unwrap();
    Outcome {
        result,
        log: path,
        _dir: dir,
    }
}

fn identify_f32(recording: &Recording) -> identify::Report {
    identify_recording(recording, &Options::default()).unwrap()
}

#[test]
fn a_clean_link_reproduces_identify_f32_exactly() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let outcome = replay::<1023>(&recording, Faults::default());
    let report = outcome.result.unwrap();
    assert_eq!(report.report, identify_f32(&recording));
    assert_eq!(report.link.samples_lost, 0);
    assert_eq!(report.link.retransmits, 0);
    assert_eq!(report.link.samples_acked, recording.len() as u64);
    // Every frame the device sent is in the log, after the one session note-free run.
    let contents = read_log(&std::fs::read(&outcome.log).unwrap()).unwrap();
    assert!(contents.partial_tail.is_none());
    let frames = contents
        .records
        .iter()
        .filter(|r| r.kind == RecordKind::Frame)
        .count();
    // hello, configure, one ack per batch, model and health at least.
    assert!(frames >= recording.len() / 24 + 4, "{frames} frames logged");
    assert_eq!(contents.records.last().unwrap().kind, RecordKind::Summary);
}

#[test]
fn drops_flips_and_a_burst_change_nothing_and_lose_nothing() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let faults = Faults {
        drop_every: 37,
        flip_every: 23,
        burst: 12,
        burst_at: 300,
        die_after: 0,
    };
    let report = replay::<1023>(&recording, faults).result.unwrap();
    assert_eq!(report.report, identify_f32(&recording));
    assert_eq!(report.link.samples_lost, 0);
    assert!(report.link.retransmits > 0);
    assert!(report.link.crc_errors > 0, "{:?}", report.link);
}

#[test]
fn a_device_that_goes_away_is_an_error_naming_the_port_and_the_log_survives() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let faults = Faults {
        die_after: 200,
        ..Faults::default()
    };
    let outcome = replay::<1023>(&recording, faults);
    let error = match outcome.result {
        Err(ReplayError::Link(error @ LinkError::Closed { .. })) => error,
        Err(other) => panic!("expected the link to close, got {other}"),
        Ok(_) => panic!("the replay succeeded without a device"),
    };
    let text = error.to_string();
    assert!(text.starts_with("socket: the link closed"), "{text}");
    let contents = read_log(&std::fs::read(&outcome.log).unwrap()).unwrap();
    assert!(contents.partial_tail.is_none());
    let acks = contents
        .records
        .iter()
        .filter(|r| r.kind == RecordKind::Frame)
        .count();
    assert!(acks >= 150, "only {acks} frames were logged");
}

#[test]
fn a_window_the_device_cannot_hold_is_refused_before_streaming() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let (config, _) = identify::configure(&recording, &Options::default()).unwrap();
    let outcome = replay::<16>(&recording, Faults::default());
    match outcome.result {
        Err(ReplayError::Input(sentence)) => {
            assert!(
                sentence.contains(&format!("{} samples", config.window)),
                "{sentence}"
            );
            assert!(sentence.contains("at most 16"), "{sentence}");
        }
        Err(other) => panic!("expected a refusal, got {other}"),
        Ok(_) => panic!("a 16-sample device took a {}-sample window", config.window),
    }
}

#[test]
fn three_channels_on_a_two_channel_device_are_refused_in_one_sentence() {
    let mut recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let two = replay_to::<1023, 2>(&recording, Faults::default());
    assert_eq!(two.result.unwrap().report, identify_f32(&recording));
    // The bundled x and v with the forcing 5 cos 2t as a measured u.
    recording.u = Some(recording.t.iter().map(|t| 5.0 * (2.0 * t).cos()).collect());
    recording.columns.u = Some("u".to_owned());
    match replay_to::<1023, 2>(&recording, Faults::default()).result {
        Err(ReplayError::Input(sentence)) => {
            assert!(
                sentence.contains(
                    "refused the configuration because this recording has 3 channels (x, v and u)"
                ),
                "{sentence}"
            );
            assert!(sentence.contains("--features three-channels"), "{sentence}");
            assert_eq!(sentence.matches(". ").count(), 0, "{sentence}");
        }
        Err(other) => panic!("expected a refusal, got {other}"),
        Ok(_) => panic!("a two-channel device took x, v and u"),
    }
}

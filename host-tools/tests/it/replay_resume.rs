//! A link that does not give up, and continues where it stopped (issue 14, item 5), against
//! the real device code (`lssi_device::Device`) in this process over a socket pair:
//!
//! - a host that stopped mid-recording (a replay that gave up) is followed by
//!   `lssi replay --resume`'s path ([`ReplayMode::resume`]), which asks the device where it
//!   is and sends the rest: the model is that of the whole recording, nothing lost;
//! - a line on which no sample frame crosses ends at the deadline with a message that says
//!   what was measured (the share of frames lost, the samples acknowledged) and how to
//!   resume.

#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use lssi_device::wire::config_to_wire;
use lssi_device::{Device, NoCost, Transport};
use lssi_host::identify::identify_recording;
use lssi_host::identify::{self, Options};
use lssi_host::recording::{ColumnNames, Recording};
use lssi_host::serial::link::{BatchSource, Link, LinkError, LinkOptions, Quiet};
use lssi_host::serial::quantise::{Quantised, quantise};
use lssi_host::serial::replay::{ReplayError, ReplayMode, replay_over_with};
use lssi_host::telemetry::TelemetryLog;
use lssi_proto::SampleEncoding;

fn bundled() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/paper-eq17.csv")
}

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

/// A device on `stream` until the host closes it; the frames to it `lost` picks are lost.
fn device(stream: UnixStream, lost: fn(&[u8]) -> bool) -> JoinHandle<()> {
    std::thread::Builder::new()
        .stack_size(8 << 20)
        .spawn(move || {
            let mut device: Box<Device<256, 24, 3>> = Box::new(Device::new());
            let mut reader = stream.try_clone().unwrap();
            let mut link = Socket(stream);
            let mut frame = Vec::new();
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
                    if !lost(&frame) && device.receive(&frame, &mut link, &mut NoCost).is_err() {
                        return;
                    }
                    frame.clear();
                }
            }
        })
        .unwrap()
}

/// The first `len` samples of a quantised recording.
struct Prefix<'a>(&'a Quantised, usize);

impl BatchSource for Prefix<'_> {
    fn len(&self) -> usize {
        self.1
    }

    fn max_batch(&self) -> usize {
        self.0.max_batch()
    }

    fn bytes_per_sample(&self) -> usize {
        self.0.bytes_per_sample()
    }

    fn frame(&self, seq: u32, from: usize, max: usize) -> (Vec<u8>, usize) {
        self.0.frame(seq, from, max.min(self.1 - from))
    }
}

fn options() -> LinkOptions {
    let mut options = LinkOptions::for_baud(921_600);
    options.silence = Duration::from_secs(10);
    options
}

#[test]
fn a_resumed_replay_continues_from_the_last_applied_sample_and_gives_the_whole_model() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let quantised = quantise(&recording).unwrap();
    let (config, estimated) =
        identify::configure(&quantised.recording, &Options::default()).unwrap();
    let expected = identify_recording(&quantised.recording, &Options::default()).unwrap();
    let (host, far) = UnixStream::pair().unwrap();
    let device = device(far, |_| false);
    host.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut log = TelemetryLog::open(dir.path().join("replay.tlm")).unwrap();
    let mut quiet = Quiet;
    let stopped_at = 12_345;

    // The first host: configured, 12,345 samples sent, then gone.
    {
        let mut link = Link::new(
            "socket",
            Box::new(host.try_clone().unwrap()),
            Box::new(host.try_clone().unwrap()),
            &mut log,
            &mut quiet,
            options(),
        );
        link.hello().unwrap();
        let mut wire = config_to_wire(&config).unwrap();
        wire.encoding = SampleEncoding::I16(quantised.encoding);
        link.configure(&wire).unwrap();
        link.stream_from(&Prefix(&quantised, stopped_at), 0, 0)
            .unwrap();
        assert_eq!(link.stats().samples_acked, stopped_at as u64);
    }
    // Its reader thread notices at its next read timeout.
    std::thread::sleep(Duration::from_millis(200));

    // The second host resumes: no Configure, the rest of the samples.
    let report = {
        let mut link = Link::new(
            "socket",
            Box::new(host.try_clone().unwrap()),
            Box::new(host.try_clone().unwrap()),
            &mut log,
            &mut quiet,
            options(),
        );
        let mode = ReplayMode {
            quantised: Some(&quantised),
            resume: true,
            duty: None,
        };
        replay_over_with(&mut link, &quantised.recording, &config, estimated, mode).unwrap()
    };
    host.shutdown(std::net::Shutdown::Both).unwrap();
    device.join().unwrap();
    assert_eq!(report.report, expected);
    assert_eq!(report.link.samples_lost, 0);
    assert_eq!(report.link.samples_acked, recording.len() as u64);
    // Only the rest crossed the second time.
    let rest = (recording.len() - stopped_at) as u64;
    assert_eq!(report.link.samples_sent, recording.len() as u64);
    // x and v: 4 bytes a sample, and a frame's overhead.
    assert!(
        (4 * rest..5 * rest).contains(&report.link.sample_bytes),
        "{:?}",
        report.link
    );
}

#[test]
fn a_line_no_batch_crosses_ends_at_the_deadline_saying_what_was_measured() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let quantised = quantise(&recording).unwrap();
    let (config, estimated) =
        identify::configure(&quantised.recording, &Options::default()).unwrap();
    let (host, far) = UnixStream::pair().unwrap();
    // Hello, Configure and Query cross; compact sample batches (the frame's first COBS
    // block starts with the message's discriminant, 5) do not.
    let device = device(far, |frame| frame.get(1) == Some(&5));
    host.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut log = TelemetryLog::open(dir.path().join("replay.tlm")).unwrap();
    let mut quiet = Quiet;
    let mut options = options();
    options.deadline = Duration::from_secs(2);
    let started = Instant::now();
    let result = {
        let mut link = Link::new(
            "socket",
            Box::new(host.try_clone().unwrap()),
            Box::new(host.try_clone().unwrap()),
            &mut log,
            &mut quiet,
            options,
        );
        let mode = ReplayMode {
            quantised: Some(&quantised),
            resume: false,
            duty: None,
        };
        replay_over_with(&mut link, &quantised.recording, &config, estimated, mode)
    };
    host.shutdown(std::net::Shutdown::Both).unwrap();
    device.join().unwrap();
    let error = match result {
        Err(ReplayError::Link(error @ LinkError::Deadline { .. })) => error,
        other => panic!("expected the deadline, got {other:?}"),
    };
    let took = started.elapsed();
    assert!(took >= Duration::from_secs(2), "{took:?}");
    assert!(took < Duration::from_secs(10), "{took:?}");
    let LinkError::Deadline {
        frame_loss, acked, ..
    } = &error
    else {
        unreachable!()
    };
    assert!(*frame_loss > 0.9, "{error}");
    let text = error.to_string();
    assert!(text.contains("no progress for"), "{text}");
    assert!(text.contains("% of the frames it sent were lost"), "{text}");
    assert!(
        text.contains(&format!(
            "acknowledged {acked} of {} samples",
            recording.len()
        )),
        "{text}"
    );
    assert!(
        text.contains("lssi replay --resume --port socket"),
        "{text}"
    );
}

/// `--port` and a deadline before the stream began (the device answers Hello, never its
/// Configure): one sentence that says no sample was sent, not a frame loss of 0 % and
/// "0 of 0 samples" with advice to resume a stream that never began.
#[test]
fn a_deadline_before_any_sample_says_nothing_was_streamed() {
    let recording = Recording::read(bundled(), &ColumnNames::default()).unwrap();
    let (config, estimated) = identify::configure(&recording, &Options::default()).unwrap();
    let (host, far) = UnixStream::pair().unwrap();
    // Configure (discriminant 1) never reaches the device.
    let device = device(far, |frame| frame.get(1) == Some(&1));
    host.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut log = TelemetryLog::open(dir.path().join("replay.tlm")).unwrap();
    let mut quiet = Quiet;
    let mut options = options();
    options.deadline = Duration::from_secs(1);
    let result = {
        let mut link = Link::new(
            "/dev/ttyACM7",
            Box::new(host.try_clone().unwrap()),
            Box::new(host.try_clone().unwrap()),
            &mut log,
            &mut quiet,
            options,
        );
        replay_over_with(
            &mut link,
            &recording,
            &config,
            estimated,
            ReplayMode::default(),
        )
    };
    host.shutdown(std::net::Shutdown::Both).unwrap();
    device.join().unwrap();
    let error = match result {
        Err(ReplayError::Link(error @ LinkError::Deadline { sent: 0, .. })) => error,
        other => panic!("expected the deadline before any sample, got {other:?}"),
    };
    let text = error.to_string();
    assert!(text.starts_with("/dev/ttyACM7: the host waited "), "{text}");
    assert!(
        text.contains("for the answer to Configure and none came"),
        "{text}"
    );
    assert!(text.contains("before sending a single sample"), "{text}");
    assert!(!text.contains("--resume"), "{text}");
    assert!(!text.contains("were lost"), "{text}");
    assert!(!text.contains(". "), "one sentence: {text}");
    // `lssi` prints it with a full stop: `ReplayError` adds it.
    let cli = ReplayError::Link(error).to_string();
    assert!(cli.ends_with("run the same command again."), "{cli}");
}

//! The bundled recording through the Cortex-M4F firmware under QEMU: the model the device
//! reports must equal, bit for bit, the model `lssi identify --f32 --no-refine` computes on the host.
//!
//! The test builds nothing: it runs the release ELF of `crates/lssi-firmware` (built by
//! `scripts/ci-qemu.sh`, or `cd crates/lssi-firmware && cargo build --release`), or the one
//! `LSSI_FIRMWARE_ELF` names, on `qemu-system-arm -machine mps2-an386` with UART0 on a Unix
//! socket, and speaks the lssi protocol over it: `Hello`, `Configure` (the configuration
//! `lssi identify` chooses for the file), every sample in batches (each waiting for its
//! `Ack`), `Query`. It then compares the device's `Model` with the host identifier's, run
//! on the same samples in f32, and checks the `Health` report (watchdog, per-sample cost).
//!
//! Both tests are `#[ignore]`d, with the reason shown by `cargo test`: they need
//! `qemu-system-arm` and the firmware's release ELF. `scripts/ci-qemu.sh` (CI) installs QEMU,
//! builds the ELF and runs them with `--include-ignored`; a missing prerequisite then fails
//! the test, it never passes silently. The firmware's defmt log (QEMU's stdout) is decoded with
//! `defmt-print` when it is installed and printed on failure (or with `--nocapture`).

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use lssi_core::{Identifier, Model, Sample};
use lssi_device::wire::{config_to_wire, model_from_snapshot};
use lssi_host::identify::{Options, TERM_CAPACITY, WINDOW_CAPACITY, configure};
use lssi_host::recording::{ColumnNames, Recording};
use lssi_proto::{
    Channels, CostUnit, DeviceFrameDecoder, DeviceMsg, HostMsg, MAX_BATCH, MAX_HOST_FRAME_LEN,
    PROTOCOL_VERSION, SampleBatch, SnapshotCause, WireSample, encode,
};

/// Longest wait for one reply: a batch that runs a screening takes ~6·10⁶ instructions.
const REPLY_TIMEOUT: Duration = Duration::from_secs(60);

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is inside the repository")
        .to_path_buf()
}

fn firmware_elf() -> PathBuf {
    std::env::var_os("LSSI_FIRMWARE_ELF").map_or_else(
        || {
            repository()
                .join("crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-firmware")
        },
        PathBuf::from,
    )
}

fn has_tool(name: &str) -> bool {
    Command::new(name)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// `None` when the test can run; otherwise why not.
fn missing_prerequisite(elf: &Path) -> Option<String> {
    if !has_tool("qemu-system-arm") {
        return Some("qemu-system-arm is not installed (apt-get install qemu-system-arm)".into());
    }
    if !elf.is_file() {
        return Some(format!(
            "no firmware ELF at {} (build it: cd crates/lssi-firmware && cargo build --release)",
            elf.display()
        ));
    }
    None
}

/// QEMU, killed when dropped; its stdout (the defmt stream) goes to a file.
pub(crate) struct Qemu {
    child: Child,
    log: PathBuf,
    elf: PathBuf,
}

impl Qemu {
    pub(crate) fn start(elf: &Path, socket: &Path, log: &Path) -> Self {
        let stdout = std::fs::File::create(log).expect("log file");
        // QEMU itself, not under `timeout`: killing a `timeout` would orphan QEMU. Every
        // wait for a reply is bounded instead, and `Drop` kills QEMU whatever happens.
        let stderr = std::fs::File::create(log.with_extension("stderr")).expect("log file");
        let child = Command::new("qemu-system-arm")
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4"])
            .args(["-nographic", "-monitor", "none"])
            .arg("-serial")
            .arg(format!("unix:{},server=on,wait=on", socket.display()))
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(["-icount", "shift=0", "-kernel"])
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(stdout)
            .stderr(stderr)
            .spawn()
            .expect("qemu-system-arm starts");
        Self {
            child,
            log: log.to_path_buf(),
            elf: elf.to_path_buf(),
        }
    }

    /// The firmware's log, decoded if defmt-print is installed.
    fn firmware_log(&self) -> String {
        if !has_tool("defmt-print") {
            return "(install defmt-print to decode the firmware's defmt log)".into();
        }
        let Ok(input) = std::fs::File::open(&self.log) else {
            return String::new();
        };
        Command::new("defmt-print")
            .arg("-e")
            .arg(&self.elf)
            .stdin(input)
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
            .unwrap_or_default()
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let stderr = std::fs::read_to_string(self.log.with_extension("stderr")).unwrap_or_default();
        eprintln!("QEMU:\n{stderr}\nfirmware log:\n{}", self.firmware_log());
    }
}

/// The host's end of the link.
pub(crate) struct Link {
    stream: UnixStream,
    decoder: DeviceFrameDecoder,
    pending: std::collections::VecDeque<DeviceMsg>,
}

impl Link {
    pub(crate) fn connect(socket: &Path) -> Self {
        let start = Instant::now();
        let stream = loop {
            match UnixStream::connect(socket) {
                Ok(s) => break s,
                Err(e) if start.elapsed() < Duration::from_secs(20) => {
                    let _ = e;
                    std::thread::sleep(Duration::from_millis(50));
                }
                Err(e) => panic!(
                    "cannot connect to QEMU's UART socket {}: {e}",
                    socket.display()
                ),
            }
        };
        stream
            .set_read_timeout(Some(Duration::from_millis(200)))
            .expect("socket timeout");
        Self {
            stream,
            decoder: DeviceFrameDecoder::new(),
            pending: Default::default(),
        }
    }

    pub(crate) fn send(&mut self, message: &HostMsg) {
        let mut frame = [0u8; MAX_HOST_FRAME_LEN];
        let len = encode(message, &mut frame).expect("the message fits a frame");
        self.stream
            .write_all(&frame[..len])
            .expect("write to the UART socket");
    }

    pub(crate) fn receive(&mut self) -> DeviceMsg {
        let start = Instant::now();
        loop {
            if let Some(m) = self.pending.pop_front() {
                return m;
            }
            assert!(
                start.elapsed() < REPLY_TIMEOUT,
                "no reply from the firmware within {REPLY_TIMEOUT:?}"
            );
            let mut buf = [0u8; 512];
            match self.stream.read(&mut buf) {
                Ok(0) => panic!("QEMU closed the UART socket"),
                Ok(n) => {
                    for m in self.decoder.feed::<DeviceMsg>(&buf[..n]) {
                        self.pending
                            .push_back(m.expect("a valid frame from the device"));
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("reading the UART socket: {e}"),
            }
        }
    }
}

fn host_model(recording: &Recording, config: lssi_core::Config) -> Model<f32, TERM_CAPACITY> {
    // What `lssi identify --f32 --no-refine` runs (host-tools' identify::run), up to its report.
    let mut id: Identifier<f32, WINDOW_CAPACITY, TERM_CAPACITY> =
        Identifier::new(config).expect("the host's configuration builds");
    for s in recording.samples() {
        let _ = id.push(Sample {
            t: s.t,
            x: s.x as f32,
            v: s.v.map(|v| v as f32),
            u: s.u.map(|u| u as f32),
        });
    }
    id.screen();
    id.model().expect("the host finds a model").clone()
}

/// The firmware ELF; a missing QEMU or image fails the (ignored, so asked-for) test.
pub(crate) fn qemu_firmware() -> PathBuf {
    let elf = firmware_elf();
    if let Some(reason) = missing_prerequisite(&elf) {
        panic!("{reason} (bash scripts/ci-qemu.sh installs QEMU and builds the image)");
    }
    elf
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn bundled_recording_through_qemu_firmware_equals_host_f32() {
    let elf = qemu_firmware();

    let file = repository().join("data/paper-eq17.csv");
    let recording = Recording::read(&file, &ColumnNames::default()).expect("bundled recording");
    // `lssi identify data/paper-eq17.csv --omega 2 --f32`
    let options = Options {
        omega: Some(2.0),
        f32: true,
        ..Options::default()
    };
    let (config, _) = configure(&recording, &options).expect("configure");
    let wire_config = config_to_wire(&config).expect("the configuration fits the wire");

    let dir = tempfile::tempdir().expect("temp dir");
    let socket = dir.path().join("uart.sock");
    let qemu = Qemu::start(&elf, &socket, &dir.path().join("defmt.bin"));
    let mut link = Link::connect(&socket);
    let started = Instant::now();

    link.send(&HostMsg::Hello {
        protocol_version: PROTOCOL_VERSION,
    });
    match link.receive() {
        DeviceMsg::HelloReply {
            protocol_version,
            window_capacity,
            max_terms,
            ..
        } => {
            assert_eq!(protocol_version, PROTOCOL_VERSION);
            assert!(
                usize::from(window_capacity) >= config.window,
                "window {}",
                config.window
            );
            assert!(usize::from(max_terms) >= 12);
        }
        other => panic!("expected HelloReply, got {other:?}"),
    }
    link.send(&HostMsg::Configure(wire_config));
    match link.receive() {
        DeviceMsg::Ack { .. } => {}
        other => panic!("expected Ack of Configure, got {other:?}"),
    }

    let channels = Channels::new(config.channels.velocity, config.channels.input);
    let samples: Vec<WireSample> = recording
        .samples()
        .map(|s| WireSample {
            t: s.t,
            x: s.x as f32,
            v: s.v.map(|v| v as f32),
            u: s.u.map(|u| u as f32),
        })
        .collect();
    let mut scheduled = 0;
    for (seq, chunk) in samples.chunks(MAX_BATCH).enumerate() {
        let seq = u32::try_from(seq).expect("few batches");
        let mut batch = SampleBatch::new(seq, channels);
        for &s in chunk {
            batch.push(s).expect("a batch holds MAX_BATCH samples");
        }
        link.send(&HostMsg::Samples(batch));
        loop {
            match link.receive() {
                DeviceMsg::Ack { seq: s } if s == seq => break,
                DeviceMsg::Model(_) => scheduled += 1,
                DeviceMsg::Log { .. } => {}
                other => panic!("batch {seq}: expected its Ack, got {other:?}"),
            }
        }
    }
    // A scheduled model may follow the last Ack.
    link.send(&HostMsg::Query);
    let snapshot = loop {
        match link.receive() {
            DeviceMsg::Model(m) if m.cause == SnapshotCause::Query => break m,
            DeviceMsg::Model(_) => scheduled += 1,
            DeviceMsg::Log { .. } => {}
            other => panic!("expected the queried Model, got {other:?}"),
        }
    };
    let health = link.receive();
    eprintln!(
        "replayed {} samples through QEMU in {:.1} s ({scheduled} scheduled models); {health:?}",
        samples.len(),
        started.elapsed().as_secs_f64()
    );
    match health {
        DeviceMsg::Health {
            samples: n,
            watchdog,
            cost_mean,
            cost_max,
            cost_unit,
            screen_cost_max,
            crc_errors,
            ..
        } => {
            assert_eq!(n, samples.len() as u64);
            assert!(watchdog > 0, "the watchdog counter must move");
            assert_eq!(cost_unit, CostUnit::Instructions);
            assert!(cost_mean > 0 && cost_max >= cost_mean && screen_cost_max > cost_max);
            assert_eq!(crc_errors, 0);
        }
        other => panic!("expected Health, got {other:?}"),
    }

    let device: Model<f32, TERM_CAPACITY> =
        model_from_snapshot(&snapshot).expect("the snapshot converts");
    let host = host_model(&recording, config);
    let n = host.terms.len();
    let bits = |c: &[f32]| c[..n].iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    let describe = |m: &Model<f32, TERM_CAPACITY>| {
        m.terms
            .iter()
            .zip(&m.coefficients)
            .map(|(t, c)| format!("{} {c:e}", t.name(m.omega)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    assert_eq!(device.terms, host.terms, "terms");
    assert_eq!(
        bits(&device.coefficients),
        bits(&host.coefficients),
        "coefficients differ:\n device {}\n host   {}",
        describe(&device),
        describe(&host)
    );
    assert_eq!(device.selected, host.selected, "selected solution");
    let supports =
        |m: &Model<f32, TERM_CAPACITY>| m.solutions.iter().map(|s| s.support).collect::<Vec<_>>();
    assert_eq!(supports(&device), supports(&host), "solutions");
    assert_eq!(device.k, host.k, "K");
    assert_eq!(
        device.offset_x.to_bits(),
        host.offset_x.to_bits(),
        "offset x"
    );
    assert_eq!(
        device.offset_v.to_bits(),
        host.offset_v.to_bits(),
        "offset v"
    );
    assert_eq!(device.samples, host.samples);
    assert_eq!(device.rows, host.rows);
    eprintln!("device model = host model: {}", describe(&device));
    drop(qemu);
}

/// The user's command: `lssi replay data/paper-eq17.csv --qemu --json` (its code, in this
/// process: QEMU on a pty, the link through `serialport`, defmt decoded) reports exactly the
/// report of `lssi identify --f32 --no-refine` on the same file.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF: bash scripts/ci-qemu.sh runs it"]
fn lssi_replay_qemu_reports_what_identify_f32_reports() {
    use lssi_host::commands::replay::{ReplayArgs, replay};
    use lssi_host::identify::identify_recording;

    let elf = qemu_firmware();
    let file = repository().join("data/paper-eq17.csv");
    let dir = tempfile::tempdir().expect("temp dir");
    let args = ReplayArgs {
        qemu: true,
        firmware: Some(elf.clone()),
        elf: Some(elf),
        log: Some(dir.path().join("qemu.tlm")),
        json: true,
        ..ReplayArgs::for_file(&file).expect("default arguments")
    };
    let recording = Recording::read(&file, &ColumnNames::default()).expect("bundled recording");
    let expected =
        identify_recording(&recording, &args.options().expect("options")).expect("identify --f32");
    let replayed = replay(&args).expect("lssi replay --qemu");
    assert_eq!(replayed.report, expected);
    assert_eq!(replayed.link.samples_lost, 0);
    assert_eq!(replayed.link.samples_acked, recording.len() as u64);
}

//! `lssi replay`'s work once a link is open: configure the device exactly as `lssi identify`
//! would configure its own identifier, stream the recording, query the model, and report it
//! with `lssi identify`'s report.
//!
//! The host computes the `Config` with [`identify::configure`] (same flags, same data → same
//! window, degree and Ω), sends it field for field ([`lssi_device::wire::config_to_wire`]),
//! streams every sample with its exact `t` (f64) and `x`, `v`, `u` rounded to f32 as
//! `lssi identify --f32` rounds them, and queries once at the end. The device's f32 model comes
//! back bit for bit ([`lssi_device::wire::model_from_snapshot`]) and goes through
//! [`identify::report`], so the terms and coefficients are those of `lssi identify --f32`.

use lssi_core::Config;
use lssi_device::wire::{config_to_wire, fits, model_from_snapshot};
use lssi_proto::{ModelSnapshot, NakReason, WireConfig, WireSample};
use serde::Serialize;

use crate::identify::{self, Report, TERM_CAPACITY};
use crate::recording::Recording;
use crate::serial::link::{Link, LinkError, LinkStats};

/// What `lssi replay --json` prints: `lssi identify --json`'s object plus `"link"`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ReplayReport {
    /// The device's model, reported as `lssi identify` reports its own.
    #[serde(flatten)]
    pub report: Report,
    /// The link's counters.
    pub link: LinkStats,
}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The link or the device failed (exit 1).
    #[error("{0}.")]
    Link(#[from] LinkError),
    /// The recording or the flags ask for something the device cannot do (exit 2).
    #[error("{0}")]
    Input(String),
}

/// The samples as they cross the link: `t` exact, the channels rounded to f32.
pub fn wire_samples(recording: &Recording) -> Vec<WireSample> {
    recording
        .samples()
        .map(|s| WireSample {
            t: s.t,
            x: s.x as f32,
            v: s.v.map(|v| v as f32),
            u: s.u.map(|u| u as f32),
        })
        .collect()
}

/// The wire form of `config`, or a sentence naming the file.
pub fn wire_config(recording: &Recording, config: &Config) -> Result<WireConfig, ReplayError> {
    config_to_wire(config)
        .map_err(|e| ReplayError::Input(format!("{}: {e}.", recording.path.display())))
}

/// The report of a device's model snapshot: `lssi identify --f32`'s report of the same model.
pub fn report_from_snapshot(
    snapshot: &ModelSnapshot,
    config: &Config,
    omega_estimated: bool,
) -> Result<Report, String> {
    let model = model_from_snapshot::<TERM_CAPACITY>(snapshot).map_err(|e| e.to_string())?;
    Ok(identify::report(
        &model,
        config,
        omega_estimated,
        model.rejected,
        "f32",
    ))
}

/// Hello, configure, stream `recording`, query: the device's model as a report.
///
/// `config` comes from [`identify::configure`] on the same recording; a configuration that
/// does not fit the device's capacities is refused here with a sentence that says which.
/// The device's channel capacity is not in its `HelloReply`: a configuration with x, v and
/// u that it refuses (the firmware keeps two channel rings unless built with its
/// `three-channels` feature) gets a sentence saying so.
pub fn replay_over(
    link: &mut Link<'_>,
    recording: &Recording,
    config: &Config,
    omega_estimated: bool,
) -> Result<ReplayReport, ReplayError> {
    let file = recording.path.display().to_string();
    let wire = wire_config(recording, config)?;
    let info = link.hello()?;
    fits(config, info.window_capacity, info.max_terms).map_err(|e| {
        ReplayError::Input(format!(
            "{file}: {e} ({}), so it cannot identify this recording with these flags; try a lower --poly-order or --harmonics.",
            link.port()
        ))
    })?;
    link.configure(&wire).map_err(|e| match e {
        // `fits` passed and `identify::configure` validated the rest: with three channels,
        // their count is what the device cannot take.
        LinkError::Refused {
            port,
            reason: NakReason::BadConfig,
            ..
        } if config.channels.count() == 3 => ReplayError::Input(format!(
            "{file}: the device ({port}) refused the configuration because this recording has 3 channels (x, v and u) and the device keeps ring buffers for fewer (the firmware keeps 2 unless built with `--features three-channels`), so flash such a firmware or drop the v or u column from the file."
        )),
        e => e.into(),
    })?;
    let samples = wire_samples(recording);
    link.stream(&samples)?;
    let (snapshot, health) = link.query()?;
    let snapshot = snapshot.ok_or_else(|| {
        ReplayError::Input(format!(
            "{file}: no model: the device accepted {} samples and rejected {}, too few regression rows for the library.",
            health.samples, health.rejected
        ))
    })?;
    let report = report_from_snapshot(&snapshot, config, omega_estimated).map_err(|e| {
        ReplayError::Input(format!(
            "{}: the device's model cannot be read: {e}.",
            link.port()
        ))
    })?;
    link.log_summary()?;
    Ok(ReplayReport {
        report,
        link: *link.stats(),
    })
}

/// The link line of the human output.
pub fn render_link(stats: &LinkStats) -> String {
    format!(
        "link: {} frames sent, {} retransmitted, {} CRC errors, {} samples lost, {} samples in {:.2} s ({:.0} samples/s)\n",
        stats.frames_sent,
        stats.retransmits,
        stats.crc_errors,
        stats.samples_lost,
        stats.samples_acked,
        stats.stream_seconds,
        stats.samples_per_second()
    )
}

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
use lssi_proto::{ModelSnapshot, NakReason, SampleEncoding, WireConfig, WireSample};
use serde::Serialize;

use crate::identify::{self, Report, TERM_CAPACITY};
use crate::recording::Recording;
use crate::serial::link::{F32Samples, Link, LinkError, LinkStats};
use crate::serial::quantise::{Quantisation, Quantised};

/// What `lssi replay --json` prints: `lssi identify --json`'s object plus `"link"`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ReplayReport {
    /// The device's model, reported as `lssi identify` reports its own.
    #[serde(flatten)]
    pub report: Report,
    /// The link's counters.
    pub link: LinkStats,
    /// With the compact encoding: how the samples were quantised (the model is that of the
    /// quantised recording, `lssi identify --quantise i16`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantisation: Option<Quantisation>,
}

/// How a replay sends its samples and where it starts.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReplayMode<'a> {
    /// The compact encoding's quantised recording (`None`: f32 samples).
    pub quantised: Option<&'a Quantised>,
    /// Continue a replay the device has begun, from the last sample it applied, without
    /// configuring it again.
    pub resume: bool,
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
    replay_over_with(
        link,
        recording,
        config,
        omega_estimated,
        ReplayMode::default(),
    )
}

/// [`replay_over`] in the compact encoding and/or resuming, as `mode` says. With the compact
/// encoding, `recording` and `config` are those of the quantised recording
/// ([`Quantised::recording`]).
pub fn replay_over_with(
    link: &mut Link<'_>,
    recording: &Recording,
    config: &Config,
    omega_estimated: bool,
    mode: ReplayMode<'_>,
) -> Result<ReplayReport, ReplayError> {
    let file = recording.path.display().to_string();
    let mut wire = wire_config(recording, config)?;
    if let Some(quantised) = mode.quantised {
        wire.encoding = SampleEncoding::I16(quantised.encoding);
    }
    let info = link.hello()?;
    fits(config, info.window_capacity, info.max_terms).map_err(|e| {
        ReplayError::Input(format!(
            "{file}: {e} ({}), so it cannot identify this recording with these flags; try a lower --poly-order or --harmonics.",
            link.port()
        ))
    })?;
    let configured = if mode.resume {
        Ok(())
    } else {
        link.configure(&wire)
    };
    configured.map_err(|e| match e {
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
    let (from, first_seq) = if mode.resume {
        let (applied, next) = link.position()?;
        (usize::try_from(applied).unwrap_or(usize::MAX), next)
    } else {
        (0, 0)
    };
    if from > recording.len() {
        return Err(ReplayError::Input(format!(
            "{file}: the device ({}) has applied {from} samples, more than the recording's {}, so it is not replaying this recording; replay without --resume.",
            link.port(),
            recording.len()
        )));
    }
    match mode.quantised {
        Some(quantised) => link.stream_from(quantised, from, first_seq)?,
        None => link.stream_from(&F32Samples(&wire_samples(recording)), from, first_seq)?,
    }
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
        quantisation: mode.quantised.map(|q| q.summary.clone()),
    })
}

/// The link line of the human output.
pub fn render_link(stats: &LinkStats) -> String {
    let line = if stats.line_error_rate > 0.0 {
        format!(
            "; the device received {} damaged frames: a byte error rate of about {:.3} % on the line to it\n",
            stats.crc_errors.saturating_sub(stats.rx_crc_errors),
            100.0 * stats.line_error_rate
        )
    } else {
        "\n".to_string()
    };
    format!(
        "link: {} frames sent, {} retransmitted, {} CRC errors, {} samples lost, {} samples in {:.2} s ({:.0} samples/s){line}",
        stats.frames_sent,
        stats.retransmits,
        stats.crc_errors,
        stats.samples_lost,
        stats.samples_acked,
        stats.stream_seconds,
        stats.samples_per_second()
    )
}

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

use lssi_core::{Config, SystemConfig};
use lssi_device::system::{system_config_to_wire, system_model_from_snapshot};
use lssi_device::wire::{config_to_wire, fits, model_from_snapshot};
use lssi_proto::{
    ModelSnapshot, NakReason, SampleEncoding, SystemWireSample, WireConfig, WireDuty, WireSample,
};
use serde::Serialize;

use crate::identify::{self, Report, TERM_CAPACITY};
use crate::recording::Recording;
use crate::serial::link::{F32Samples, Link, LinkError, LinkStats, SystemSamples};
use crate::serial::quantise::{Quantisation, Quantised};
use crate::system::{SystemData, SystemReport};

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
    /// The duty cycle sent in the configuration (a standalone device's; one the host feeds
    /// ignores it).
    pub duty: Option<WireDuty>,
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
    wire.duty = mode.duty;
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

/// What `lssi replay --json` prints for a system: `lssi identify --json`'s object for the
/// system plus `"link"`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SystemReplayReport {
    /// The device's equations, reported as `lssi identify` reports its own.
    #[serde(flatten)]
    pub report: SystemReport,
    /// The link's counters.
    pub link: LinkStats,
}

/// A system's samples as they cross the link: `t` exact, every channel rounded to f32 as
/// `lssi identify --f32` rounds them.
pub fn system_wire_samples(data: &SystemData) -> Vec<SystemWireSample> {
    let r = &data.recording;
    (0..r.len())
        .map(|i| SystemWireSample {
            t: r.t[i],
            x: r.x[i] as f32,
            v: r.v.as_ref().map(|v| v[i] as f32),
            u: r.u.as_ref().map(|u| u[i] as f32),
            electrical: data
                .electrical
                .iter()
                .take(lssi_proto::MAX_ELECTRICAL)
                .map(|e| e.values[i] as f32)
                .collect(),
        })
        .collect()
}

/// Hello, `ConfigureSystem`, stream the system's samples, query: the device's equations as
/// `lssi identify --f32` reports a system (standard errors computed on the host from the
/// same data and the device's selected terms).
///
/// The device's snapshot carries each equation's selected solution only (not the whole
/// sweep: a frame holds three equations' coefficients but not their 32 candidates each), so
/// the report's `solutions` lists that one, `selected` 0.
pub fn replay_system_over(
    link: &mut Link<'_>,
    data: &SystemData,
    config: &SystemConfig,
    omega_estimated: bool,
    mode: ReplayMode<'_>,
) -> Result<SystemReplayReport, ReplayError> {
    let file = data.recording.path.display().to_string();
    let mut wire =
        system_config_to_wire(config).map_err(|e| ReplayError::Input(format!("{file}: {e}.")))?;
    wire.base.duty = mode.duty;
    let info = link.hello()?;
    fits(&config.base, info.window_capacity, info.max_terms).map_err(|e| {
        ReplayError::Input(format!(
            "{file}: {e} ({}), so it cannot identify this recording with these flags; try a lower --poly-order or --harmonics.",
            link.port()
        ))
    })?;
    let configured = if mode.resume {
        Ok(())
    } else {
        link.configure_system(&wire)
    };
    configured.map_err(|e| match e {
        LinkError::Refused {
            port,
            reason: NakReason::Decode,
            ..
        } => ReplayError::Input(format!(
            "{file}: the device ({port}) does not take a system of equations (it did not decode ConfigureSystem): flash a firmware built with its `system` feature, or replay a recording without an electrical column."
        )),
        LinkError::Refused {
            port,
            reason: NakReason::TooManyTerms { terms, capacity },
            ..
        } => ReplayError::Input(format!(
            "{file}: the device ({port}) holds at most {capacity} library terms, and this system's shared library has {terms}; try a lower --poly-order, --harmonics or --coupling-order."
        )),
        LinkError::Refused {
            port,
            reason: NakReason::BadConfig,
            ..
        } => ReplayError::Input(format!(
            "{file}: the device ({port}) refused the system's configuration: its channels (x, {}{}the electrical ones) or its window do not fit the device's ring buffers; drop the v or u column from the file or flash a firmware with more channels.",
            if data.recording.v.is_some() { "v, " } else { "" },
            if data.recording.u.is_some() { "u, " } else { "" },
        )),
        e => e.into(),
    })?;
    let samples = system_wire_samples(data);
    let (from, first_seq) = if mode.resume {
        let (applied, next) = link.position_of(true)?;
        (usize::try_from(applied).unwrap_or(usize::MAX), next)
    } else {
        (0, 0)
    };
    if from > samples.len() {
        return Err(ReplayError::Input(format!(
            "{file}: the device ({}) has applied {from} samples, more than the recording's {}, so it is not replaying this recording; replay without --resume.",
            link.port(),
            samples.len()
        )));
    }
    link.stream_from(&SystemSamples(&samples), from, first_seq)?;
    let (snapshot, health) = link.query_system()?;
    let snapshot = snapshot.ok_or_else(|| {
        ReplayError::Input(format!(
            "{file}: no model: the device accepted {} samples and rejected {}, too few regression rows for the system's library.",
            health.samples, health.rejected
        ))
    })?;
    let model =
        system_model_from_snapshot::<{ crate::system::TERM_CAPACITY }>(&snapshot).map_err(|e| {
            ReplayError::Input(format!(
                "{}: the device's model cannot be read: {e}.",
                link.port()
            ))
        })?;
    let mut report = SystemReport::of(&model, config, omega_estimated, model.rejected, "f32", data);
    crate::system::report::add_standard_errors(&mut report, data);
    link.log_summary()?;
    Ok(SystemReplayReport {
        report,
        link: *link.stats(),
    })
}

/// A recording's rows averaged `k` at a time (the last incomplete group dropped): a
/// first-order CIC (the STM32L4's oversampler, `lssi_device::decimate` of order 1) before
/// its droop compensator ([`compensate_rows`]). Every column is averaged, t too (a row
/// stands for the middle of its conversions).
pub fn average_rows(values: &[f64], k: usize) -> Vec<f64> {
    let k = k.max(1);
    values
        .chunks_exact(k)
        .map(|c| c.iter().sum::<f64>() / k as f64)
        .collect()
}

/// The side tap of the droop compensator after a first-order CIC: `a = N / 24`, N = 1 (as
/// `lssi_device::decimate::Decimator` of order 1, which computes it in f32 on the device).
pub const COMPENSATOR_SIDE: f64 = 1.0 / 24.0;

/// Averaged rows through the droop compensator: `c_r = (1 + 2a)·y_r − a·(y_{r−1} +
/// y_{r+1})` for every row with a row either side (the first and last have none and are
/// dropped: `y.len() − 2` rows, row `j` the compensated `y_{j+1}`), a = [`COMPENSATOR_SIDE`].
/// What a device whose ADC oversampler averages the conversions delivers, in f64.
pub fn compensate_rows(y: &[f64]) -> Vec<f64> {
    let a = COMPENSATOR_SIDE;
    y.windows(3)
        .map(|w| (1.0 + 2.0 * a) * w[1] - a * (w[0] + w[2]))
        .collect()
}

/// One channel at `k` times fewer rows: averaged ([`average_rows`]), then compensated
/// ([`compensate_rows`]).
pub fn decimate_column(values: &[f64], k: usize) -> Vec<f64> {
    compensate_rows(&average_rows(values, k))
}

/// The times of [`decimate_column`]'s rows: each compensated row's own averaged time (the
/// first and last averaged rows dropped).
pub fn decimate_times(t: &[f64], k: usize) -> Vec<f64> {
    let mut t = average_rows(t, k);
    if t.len() < 3 {
        return Vec::new();
    }
    t.pop();
    t.remove(0);
    t
}

/// The recording at `k` times fewer rows, as a device decimates it: every channel averaged
/// `k` rows at a time and compensated for the average's droop ([`decimate_column`]), the
/// times those of the compensated rows ([`decimate_times`]).
pub fn decimate_recording(recording: &Recording, k: usize) -> Recording {
    if k <= 1 {
        return recording.clone();
    }
    Recording {
        path: recording.path.clone(),
        t: decimate_times(&recording.t, k),
        x: decimate_column(&recording.x, k),
        v: recording.v.as_ref().map(|v| decimate_column(v, k)),
        u: recording.u.as_ref().map(|u| decimate_column(u, k)),
        columns: recording.columns.clone(),
    }
}

/// A system's recording at `k` times fewer rows, the electrical channels too.
pub fn decimate_system(data: &SystemData, k: usize) -> SystemData {
    let mut out = data.clone();
    if k > 1 {
        out.recording = decimate_recording(&data.recording, k);
        for e in &mut out.electrical {
            e.values = decimate_column(&e.values, k);
        }
    }
    out
}

/// The whole number of a recording's rows a row at `row_rate` Hz averages, for a recording
/// sampled every `sample_period` seconds; or the sentence saying why there is none.
pub fn rows_per_row(file: &str, sample_period: f64, row_rate: f64) -> Result<usize, String> {
    let own = 1.0 / sample_period;
    if !(row_rate.is_finite() && row_rate > 0.0) {
        return Err(format!(
            "--row-rate {row_rate}: the row rate must be a positive number of rows a second."
        ));
    }
    if row_rate > own * 1.001 {
        return Err(format!(
            "{file}: --row-rate {row_rate} Hz is faster than the recording's {} samples a second, and a replay cannot make rows it has not got; give {} or less (its rate divided by a whole number).",
            short(own),
            short(own)
        ));
    }
    match lssi_device::decimate::factor_for(own, 1.0 / row_rate) {
        Some(k) => Ok(k as usize),
        None => {
            let k = (own / row_rate).floor().clamp(1.0, 255.0);
            Err(format!(
                "{file}: --row-rate {row_rate} Hz is not the recording's {} Hz divided by a whole number from 1 to {}, so rows cannot average whole samples; try {} or {} Hz.",
                short(own),
                lssi_device::decimate::MAX_FACTOR,
                short(own / k),
                short(own / (k + 1.0))
            ))
        }
    }
}

/// A rate in Hz, shortly.
fn short(hz: f64) -> String {
    let rounded = (hz * 1000.0).round() / 1000.0;
    format!("{rounded}")
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The amplitude of an `f_hz` sine in rows at times `t` (least squares on sin and cos).
    fn amplitude(t: &[f64], y: &[f64], f_hz: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&t, &y) in t.iter().zip(y) {
            let (s, c) = ((w * t).sin(), (w * t).cos());
            ss += s * s;
            sc += s * c;
            cc += c * c;
            ys += y * s;
            yc += y * c;
        }
        let det = ss * cc - sc * sc;
        ((ys * cc - yc * sc) / det).hypot((yc * ss - ys * sc) / det)
    }

    #[test]
    fn replayed_rows_are_the_compensated_averages_at_their_own_times() {
        // 10 kHz rows averaged by 47 (212.8 rows/s, the rate proposed for eveh): the mean's
        // droop at 10.2 Hz (0.38 %) is gone to second order, a ramp stays on its times, and
        // every channel keeps as many rows as the times.
        let t: Vec<f64> = (0..20_000).map(|i| f64::from(i) / 10_000.0).collect();
        for f in [3.4, 10.2, 20.0] {
            let x: Vec<f64> = t
                .iter()
                .map(|t| (2.0 * std::f64::consts::PI * f * t).sin())
                .collect();
            let (tr, averaged) = (average_rows(&t, 47), average_rows(&x, 47));
            let (tc, compensated) = (decimate_times(&t, 47), decimate_column(&x, 47));
            assert_eq!(tc.len(), averaged.len() - 2);
            assert_eq!(compensated.len(), tc.len());
            assert_eq!(tc[..], tr[1..tr.len() - 1]);
            let droop = 1.0 - amplitude(&tr, &averaged, f);
            let left = (1.0 - amplitude(&tc, &compensated, f)).abs();
            assert!(
                droop > 0.0 && left <= droop / 15.0,
                "{f} Hz: {left} of {droop}"
            );
        }
        let ramp = decimate_column(&t, 47);
        let times = decimate_times(&t, 47);
        for (x, t) in ramp.iter().zip(&times) {
            assert!((x - t).abs() < 1e-12, "{x} at {t}");
        }
        assert!(decimate_column(&t[..47 * 2], 47).is_empty());
        assert!(decimate_times(&t[..47 * 2], 47).is_empty());
    }
}

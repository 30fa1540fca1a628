//! A telemetry log's records decoded, as `lssi log` prints them: text, JSON lines (one object
//! per record) or CSV rows (model coefficients, health counters and device log lines over
//! time, one value a row). Frames are decoded here, from the raw bytes the log keeps; device
//! log lines are decoded with the firmware's defmt tables, or shown raw.

use std::collections::BTreeMap;

use lssi_core::Config;
use lssi_device::wire::config_from_wire;
use lssi_proto::{DeviceMsg, ModelSnapshot, SnapshotCause, WireConfig, decode_frame};
use serde_json::{Value, json};

use crate::identify;
use crate::serial::link::nak_text;
use crate::serial::replay::report_from_snapshot;
use crate::telemetry::defmt::{DefmtLines, Tables, hex};
use crate::telemetry::{Record, RecordKind};

/// One record, decoded, as every output format sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Session number, from 1 (0: records before any session record).
    pub session: usize,
    /// Seconds since the session's start.
    pub time_s: f64,
    /// Microseconds since the Unix epoch.
    pub unix_us: u64,
    /// What happened.
    pub event: Event,
}

/// A decoded record.
#[derive(Debug, Clone, PartialEq)]
#[allow(
    clippy::large_enum_variant,
    reason = "entries are decoded once and printed; a log holds few enough of them"
)]
pub enum Event {
    /// A replay started (its description).
    Session(Value),
    /// A frame from the device.
    Message(DeviceMsg),
    /// A frame that failed its check on the host.
    Corrupt {
        /// Its bytes.
        bytes: Vec<u8>,
        /// Why.
        error: String,
    },
    /// A device log line (decoded, or raw bytes with a hint).
    Line(String),
    /// A host note.
    Note(String),
    /// The link counters at the end of a replay.
    Summary(Value),
}

/// Decodes every record; `elf` tables decode the device log lines.
pub fn decode(records: &[Record], tables: Option<&Tables>) -> Vec<Entry> {
    let mut entries = Vec::new();
    let mut session = 0;
    let mut start = records.first().map_or(0, |r| r.time_us);
    let mut lines = DefmtLines::new(tables);
    for record in records {
        let time_s = record.time_us.saturating_sub(start) as f64 * 1e-6;
        let mut push = |session, event| {
            entries.push(Entry {
                session,
                time_s,
                unix_us: record.time_us,
                event,
            })
        };
        match record.kind {
            RecordKind::Session => {
                session += 1;
                start = record.time_us;
                lines = DefmtLines::new(tables);
                let value = serde_json::from_slice(&record.data).unwrap_or_else(|_| {
                    Value::String(String::from_utf8_lossy(&record.data).into())
                });
                entries.push(Entry {
                    session,
                    time_s: 0.0,
                    unix_us: record.time_us,
                    event: Event::Session(value),
                });
            }
            RecordKind::Frame => {
                let mut bytes = record.data.clone();
                match decode_frame::<DeviceMsg>(&mut bytes) {
                    Ok(DeviceMsg::Log { bytes }) => {
                        for line in lines.push(&bytes) {
                            push(session, Event::Line(line));
                        }
                    }
                    Ok(message) => push(session, Event::Message(message)),
                    Err(error) => push(
                        session,
                        Event::Corrupt {
                            bytes: record.data.clone(),
                            error: error.to_string(),
                        },
                    ),
                }
            }
            RecordKind::Defmt => {
                for line in lines.push(&record.data) {
                    push(session, Event::Line(line));
                }
            }
            RecordKind::Note => push(
                session,
                Event::Note(String::from_utf8_lossy(&record.data).into_owned()),
            ),
            RecordKind::Summary => push(
                session,
                Event::Summary(serde_json::from_slice(&record.data).unwrap_or(Value::Null)),
            ),
        }
    }
    entries
}

/// The identifier configuration a session record describes (for rendering its models).
pub fn session_config(value: &Value) -> (Config, bool) {
    let config = value
        .get("config")
        .and_then(|c| serde_json::from_value::<WireConfig>(c.clone()).ok())
        .map_or_else(Config::default, |w| config_from_wire(&w));
    let estimated = value
        .get("omega_estimated")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    (config, estimated)
}

fn snapshot_report(snapshot: &ModelSnapshot, session: &(Config, bool)) -> Value {
    match report_from_snapshot(snapshot, &session.0, session.1) {
        Ok(report) => serde_json::to_value(report).unwrap_or(Value::Null),
        Err(error) => json!({ "error": error }),
    }
}

fn cause(snapshot: &ModelSnapshot) -> &'static str {
    match snapshot.cause {
        SnapshotCause::Scheduled => "scheduled",
        SnapshotCause::Query => "query",
        SnapshotCause::Final => "final",
    }
}

/// The JSON object of one entry.
pub fn entry_json(entry: &Entry, session: &(Config, bool)) -> Value {
    let mut object = match &entry.event {
        Event::Session(value) => json!({ "kind": "session", "session_info": value }),
        Event::Message(message) => message_json(message, session),
        Event::Corrupt { bytes, error } => {
            json!({ "kind": "corrupt_frame", "bytes": hex(bytes), "error": error })
        }
        Event::Line(line) => json!({ "kind": "log", "line": line }),
        Event::Note(text) => json!({ "kind": "note", "text": text }),
        Event::Summary(value) => json!({ "kind": "summary", "link": value }),
    };
    if let Value::Object(map) = &mut object {
        map.insert("session".into(), json!(entry.session));
        map.insert("time_s".into(), json!(entry.time_s));
        map.insert("unix_us".into(), json!(entry.unix_us));
    }
    object
}

/// A system snapshot's equations, one line each (`x'' = …`, `V' = …`), as lssi-core
/// writes them; or why the snapshot cannot be read.
pub fn system_equations(snapshot: &lssi_proto::SystemSnapshot) -> Vec<String> {
    match lssi_device::system::system_model_from_snapshot::<{ lssi_proto::MAX_TERMS }>(snapshot) {
        Ok(model) => (0..model.equations.len())
            .map(|k| {
                let mut line = String::new();
                let _ = model.write_equation(k, 6, &mut line);
                line
            })
            .collect(),
        Err(error) => vec![format!("(unreadable: {error})")],
    }
}

/// The JSON object of one device message (as `lssi log --json` and `lssi monitor --json` print it).
pub fn message_json(message: &DeviceMsg, session: &(Config, bool)) -> Value {
    match message {
        DeviceMsg::HelloReply {
            protocol_version,
            max_terms,
            window_capacity,
            max_batch,
        } => json!({
            "kind": "hello",
            "protocol_version": protocol_version,
            "max_terms": max_terms,
            "window_capacity": window_capacity,
            "max_batch": max_batch,
        }),
        DeviceMsg::Ack { seq } => json!({ "kind": "ack", "seq": seq }),
        DeviceMsg::Nak { seq, reason } => {
            json!({ "kind": "nak", "seq": seq, "reason": format!("{reason:?}") })
        }
        DeviceMsg::Model(snapshot) => json!({
            "kind": "model",
            "cause": cause(snapshot),
            "report": snapshot_report(snapshot, session),
        }),
        DeviceMsg::SystemModel(snapshot) => json!({
            "kind": "system_model",
            "cause": format!("{:?}", snapshot.cause).to_lowercase(),
            "samples": snapshot.samples,
            "equations": system_equations(snapshot),
        }),
        DeviceMsg::Health {
            samples,
            rejected,
            buffer_fill,
            cost_mean,
            cost_max,
            cost_unit,
            watchdog,
            crc_errors,
            frames_ok,
            screen_cost,
            screen_cost_max,
            screenings,
            duplicates,
            decode_errors,
            overruns,
            queue_high_water,
            latency_max_ns,
            screenings_skipped,
            sample_rate_hz,
            drift,
            reference,
        } => json!({
            "kind": "health",
            "samples": samples,
            "rejected": rejected,
            "buffer_fill": buffer_fill,
            "cost_mean": cost_mean,
            "cost_max": cost_max,
            "cost_unit": format!("{cost_unit:?}"),
            "watchdog": watchdog,
            "crc_errors": crc_errors,
            "frames_ok": frames_ok,
            "screen_cost": screen_cost,
            "screen_cost_max": screen_cost_max,
            "screenings": screenings,
            "duplicates": duplicates,
            "decode_errors": decode_errors,
            "overruns": overruns,
            "queue_high_water": queue_high_water,
            "latency_max_ns": latency_max_ns,
            "screenings_skipped": screenings_skipped,
            "sample_rate_hz": sample_rate_hz,
            "drift": drift.map(|d| drift_json(&d)),
            "reference": reference.map(|r| reference_json(&r)),
        }),
        DeviceMsg::Log { bytes } => json!({ "kind": "log", "bytes": hex(bytes) }),
        DeviceMsg::ModelPart(part) => json!({
            "kind": "model_part",
            "total": part.total,
            "offset": part.offset,
            "crc": part.crc,
            "bytes": hex(&part.bytes),
        }),
    }
}

/// The text form of the entries.
pub fn render_text(entries: &[Entry]) -> String {
    let mut out = String::new();
    let mut session = (Config::default(), false);
    let mut counts: BTreeMap<&str, u64> = BTreeMap::new();
    let flush = |out: &mut String, counts: &mut BTreeMap<&str, u64>| {
        if !counts.is_empty() {
            let parts: Vec<String> = counts.iter().map(|(k, n)| format!("{n} {k}")).collect();
            out.push_str(&format!("  frames: {}\n", parts.join(", ")));
            counts.clear();
        }
    };
    for entry in entries {
        let at = format!("  {:>9.3} s  ", entry.time_s);
        match &entry.event {
            Event::Session(value) => {
                flush(&mut out, &mut counts);
                session = session_config(value);
                let text = |key: &str| value.get(key).map_or(String::from("?"), |v| match v {
                    Value::String(s) => s.clone(),
                    other => other.to_string(),
                });
                out.push_str(&format!(
                    "session {}: {} on {} ({}, {} baud), {} samples, at {} µs since the Unix epoch\n",
                    entry.session,
                    text("input"),
                    text("port"),
                    text("device"),
                    text("baud"),
                    text("samples"),
                    entry.unix_us
                ));
            }
            Event::Message(message) => match message {
                DeviceMsg::Ack { .. } => *counts.entry("acks").or_default() += 1,
                DeviceMsg::Nak { seq, reason } => {
                    *counts.entry("naks").or_default() += 1;
                    if *seq == lssi_proto::CONTROL_SEQ {
                        out.push_str(&format!("{at}nak of a command: {}\n", nak_text(*reason)));
                    }
                }
                DeviceMsg::HelloReply {
                    protocol_version,
                    max_terms,
                    window_capacity,
                    max_batch,
                } => out.push_str(&format!(
                    "{at}hello: protocol {protocol_version}, {max_terms} terms, window {window_capacity}, batches of {max_batch}\n"
                )),
                DeviceMsg::SystemModel(snapshot) => {
                    out.push_str(&format!(
                        "{at}system model ({:?}, {} samples):\n",
                        snapshot.cause, snapshot.samples
                    ));
                    for line in system_equations(snapshot) {
                        out.push_str(&format!("{at}  {line}\n"));
                    }
                }
                DeviceMsg::Model(snapshot) => {
                    let equation = match report_from_snapshot(snapshot, &session.0, session.1) {
                        Ok(report) => identify::render(&report)
                            .lines()
                            .next()
                            .unwrap_or_default()
                            .to_string(),
                        Err(error) => format!("(unreadable: {error})"),
                    };
                    out.push_str(&format!(
                        "{at}model ({}, {} samples): {equation}\n",
                        cause(snapshot),
                        snapshot.samples
                    ));
                }
                DeviceMsg::Health {
                    samples,
                    rejected,
                    crc_errors,
                    frames_ok,
                    duplicates,
                    cost_mean,
                    cost_max,
                    cost_unit,
                    screenings,
                    drift,
                    reference,
                    ..
                } => out.push_str(&format!(
                    "{at}health: {samples} samples ({rejected} rejected), {screenings} screenings, {frames_ok} frames ok, {crc_errors} CRC errors, {duplicates} duplicates, cost {cost_mean} mean / {cost_max} max {cost_unit:?}{}{}\n",
                    drift.map(|d| format!(", {}", drift_text(&d))).unwrap_or_default(),
                    reference.map(|r| format!(", {}", reference_text(&r))).unwrap_or_default()
                )),
                DeviceMsg::Log { bytes } => out.push_str(&format!("{at}device: {}\n", hex(bytes))),
                DeviceMsg::ModelPart(part) => out.push_str(&format!(
                    "{at}model part: bytes {}..{} of {}\n",
                    part.offset,
                    usize::from(part.offset) + part.bytes.len(),
                    part.total
                )),
            },
            Event::Corrupt { error, .. } => {
                *counts.entry("corrupt").or_default() += 1;
                let _ = error;
            }
            Event::Line(line) => out.push_str(&format!("{at}device: {line}\n")),
            Event::Note(text) => out.push_str(&format!("{at}note: {text}\n")),
            Event::Summary(value) => {
                let get = |k: &str| value.get(k).and_then(Value::as_u64).unwrap_or(0);
                out.push_str(&format!(
                    "{at}summary: {} frames sent, {} retransmitted, {} CRC errors, {} samples lost\n",
                    get("frames_sent"),
                    get("retransmits"),
                    get("crc_errors"),
                    get("samples_lost")
                ));
            }
        }
    }
    flush(&mut out, &mut counts);
    out
}

/// The CSV rows (session, time_s, kind, field, value) of the entries: model coefficients and
/// figures, health counters, device log lines and notes.
pub fn csv_rows(entries: &[Entry]) -> Vec<[String; 5]> {
    let mut rows = Vec::new();
    let mut session = (Config::default(), false);
    for entry in entries {
        let mut row = |kind: &str, field: &str, value: String| {
            rows.push([
                entry.session.to_string(),
                format!("{:.6}", entry.time_s),
                kind.to_string(),
                field.to_string(),
                value,
            ]);
        };
        match &entry.event {
            Event::Session(value) => session = session_config(value),
            Event::Message(DeviceMsg::Model(snapshot)) => {
                if let Ok(report) = report_from_snapshot(snapshot, &session.0, session.1) {
                    row("model", "samples", report.samples.to_string());
                    for term in &report.terms {
                        row("model", &term.term, term.coef.to_string());
                    }
                    if let Some(f) = report.resonance_hz {
                        row("model", "resonance_hz", f.to_string());
                    }
                    if let Some(w) = report.wells {
                        row("model", "wells", w.to_string());
                    }
                }
            }
            Event::Message(message @ DeviceMsg::Health { .. }) => {
                if let Value::Object(map) = message_json(message, &session) {
                    for (field, value) in map {
                        if let Value::Object(figures) = &value {
                            // The drift's figures and the references, a row each (none
                            // without a duty cycle, or with channels about zero).
                            for (name, figure) in figures {
                                row("health", &format!("{field}_{name}"), figure.to_string());
                            }
                        } else if field == "drift" || field == "reference" {
                        } else if field != "kind" {
                            let text = match value {
                                Value::String(s) => s,
                                other => other.to_string(),
                            };
                            row("health", &field, text);
                        }
                    }
                }
            }
            Event::Line(line) => row("log", "line", line.clone()),
            Event::Note(text) => row("note", "text", text.clone()),
            _ => {}
        }
    }
    rows
}

/// A standalone device's references as `lssi log --json` and `lssi monitor --json` give
/// them: x, v, e, each as the device has it in f64 (0: nothing subtracted).
pub fn reference_json(reference: &lssi_proto::WireReference) -> Value {
    json!({
        "x": reference.x,
        "v": reference.v,
        "e": reference.e,
    })
}

/// A standalone device's references in words: "references x 10000.0012 (the model is
/// about the channels less them)", the channels about zero left out.
pub fn reference_text(reference: &lssi_proto::WireReference) -> String {
    let named: Vec<String> = [("x", reference.x), ("v", reference.v), ("e", reference.e)]
        .iter()
        .filter(|(_, r)| *r != 0.0)
        .map(|(name, r)| format!("{name} {r}"))
        .collect();
    format!(
        "references {} (the model is about the channels less them)",
        named.join(", ")
    )
}

/// A duty cycle's drift as `lssi log --json` and `lssi monitor --json` give it.
pub fn drift_json(drift: &lssi_proto::WireDrift) -> Value {
    json!({
        "windows": drift.windows,
        "relative": drift.relative,
        "largest": drift.largest,
        "largest_term": drift.largest_term,
        "support_changes": drift.support_changes,
    })
}

/// A duty cycle's drift in words: "drift over window 3: coefficients moved 2.1 % (RMS), at
/// most 7.5 % (term 4), 1 term in or out".
pub fn drift_text(drift: &lssi_proto::WireDrift) -> String {
    format!(
        "drift over window {}: coefficients moved {:.2} % (RMS), at most {:.2} % (term {}), {} term{} in or out",
        drift.windows,
        100.0 * f64::from(drift.relative),
        100.0 * f64::from(drift.largest),
        drift.largest_term,
        drift.support_changes,
        if drift.support_changes == 1 { "" } else { "s" }
    )
}

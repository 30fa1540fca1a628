//! Strategies, worst-case values and helpers shared by the integration tests.
#![allow(dead_code)]

use lssi_proto::{
    Channels, CompactBatch, CostUnit, DeviceMsg, Error, FrameDecoder, HostMsg, I16Encoding,
    MAX_BATCH, MAX_COMPACT_BATCH, MAX_LOG, MAX_SOLUTIONS, MAX_TERMS, MODEL_PART_LEN, Message,
    ModelPart, ModelSnapshot, NakReason, PROTOCOL_VERSION, PolyFamily, SampleBatch, SampleEncoding,
    SnapshotCause, SolutionSummary, TermCode, TermKind, WireChannels, WireConfig, WireDuty,
    WireLibrary, WireSample, encode,
};
pub use lssi_testkit::wire::{any_f64, any_wire_config};
use proptest::collection::vec;
use proptest::prelude::*;

/// `cases` cases; failures are printed shrunk rather than saved under the source tree.
pub fn cases(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Any f32, NaNs and infinities included: the link must carry the bits, not the value.
pub fn any_f32() -> impl Strategy<Value = f32> {
    any::<u32>().prop_map(f32::from_bits)
}

pub fn channels() -> impl Strategy<Value = Channels> {
    prop_oneof![
        Just(Channels::X),
        Just(Channels::XV),
        Just(Channels::XU),
        Just(Channels::XVU)
    ]
}

pub fn sample(channels: Channels) -> impl Strategy<Value = WireSample> {
    (any_f64(), any_f32(), any_f32(), any_f32()).prop_map(move |(t, x, v, u)| WireSample {
        t,
        x,
        v: channels.has_v().then_some(v),
        u: channels.has_u().then_some(u),
    })
}

pub fn batch() -> impl Strategy<Value = SampleBatch> {
    (any::<u32>(), channels()).prop_flat_map(|(seq, channels)| {
        vec(sample(channels), 0..=MAX_BATCH).prop_map(move |samples| {
            let mut batch = SampleBatch::new(seq, channels);
            for sample in samples {
                batch
                    .push(sample)
                    .expect("at most MAX_BATCH samples of the batch's channels");
            }
            batch
        })
    })
}

pub fn i16_encoding() -> impl Strategy<Value = I16Encoding> {
    (any::<f64>(), any::<f64>(), any::<[f32; 3]>()).prop_map(|(t0, dt, scale)| I16Encoding {
        t0,
        dt,
        scale,
    })
}

pub fn compact_batch() -> impl Strategy<Value = CompactBatch> {
    (
        any::<u32>(),
        any::<u32>(),
        0u8..4,
        vec(any::<[i16; 3]>(), 0..=MAX_COMPACT_BATCH),
    )
        .prop_map(|(seq, start, bits, samples)| {
            let channels = Channels::from_bits(bits).expect("two bits");
            let width = channels.values_per_sample() - 1;
            let mut batch = CompactBatch::new(seq, start, channels);
            for sample in &samples {
                batch.push(&sample[..width]).expect("64 samples fit");
            }
            batch
        })
}

pub fn host_msg() -> impl Strategy<Value = HostMsg> {
    prop_oneof![
        Just(HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION
        }),
        any_wire_config().prop_map(HostMsg::Configure),
        batch().prop_map(HostMsg::Samples),
        Just(HostMsg::Query),
        Just(HostMsg::Reset),
        (any_wire_config(), i16_encoding()).prop_map(|(mut config, encoding)| {
            config.encoding = SampleEncoding::I16(encoding);
            HostMsg::Configure(config)
        }),
        compact_batch().prop_map(HostMsg::Compact),
        any::<u16>().prop_map(|offset| HostMsg::ModelPart { offset }),
    ]
}

pub fn term_kind() -> impl Strategy<Value = TermKind> {
    prop_oneof![
        Just(TermKind::Constant),
        Just(TermKind::Monomial),
        Just(TermKind::Sin),
        Just(TermKind::Cos),
        Just(TermKind::Input),
    ]
}

pub fn nak_reason() -> impl Strategy<Value = NakReason> {
    prop_oneof![
        Just(NakReason::Crc),
        Just(NakReason::Decode),
        Just(NakReason::Overflow),
        Just(NakReason::OutOfOrder),
        Just(NakReason::NotConfigured),
        Just(NakReason::BadConfig),
        Just(NakReason::Busy),
        Just(NakReason::VersionMismatch),
    ]
}

pub fn cost_unit() -> impl Strategy<Value = CostUnit> {
    prop_oneof![
        Just(CostUnit::Instructions),
        Just(CostUnit::Cycles),
        Just(CostUnit::Ticks),
        Just(CostUnit::Nanoseconds),
    ]
}

pub fn snapshot() -> impl Strategy<Value = ModelSnapshot> {
    let term =
        (term_kind(), any::<u8>(), any::<u8>()).prop_map(|(kind, a, b)| TermCode { kind, a, b });
    let solution =
        (any_f32(), any_f32(), any::<u32>()).prop_map(|(threshold, mean_error, support)| {
            SolutionSummary {
                threshold,
                mean_error,
                support,
            }
        });
    (
        vec(term, 0..=MAX_TERMS),
        vec(any_f32(), 0..=MAX_TERMS),
        vec(solution, 0..=MAX_SOLUTIONS),
        (any::<u8>(), any::<u8>(), any::<u8>(), any_f64()),
        (
            proptest::option::of(any_f64()),
            proptest::option::of(any_f64()),
        ),
        (any_f32(), any_f32(), any::<u64>(), any::<u64>()),
        (any::<u64>(), snapshot_cause()),
    )
        .prop_map(
            |(
                terms,
                coefficients,
                solutions,
                (selected, k_x, k_v, omega),
                (resonance_hz, wells),
                rest,
                (rows, cause),
            )| {
                let (offset_x, offset_v, samples, rejected) = rest;
                ModelSnapshot {
                    terms: terms.into_iter().collect(),
                    coefficients: coefficients.into_iter().collect(),
                    solutions: solutions.into_iter().collect(),
                    selected,
                    k_x,
                    k_v,
                    omega,
                    resonance_hz,
                    wells,
                    offset_x,
                    offset_v,
                    samples,
                    rejected,
                    rows,
                    cause,
                }
            },
        )
}

pub fn snapshot_cause() -> impl Strategy<Value = SnapshotCause> {
    prop_oneof![
        Just(SnapshotCause::Scheduled),
        Just(SnapshotCause::Query),
        Just(SnapshotCause::Final)
    ]
}

pub fn device_msg() -> impl Strategy<Value = DeviceMsg> {
    prop_oneof![
        (any::<u8>(), any::<u16>(), any::<u16>()).prop_map(
            |(max_terms, window_capacity, max_batch)| {
                DeviceMsg::HelloReply {
                    protocol_version: PROTOCOL_VERSION,
                    max_terms,
                    window_capacity,
                    max_batch,
                }
            }
        ),
        any::<u32>().prop_map(|seq| DeviceMsg::Ack { seq }),
        (any::<u32>(), nak_reason()).prop_map(|(seq, reason)| DeviceMsg::Nak { seq, reason }),
        snapshot().prop_map(DeviceMsg::Model),
        (
            (
                any::<u64>(),
                any::<u64>(),
                any::<u16>(),
                any::<u32>(),
                any::<u32>()
            ),
            (cost_unit(), any::<u32>(), any::<u32>(), any::<u32>()),
            (
                any::<u32>(),
                any::<u32>(),
                any::<u32>(),
                any::<u32>(),
                any::<u32>()
            ),
            (
                any::<u32>(),
                any::<u16>(),
                any::<u32>(),
                any::<u32>(),
                0.0f32..1.0e6
            ),
            proptest::option::of((
                any::<u32>(),
                0.0f32..10.0,
                0.0f32..10.0,
                any::<u8>(),
                any::<u8>()
            )),
            proptest::option::of((-1.0e9f64..1.0e9, -1.0e9f64..1.0e9, -1.0e9f64..1.0e9)),
        )
            .prop_map(
                |(
                    (samples, rejected, buffer_fill, cost_mean, cost_max),
                    (cost_unit, watchdog, crc_errors, frames_ok),
                    (screen_cost, screen_cost_max, screenings, duplicates, decode_errors),
                    (
                        overruns,
                        queue_high_water,
                        latency_max_ns,
                        screenings_skipped,
                        sample_rate_hz,
                    ),
                    drift,
                    reference,
                )| DeviceMsg::Health {
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
                    drift: drift.map(
                        |(windows, relative, largest, largest_term, support_changes)| {
                            lssi_proto::WireDrift {
                                windows,
                                relative,
                                largest,
                                largest_term,
                                support_changes,
                            }
                        }
                    ),
                    reference: reference.map(|(x, v, e)| lssi_proto::WireReference { x, v, e }),
                },
            ),
        vec(any::<u8>(), 0..=MAX_LOG).prop_map(|bytes| DeviceMsg::Log {
            bytes: bytes.into_iter().collect()
        }),
        (
            any::<u16>(),
            any::<u16>(),
            any::<u32>(),
            vec(any::<u8>(), 0..=MODEL_PART_LEN)
        )
            .prop_map(
                |(total, offset, crc, bytes)| DeviceMsg::ModelPart(ModelPart {
                    total,
                    offset,
                    crc,
                    bytes: bytes.into_iter().collect(),
                })
            ),
    ]
}

/// The largest encoding of each shape: full vectors, widest varints, every `Option` `Some`.
pub fn worst_batch() -> SampleBatch {
    let mut batch = SampleBatch::new(u32::MAX, Channels::XVU);
    while !batch.is_full() {
        batch
            .push(WireSample {
                t: -1.5,
                x: 2.5,
                v: Some(-3.5),
                u: Some(4.5),
            })
            .expect("room until full");
    }
    batch
}

pub fn worst_config() -> WireConfig {
    WireConfig {
        sample_period: 1e-3,
        window: u16::MAX,
        derivative_degree: u8::MAX,
        library: WireLibrary {
            poly_order: u8::MAX,
            family: PolyFamily::OddFamilies,
            constant: true,
            harmonics: u8::MAX,
            input: true,
        },
        omega: 21.4,
        channels: WireChannels {
            velocity: true,
            input: true,
        },
        memory: Some(10.0),
        screening_period: u32::MAX,
        thresholds: u8::MAX,
        smoothing: true,
        row_stride: u16::MAX,
        parsimony: 0.05,
        offsets: true,
        max_abs: 1e9,
        test_rows: u16::MAX,
        encoding: SampleEncoding::I16(I16Encoding {
            t0: 1e300,
            dt: 1e-300,
            scale: [f32::MAX; 3],
        }),
        duty: Some(WireDuty {
            window: f32::MAX,
            interval: f32::MAX,
            model_every: u16::MAX,
        }),
    }
}

pub fn worst_snapshot() -> ModelSnapshot {
    let term = TermCode {
        kind: TermKind::Input,
        a: u8::MAX,
        b: u8::MAX,
    };
    let solution = SolutionSummary {
        threshold: 0.1,
        mean_error: 0.2,
        support: u32::MAX,
    };
    ModelSnapshot {
        terms: core::iter::repeat_n(term, MAX_TERMS).collect(),
        coefficients: core::iter::repeat_n(1.0, MAX_TERMS).collect(),
        solutions: core::iter::repeat_n(solution, MAX_SOLUTIONS).collect(),
        selected: u8::MAX,
        k_x: u8::MAX,
        k_v: u8::MAX,
        omega: 21.4,
        resonance_hz: Some(3.2),
        wells: Some(2.1e-3),
        offset_x: 1e-4,
        offset_v: -1e-4,
        samples: u64::MAX,
        rejected: u64::MAX,
        rows: u64::MAX,
        cause: SnapshotCause::Query,
    }
}

/// The largest value of every variant of both enums.
pub fn worst_compact_batch() -> CompactBatch {
    let mut batch = CompactBatch::new(u32::MAX, u32::MAX, Channels::XVU);
    while batch.push(&[i16::MIN, i16::MAX, -1]).is_ok() {}
    batch
}

pub fn worst_model_part() -> ModelPart {
    ModelPart {
        total: u16::MAX,
        offset: u16::MAX,
        crc: u32::MAX,
        bytes: core::iter::repeat_n(0xFF, MODEL_PART_LEN).collect(),
    }
}

pub fn worst_host_msgs() -> Vec<HostMsg> {
    vec![
        HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
        },
        HostMsg::Configure(worst_config()),
        HostMsg::Samples(worst_batch()),
        HostMsg::Query,
        HostMsg::Reset,
        HostMsg::Compact(worst_compact_batch()),
        HostMsg::ModelPart { offset: u16::MAX },
    ]
}

pub fn worst_device_msgs() -> Vec<DeviceMsg> {
    vec![
        DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            max_terms: u8::MAX,
            window_capacity: u16::MAX,
            max_batch: u16::MAX,
        },
        DeviceMsg::Ack { seq: u32::MAX },
        DeviceMsg::Nak {
            seq: u32::MAX,
            reason: NakReason::VersionMismatch,
        },
        DeviceMsg::Model(worst_snapshot()),
        DeviceMsg::Health {
            samples: u64::MAX,
            rejected: u64::MAX,
            buffer_fill: u16::MAX,
            cost_mean: u32::MAX,
            cost_max: u32::MAX,
            cost_unit: CostUnit::Nanoseconds,
            watchdog: u32::MAX,
            crc_errors: u32::MAX,
            frames_ok: u32::MAX,
            screen_cost: u32::MAX,
            screen_cost_max: u32::MAX,
            screenings: u32::MAX,
            duplicates: u32::MAX,
            decode_errors: u32::MAX,
            overruns: u32::MAX,
            queue_high_water: u16::MAX,
            latency_max_ns: u32::MAX,
            screenings_skipped: u32::MAX,
            sample_rate_hz: f32::MAX,
            drift: Some(lssi_proto::WireDrift {
                windows: u32::MAX,
                relative: f32::MAX,
                largest: f32::MAX,
                largest_term: u8::MAX,
                support_changes: u8::MAX,
            }),
            reference: Some(lssi_proto::WireReference {
                x: f64::MAX,
                v: f64::MAX,
                e: f64::MAX,
            }),
        },
        DeviceMsg::Log {
            bytes: core::iter::repeat_n(0xA5, MAX_LOG).collect(),
        },
        DeviceMsg::ModelPart(worst_model_part()),
    ]
}

/// The frame of `message`, as a `Vec`.
pub fn frame<T: Message>(message: &T) -> Vec<u8> {
    let mut out = vec![0u8; T::MAX_FRAME_LEN];
    let len = encode(message, &mut out).expect("MAX_FRAME_LEN always suffices");
    out.truncate(len);
    out
}

/// Every result a fresh decoder gives for `chunks`, fed in order.
pub fn decode_chunks<T: Message, const N: usize>(chunks: &[&[u8]]) -> Vec<Result<T, Error>> {
    let mut decoder = FrameDecoder::<N>::new();
    let mut results = Vec::new();
    for chunk in chunks {
        results.extend(decoder.feed::<T>(chunk));
        assert!(decoder.buffered() <= N);
    }
    results
}

/// A frame around an arbitrary payload, with a correct CRC: for payloads `encode` never makes.
pub fn frame_payload(payload: &[u8]) -> Vec<u8> {
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(payload);
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = vec![0u8; raw.len() + raw.len() / 254 + 2];
    let len = cobs::encode(&raw, &mut out);
    out.truncate(len);
    out.push(0);
    out
}

//! Arbitrary bytes through the telemetry-log reader and `lssi log`'s decoding: an error or
//! entries, never a panic (issue 16, item 7).

#![allow(clippy::unwrap_used)]

use lssi_host::telemetry::decode::{csv_rows, decode, entry_json, render_text, session_config};
use lssi_host::telemetry::defmt::DefmtLines;
use lssi_host::telemetry::{MAGIC, RecordKind, encode_record, read_log};
use proptest::collection::vec;
use proptest::prelude::*;

/// What a session record might hold: JSON objects with the keys a writer uses and values of
/// any type, or bytes that are not JSON.
fn session_data() -> impl Strategy<Value = Vec<u8>> {
    let value = prop_oneof![
        Just("null".to_owned()),
        any::<f64>().prop_map(|v| if v.is_finite() {
            v.to_string()
        } else {
            "1e308".into()
        }),
        any::<i64>().prop_map(|v| v.to_string()),
        "[a-z]{0,8}".prop_map(|s| format!("{s:?}")),
        Just("{}".to_owned()),
        Just("[1,2,3]".to_owned()),
    ];
    let key = prop_oneof![
        Just("config"),
        Just("wire_config"),
        Just("f32"),
        Just("version"),
        Just("sample_period"),
        Just("omega"),
        Just("window"),
    ];
    prop_oneof![
        vec((key, value), 0..6).prop_map(|pairs| {
            let fields: Vec<String> = pairs.iter().map(|(k, v)| format!("{k:?}:{v}")).collect();
            format!("{{{}}}", fields.join(",")).into_bytes()
        }),
        vec(any::<u8>(), 0..64),
    ]
}

fn record() -> impl Strategy<Value = (u8, u64, Vec<u8>)> {
    prop_oneof![
        (1u8..=5, any::<u64>(), vec(any::<u8>(), 0..200)),
        (Just(1u8), any::<u64>(), session_data()),
        (0u8..=255, any::<u64>(), vec(any::<u8>(), 0..16)),
    ]
}

fn decode_everything(bytes: &[u8]) {
    let Ok(contents) = read_log(bytes) else {
        return;
    };
    let entries = decode(&contents.records, None);
    let _ = render_text(&entries);
    let _ = csv_rows(&entries);
    let mut session = session_config(&serde_json::Value::Null);
    for entry in &entries {
        if let lssi_host::telemetry::decode::Event::Session(value) = &entry.event {
            session = session_config(value);
        }
        let _ = entry_json(entry, &session);
    }
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic_the_log_reader(bytes in vec(any::<u8>(), 0..2000)) {
        decode_everything(&bytes);
        let mut logged = MAGIC.to_vec();
        logged.extend_from_slice(&bytes);
        decode_everything(&logged);
    }

    /// Whole records (good CRCs) of every kind with arbitrary contents, some cut or edited.
    #[test]
    fn arbitrary_records_never_panic_the_decoder(
        records in vec(record(), 0..12),
        cut in any::<prop::sample::Index>(),
        edits in vec((any::<prop::sample::Index>(), any::<u8>()), 0..3),
    ) {
        let mut bytes = MAGIC.to_vec();
        for (kind, time, data) in &records {
            match RecordKind::from_code(*kind) {
                Some(kind) => bytes.extend_from_slice(&encode_record(kind, *time, data)),
                None => {
                    // An unknown kind with a good CRC, written by hand.
                    let mut body = vec![*kind];
                    body.extend_from_slice(&time.to_le_bytes());
                    body.extend_from_slice(data);
                    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(&body);
                    bytes.extend_from_slice(&(body.len() as u32).to_le_bytes());
                    bytes.extend_from_slice(&crc.to_le_bytes());
                    bytes.extend_from_slice(&body);
                }
            }
        }
        decode_everything(&bytes);
        let mut edited = bytes.clone();
        for (at, value) in &edits {
            let i = at.index(edited.len());
            edited[i] = *value;
        }
        decode_everything(&edited);
        let cut = cut.index(bytes.len() + 1);
        decode_everything(&bytes[..cut]);
    }

    #[test]
    fn arbitrary_defmt_bytes_never_panic(chunks in vec(vec(any::<u8>(), 0..100), 0..8)) {
        let mut lines = DefmtLines::new(None);
        for chunk in &chunks {
            let _ = lines.push(chunk);
        }
    }
}

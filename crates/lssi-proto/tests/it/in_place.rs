//! `decode_host_frame` (a batch read in place) agrees with `decode_frame::<HostMsg>` on every
//! input: the same frames accepted, the same messages, the same errors.

use crate::common;

use common::*;
use lssi_proto::{Error, HostMsg, decode_frame, decode_host_frame};
use proptest::collection::vec;
use proptest::prelude::*;

/// A decoding result with the message as its frame's bytes (NaN samples compare bit for bit).
fn bits(result: Result<HostMsg, Error>) -> Result<Vec<u8>, Error> {
    result.map(|message| frame(&message))
}

/// Both decoders on a copy of `frame` each; they must agree.
fn assert_agree(frame: &[u8]) -> Result<(), TestCaseError> {
    let mut owned = frame.to_vec();
    let mut in_place = frame.to_vec();
    let expected = decode_frame::<HostMsg>(&mut owned);
    let got = decode_host_frame(&mut in_place).map(|command| command.to_msg());
    prop_assert_eq!(bits(got), bits(expected));
    Ok(())
}

/// A frame without its trailing `0x00`, as the device's receive buffer holds it.
fn body(message: &HostMsg) -> Vec<u8> {
    let mut frame = frame(message);
    frame.pop();
    frame
}

#[test]
fn worst_messages_agree() {
    for message in worst_host_msgs() {
        let mut bytes = body(&message);
        let command = decode_host_frame(&mut bytes).expect("decodes");
        assert_eq!(frame(&command.to_msg()), frame(&message));
    }
}

proptest! {
    #![proptest_config(cases(512))]

    #[test]
    fn messages_agree(message in host_msg()) {
        let mut bytes = body(&message);
        let command = decode_host_frame(&mut bytes).map(|c| c.to_msg());
        prop_assert_eq!(bits(command), Ok(frame(&message)));
        if let lssi_proto::HostCommand::Samples(batch) = decode_host_frame(&mut body(&message)).unwrap() {
            let HostMsg::Samples(owned) = &message else { panic!("not a batch") };
            prop_assert_eq!(batch.len(), owned.len());
            prop_assert_eq!(batch.seq, owned.seq);
            prop_assert_eq!(batch.channels(), owned.channels());
            for (a, b) in batch.iter().zip(owned.iter()) {
                prop_assert_eq!(a.t.to_bits(), b.t.to_bits());
                prop_assert_eq!(a.x.to_bits(), b.x.to_bits());
                prop_assert_eq!(a.v.map(f32::to_bits), b.v.map(f32::to_bits));
                prop_assert_eq!(a.u.map(f32::to_bits), b.u.map(f32::to_bits));
            }
        }
    }

    #[test]
    fn arbitrary_frames_agree(bytes in vec(any::<u8>(), 0..600)) {
        assert_agree(&bytes)?;
    }

    #[test]
    fn arbitrary_payloads_agree(payload in vec(any::<u8>(), 0..520)) {
        // Valid COBS and CRC around random bytes: postcard's checks are what is compared.
        let mut frame = frame_payload(&payload);
        frame.pop();
        assert_agree(&frame)?;
    }

    #[test]
    fn mutated_payloads_agree(message in host_msg(), index in any::<usize>(), byte in any::<u8>(), cut in any::<usize>()) {
        // A valid message's payload, one byte changed and possibly cut short.
        let mut payload = body(&message);
        let len = cobs::decode_in_place(&mut payload).unwrap();
        payload.truncate(len - 4);
        let i = index % payload.len();
        payload[i] = byte;
        payload.truncate(cut % (payload.len() + 1));
        let mut frame = frame_payload(&payload);
        frame.pop();
        assert_agree(&frame)?;
    }
}

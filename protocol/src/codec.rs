//! Bytes <-> messages. bincode 2 (standard config: little-endian, variable-length
//! integers, with a decode limit) behind these functions only: bincode is unmaintained
//! (RUSTSEC-2025-0141, informational), so swapping it means changing this file alone.
//! docs/protocol.md describes the bytes; the tests below pin that description.

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::DecodeError;

/// Largest message either side accepts (bytes).
pub const MAX_MESSAGE_BYTES: usize = 16 * 1024 * 1024;

type Config = bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Varint,
    bincode::config::Limit<MAX_MESSAGE_BYTES>,
>;

/// The one configuration: the limit also bounds what length prefixes may claim, so a
/// forged length cannot make the decoder allocate more than `MAX_MESSAGE_BYTES`.
fn config() -> Config {
    bincode::config::standard().with_limit::<MAX_MESSAGE_BYTES>()
}

/// Encodes a message. Our types always serialize, so this cannot fail. The receiver
/// refuses messages over `MAX_MESSAGE_BYTES`; a sender that may produce one (a large
/// render) checks the length.
///
/// The buffer starts with room for a single env's step reply, so one allocation holds it
/// (growing from empty took eight); batches grow it a few times. Zenoh then owns it.
pub fn encode<T: Serialize>(value: &T) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(ENCODE_START_BYTES);
    bincode::serde::encode_into_std_write(value, &mut bytes, config()).unwrap_or_else(|e| {
        // Only reachable through a Serialize impl that errors (a map without a length);
        // this crate has none.
        panic!("encoding a protocol message failed: {e}")
    });
    bytes
}

/// `encode`'s first buffer (bytes): more than a highway.toml step reply (about 1 KB).
const ENCODE_START_BYTES: usize = 2048;

/// Decodes a whole message, refusing oversized, truncated, trailing and garbage bytes.
pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, DecodeError> {
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(DecodeError::TooLarge { len: bytes.len(), limit: MAX_MESSAGE_BYTES });
    }
    let (value, used) = bincode::serde::decode_from_slice(bytes, config()).map_err(invalid)?;
    if used != bytes.len() {
        return Err(DecodeError::TrailingBytes { used, len: bytes.len() });
    }
    Ok(value)
}

/// The protocol version at the front of an envelope (`Request` or `Reply`), read even
/// when the rest does not decode (a message of another version), so the reply can say
/// "wrong version". `None` when not even a `u16` is there.
pub fn peek_version(bytes: &[u8]) -> Option<u16> {
    bincode::serde::decode_from_slice::<u16, _>(bytes, config()).ok().map(|(version, _)| version)
}

/// The client id after a request's version, read without decoding the body: a server
/// queues a request by its sender before paying for the rest. `None` when the front is
/// not a version and an id.
pub fn peek_client(bytes: &[u8]) -> Option<crate::ClientId> {
    bincode::serde::decode_from_slice::<(u16, crate::ClientId), _>(bytes, config()).ok().map(|((_, client), _)| client)
}

fn invalid(error: bincode::error::DecodeError) -> DecodeError {
    use bincode::error::DecodeError as E;
    DecodeError::Invalid(match error {
        E::UnexpectedEnd { additional } => format!("truncated: at least {additional} more byte(s) expected"),
        E::LimitExceeded => format!("its lengths claim more than the {MAX_MESSAGE_BYTES}-byte limit"),
        E::OtherString(text) => text,
        E::InvalidBooleanValue(byte) => format!("{byte} is not a bool (0 or 1)"),
        E::Utf8 { inner } => format!("a string is not UTF-8: {inner}"),
        // The rest are rare and bincode's Display is its Debug; good enough for them.
        other => other.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Action, BatchStep, ClientId, EnvId, OptionValue, PROTOCOL_VERSION, Request, RequestBody};

    fn step_request() -> Request {
        Request {
            version: PROTOCOL_VERSION,
            client: ClientId(3),
            body: RequestBody::Step {
                env: EnvId(u128::MAX - 7),
                seq: 1 << 40,
                actions: vec![("ego".into(), Action::Meta(3)), ("b".into(), Action::Continuous([0.5, -1.0]))],
            },
        }
    }

    #[test]
    fn every_truncation_is_refused_as_truncated() {
        let bytes = encode(&step_request());
        for cut in 0..bytes.len() {
            match decode::<Request>(&bytes[..cut]) {
                Err(DecodeError::Invalid(reason)) => assert!(reason.starts_with("truncated"), "{cut}: {reason}"),
                other => panic!("a message cut at {cut} of {} bytes gave {other:?}", bytes.len()),
            }
        }
        assert_eq!(decode::<Request>(&bytes), Ok(step_request()));
    }

    #[test]
    fn trailing_bytes_are_refused_and_counted() {
        let bytes = encode(&step_request());
        let mut longer = bytes.clone();
        longer.extend([0, 0]);
        let err = decode::<Request>(&longer).unwrap_err();
        assert_eq!(err, DecodeError::TrailingBytes { used: bytes.len(), len: bytes.len() + 2 });
    }

    #[test]
    fn oversized_payloads_are_refused_before_decoding() {
        // A valid message padded past the limit: refused for its size, not its tail.
        let mut huge = encode(&step_request());
        huge.resize(MAX_MESSAGE_BYTES + 1, 0);
        assert_eq!(
            decode::<Request>(&huge),
            Err(DecodeError::TooLarge { len: MAX_MESSAGE_BYTES + 1, limit: MAX_MESSAGE_BYTES })
        );
        // Exactly at the limit is not "too large" (here: trailing bytes).
        huge.truncate(MAX_MESSAGE_BYTES);
        assert!(matches!(decode::<Request>(&huge), Err(DecodeError::TrailingBytes { .. })));
    }

    #[test]
    fn garbage_is_refused_with_a_reason() {
        // Version 1, client 3, then RequestBody variant 200: there is no such request.
        let err = decode::<Request>(&[1, 3, 200]).unwrap_err();
        assert!(matches!(&err, DecodeError::Invalid(reason) if reason.contains("200")), "{err}");
        // 255 is a reserved varint marker.
        assert!(matches!(decode::<Request>(&[255; 9]), Err(DecodeError::Invalid(_))));
        // A bool that is 2: OptionValue::Bool(2).
        let err = decode::<OptionValue>(&[0, 2]).unwrap_err();
        assert_eq!(err, DecodeError::Invalid("2 is not a bool (0 or 1)".into()));
        // A string that is not UTF-8: OptionValue::Str([0xff]).
        assert!(matches!(decode::<OptionValue>(&[3, 1, 0xff]), Err(DecodeError::Invalid(r)) if r.contains("UTF-8")));
    }

    #[test]
    fn forged_lengths_are_refused_without_allocating_them() {
        // StepBatch claiming 2^60 steps, then the first one's bytes only.
        let mut bomb = vec![1, 3, 4, 253];
        bomb.extend((1u64 << 60).to_le_bytes());
        bomb.extend(encode(&BatchStep { env: EnvId(1), seq: 0, actions: vec![] }));
        assert!(matches!(decode::<Request>(&bomb), Err(DecodeError::Invalid(_))));
        // A string claiming 2^40 bytes: refused by the limit before any allocation.
        let mut bomb = vec![3, 253];
        bomb.extend((1u64 << 40).to_le_bytes());
        let err = decode::<OptionValue>(&bomb).unwrap_err();
        assert!(matches!(&err, DecodeError::Invalid(r) if r.contains("limit")), "{err}");
    }

    #[test]
    fn peek_version_reads_the_version_even_when_the_body_does_not_decode() {
        // A request from "version 300" whose body is a variant this version lacks.
        let future = [251, 0x2c, 0x01, 3, 99, 1, 2, 3];
        assert!(decode::<Request>(&future).is_err());
        assert_eq!(peek_version(&future), Some(300));
        assert_eq!(peek_version(&[]), None);
        assert_eq!(peek_version(&[252, 0, 0, 1, 0]), None, "a u32-sized first varint is not a version");
    }

    #[test]
    fn peek_client_reads_the_sender_before_the_body() {
        // Version 300, client 7 (one varint byte), then a body this version lacks.
        assert_eq!(peek_client(&[251, 0x2c, 0x01, 7, 99, 1, 2, 3]), Some(ClientId(7)));
        assert_eq!(peek_client(&[1]), None, "a version alone names no client");
    }

    // The layout of docs/protocol.md, with every expected byte derived by hand from the
    // rules written there (not copied from encoder output).
    #[test]
    fn the_byte_layout_is_what_docs_protocol_md_says() {
        // Request { version: 1, client: ClientId(300), body: Close { env: EnvId(2) } }:
        // version 1 -> [1]; client 300 -> 251 marker + u16 LE 0x012C -> [251, 0x2C, 0x01];
        // body: Close is variant 8 -> [8]; env 2 -> [2].
        let close = Request { version: 1, client: ClientId(300), body: RequestBody::Close { env: EnvId(2) } };
        assert_eq!(encode(&close), [1, 251, 0x2C, 0x01, 8, 2]);

        // Request { version: 1, client: ClientId(7), body: Step { env: EnvId(1 << 64),
        //   seq: 70000, actions: [("ego", Meta(3)), ("b", Continuous([1.0, -2.0]))] } }
        let step = Request {
            version: 1,
            client: ClientId(7),
            body: RequestBody::Step {
                env: EnvId(1 << 64),
                seq: 70_000,
                actions: vec![("ego".into(), Action::Meta(3)), ("b".into(), Action::Continuous([1.0, -2.0]))],
            },
        };
        #[rustfmt::skip]
        let expected: Vec<u8> = vec![
            1,                                      // version
            7,                                      // client
            3,                                      // RequestBody::Step is variant 3
            254, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, // env 2^64: 254 + u128 LE
            252, 0x70, 0x11, 0x01, 0x00,            // seq 70000 = 0x11170: 252 + u32 LE
            2,                                      // two (agent, action) pairs
            3, b'e', b'g', b'o', 0, 3,              // "ego", Action::Meta (0) of 3
            1, b'b', 1,                             // "b", Action::Continuous (1)
            0x00, 0x00, 0x80, 0x3F,                 // 1.0f32 LE (0x3F800000)
            0x00, 0x00, 0x00, 0xC0,                 // -2.0f32 LE (0xC0000000)
        ];
        assert_eq!(encode(&step), expected);

        // Reset { env: EnvId(250), seq: 251, seed: Some(u64::MAX), options: { overrides: [("k", Int(-3))] } }
        // under Request { version: 1, client: ClientId(0) }.
        let reset = Request {
            version: 1,
            client: ClientId(0),
            body: RequestBody::Reset {
                env: EnvId(250),
                seq: 251,
                seed: Some(u64::MAX),
                options: crate::ResetOptions { overrides: vec![("k".into(), OptionValue::Int(-3))] },
            },
        };
        #[rustfmt::skip]
        let expected: Vec<u8> = vec![
            1, 0, 2,                                // version, client, Reset is variant 2
            250,                                    // env 250: the largest one-byte varint
            251, 251, 0,                            // seq 251: 251 + u16 LE
            1, 253, 255, 255, 255, 255, 255, 255, 255, 255, // Some, then u64::MAX: 253 + u64 LE
            1, 1, b'k',                             // one override (a struct is its fields), "k"
            1, 5,                                   // OptionValue::Int (1), -3 zigzag -> 5
        ];
        assert_eq!(encode(&reset), expected);

        // Bytes-sized values are raw bytes, never varints: u8 255 and i8 -1 are [255].
        assert_eq!(encode(&crate::TensorData::U8(vec![255, 7])), [1, 2, 255, 7]);
        assert_eq!(encode(&crate::TensorData::I8(vec![-1, 1])), [2, 2, 255, 1]);
        // None is [0]; bool true is [1]; f64 is 8 bytes LE.
        assert_eq!(encode(&None::<u64>), [0]);
        assert_eq!(encode(&crate::InfoValue::Bool(true)), [1, 1]);
        assert_eq!(encode(&crate::InfoValue::F64(1.0)), [0, 0, 0, 0, 0, 0, 0, 0xF0, 0x3F]);
    }

    #[test]
    fn longer_varint_forms_than_needed_still_decode() {
        // docs/protocol.md: decoders accept a wider marker than the value needs.
        assert_eq!(decode::<u64>(&[251, 5, 0]), Ok(5));
        assert_eq!(decode::<u16>(&[252, 5, 0, 0, 0]).ok(), None, "but not one wider than the type");
    }
}

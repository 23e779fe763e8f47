//! Bad input gives a clear error, never a panic.

mod common;

use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, KeyValue};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_msgs::{CdrError, RosMessage};
use proptest::prelude::*;

#[test]
fn every_truncation_is_an_error() {
    fn check<T: RosMessage>(msg: &T) {
        let bytes = msg.to_cdr();
        for len in 0..bytes.len() {
            let err = T::from_cdr(&bytes[..len]).err().unwrap_or_else(|| {
                panic!("{}: {len} of {} bytes decoded", T::TYPE_NAME, bytes.len())
            });
            if len < 4 {
                assert_eq!(
                    err,
                    CdrError::MissingHeader {
                        type_name: T::TYPE_NAME,
                        len
                    }
                );
            } else {
                assert!(
                    matches!(err, CdrError::Truncated { len: l, offset, .. } if l == len && offset <= len),
                    "{}: {len} bytes gave {err:?}",
                    T::TYPE_NAME
                );
            }
        }
    }
    check(&common::header("rig"));
    check(&common::rig_sample());
    check(&common::excitation_random());
    check(&common::harmonic_phasors());
    check(&common::identified_parameters());
    check(&common::diagnostic_array());
}

#[test]
fn truncated_message_names_type_and_sizes() {
    let bytes = common::header("rig").to_cdr();
    let err = Header::from_cdr(&bytes[..14]).unwrap_err();
    assert_eq!(
        err,
        CdrError::Truncated {
            type_name: "std_msgs/msg/Header",
            len: 14,
            offset: 12
        }
    );
    let text = err.to_string();
    assert!(text.contains("std_msgs/msg/Header"), "{text}");
    assert!(text.contains("truncated"), "{text}");
    assert!(text.contains("14 bytes"), "{text}");
}

#[test]
fn bad_encapsulation_header() {
    let mut bytes = common::rig_sample().to_cdr();
    for bad in [[0x00, 0x03], [0x00, 0x07], [0x01, 0x00], [0xFF, 0xFF]] {
        bytes[0] = bad[0];
        bytes[1] = bad[1];
        let err = RigSample::from_cdr(&bytes).unwrap_err();
        assert!(
            matches!(err, CdrError::BadEncapsulation { header, .. } if header[..2] == bad),
            "{err:?}"
        );
        assert!(err.to_string().contains("encapsulation header"), "{err}");
    }
}

#[test]
fn invalid_utf8() {
    let mut bytes = KeyValue::new("k", "v1").to_cdr();
    bytes[16] = 0xFF; // the 'v'
    let err = KeyValue::from_cdr(&bytes).unwrap_err();
    assert!(matches!(err, CdrError::InvalidUtf8 { .. }), "{err:?}");
    assert!(err.to_string().contains("UTF-8"), "{err}");
}

#[test]
fn bad_bool() {
    let mut msg = common::harmonic_phasors();
    msg.settled = true;
    let bytes = msg.to_cdr();
    // `settled` follows the 4-aligned harmonic_cap; 3 bytes of padding and t_ref (8 bytes)
    // follow it.
    let at = bytes.len() - 12;
    assert_eq!(bytes[at], 1);
    let mut bad = bytes.clone();
    bad[at] = 7;
    let err = HarmonicPhasors::from_cdr(&bad).unwrap_err();
    assert_eq!(
        err,
        CdrError::BadBool {
            type_name: "forcemap_msgs/msg/HarmonicPhasors",
            offset: at,
            value: 7
        }
    );
}

#[test]
fn trailing_bytes_mean_wrong_type() {
    // A RigSample read as a Header: the header decodes, then many bytes are left.
    let bytes = common::rig_sample().to_cdr();
    let err = Header::from_cdr(&bytes).unwrap_err();
    assert!(matches!(err, CdrError::TrailingBytes { .. }), "{err:?}");
    assert!(err.to_string().contains("wrong message type"), "{err}");
}

#[test]
fn huge_sequence_count_is_truncation_not_allocation() {
    // A DiagnosticArray that claims 2^32-1 statuses.
    let mut bytes = DiagnosticArray::default().to_cdr();
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        DiagnosticArray::from_cdr(&bytes),
        Err(CdrError::Truncated { .. })
    ));
}

fn decode_all(bytes: &[u8]) {
    let _ = forcemap_msgs::builtin_interfaces::Time::from_cdr(bytes);
    let _ = Header::from_cdr(bytes);
    let _ = KeyValue::from_cdr(bytes);
    let _ = DiagnosticArray::from_cdr(bytes);
    let _ = RigSample::from_cdr(bytes);
    let _ = ExcitationState::from_cdr(bytes);
    let _ = HarmonicPhasors::from_cdr(bytes);
    let _ = IdentifiedParameters::from_cdr(bytes);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        decode_all(&bytes);
    }

    #[test]
    fn random_bodies_after_a_valid_header_never_panic(
        body in proptest::collection::vec(any::<u8>(), 0..256),
        be in any::<bool>(),
    ) {
        let mut bytes = vec![0, if be { 0 } else { 1 }, 0, 0];
        bytes.extend(body);
        decode_all(&bytes);
    }

    #[test]
    fn mutated_valid_messages_never_panic(at in 0usize..400, value in any::<u8>()) {
        for mut bytes in [
            common::harmonic_phasors().to_cdr(),
            common::identified_parameters().to_cdr(),
            common::diagnostic_array().to_cdr(),
        ] {
            let i = at % bytes.len();
            bytes[i] = value;
            decode_all(&bytes);
        }
    }
}

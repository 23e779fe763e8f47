//! Bytes -> `from_cdr` of every forcemap_msgs message type. Decoding must only ever return
//! `Err`, never panic. A message that decodes is also re-encoded (encoding a decoded message must
//! decode again to the same bytes) and put through the conversions to forcemap_math types that
//! consumers call next (which must also only return errors).
#![no_main]

use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{
    AxisSample, ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample,
};
use forcemap_msgs::std_msgs::Header;
use libfuzzer_sys::fuzz_target;

/// Decodes `data` as `T`; if it decodes, re-encoding must be stable (decode(encode(m)) encodes
/// to the same bytes). Compares bytes, not values, so NaN fields do not matter.
fn check<T: RosMessage>(data: &[u8]) -> Option<T> {
    let msg = T::from_cdr(data).ok()?;
    let bytes = msg.to_cdr();
    let again = T::from_cdr(&bytes)
        .unwrap_or_else(|e| panic!("{}: re-encoded message does not decode: {e}", T::TYPE_NAME));
    assert_eq!(
        again.to_cdr(),
        bytes,
        "{}: encode/decode/encode is not stable",
        T::TYPE_NAME
    );
    Some(msg)
}

fuzz_target!(|data: &[u8]| {
    check::<Time>(data);
    check::<Header>(data);
    check::<KeyValue>(data);
    check::<DiagnosticStatus>(data);
    check::<DiagnosticArray>(data);
    check::<AxisSample>(data);
    if let Some(m) = check::<RigSample>(data) {
        let _ = m.present();
    }
    if let Some(m) = check::<ExcitationState>(data) {
        let _ = m.excitation();
        let _ = m.driven();
    }
    if let Some(m) = check::<HarmonicPhasors>(data) {
        let _ = m.to_analysis(Time::ZERO);
        let _ = m.to_analysis(m.header.stamp);
        let _ = m.phasor(0, 0);
        let _ = m.phasor(m.channel_names.len().saturating_sub(1), m.harmonic_orders.len().saturating_sub(1));
    }
    if let Some(m) = check::<IdentifiedParameters>(data) {
        let _ = m.to_identification();
        let n = m.parameter_names.len();
        let _ = m.covariance_at(n.saturating_sub(1), n.saturating_sub(1));
        if let Some(name) = m.parameter_names.first() {
            let _ = m.value(name);
        }
    }
});

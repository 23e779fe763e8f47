//! With feature "ros2-client", every type is a ros2_client::Message (publishable as is).
#![cfg(feature = "ros2-client")]

fn is_message<M: ros2_client::Message>() {}

#[test]
fn all_types_are_ros2_client_messages() {
    use forcemap_msgs::builtin_interfaces::Time;
    use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
    use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
    use forcemap_msgs::std_msgs::Header;
    is_message::<Time>();
    is_message::<Header>();
    is_message::<KeyValue>();
    is_message::<DiagnosticStatus>();
    is_message::<DiagnosticArray>();
    is_message::<RigSample>();
    is_message::<ExcitationState>();
    is_message::<HarmonicPhasors>();
    is_message::<IdentifiedParameters>();
}

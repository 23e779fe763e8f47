//! The harmonic node's provisional phasors: the analysis of a step in progress (a copy of its
//! stream, finished off the intake path), published on `phasors/provisional` when it has a
//! settled part.

use forcemap_math::phasor::{PhasorStream, provisional_analysis};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::HarmonicPhasors;
use forcemap_msgs::std_msgs::Header;

use crate::log_line;
use crate::ros::now_time;

/// Analyses `stream` (the run began at `origin`) and publishes its phasors in `frame`; nothing
/// when it has no settled part yet.
pub(super) async fn publish(
    stream: Box<PhasorStream>,
    origin: Time,
    publisher: &ros2_client::Publisher<HarmonicPhasors>,
    frame: &str,
) {
    let found = tokio::task::spawn_blocking(move || provisional_analysis(&stream)).await;
    if let Ok(Some(an)) = found {
        let msg = HarmonicPhasors::from_analysis(&an, origin, Header::new(now_time(), frame));
        if let Err(e) = publisher.async_publish(msg).await {
            log_line!(
                "error: publishing provisional phasors of step {}: {e:?}",
                an.step
            );
        }
    }
}

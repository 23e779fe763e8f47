//! A node that falls behind the samples loses none of them while it is less than
//! `qos::SAMPLES_READER_DEPTH` samples behind. A DDS reader acknowledges a sample when it reaches
//! the reader's cache, not when the node takes it, so the writer goes on publishing however slow
//! the node is, and a KeepLast cache replaces its oldest samples, read or not, once it holds its
//! depth. Here a subscriber takes nothing until 30 000 samples have been published (three times
//! the writer's depth, as a recorder descheduled for 0.3 s behind a flooding sensor), then takes
//! them all: with the readers' QoS it gets all 30 000 in order; with the writer's own depth it
//! would get at most the last 10 000, which the second subscriber shows (so the test sees the
//! mechanism it guards against, not only its absence).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::collections::BTreeMap;
use std::time::Duration;

use forcemap_io::params::Params;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::RigSample;
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::ros::{NodeSetup, RosNode, qos};
use ros2_client::Subscription;

const SAMPLES: usize = 30_000;

fn setup(name: &str) -> NodeSetup {
    NodeSetup {
        name: name.to_string(),
        namespace: "/depth_test".to_string(),
        params: Params::new(),
        remaps: BTreeMap::new(),
    }
}

fn sample(i: usize) -> RigSample {
    RigSample {
        header: Header {
            stamp: Time {
                sec: (i / 1000) as i32,
                nanosec: (i % 1000) as u32 * 1_000_000,
            },
            frame_id: String::new(),
        },
        step: 0,
        present_channels: RigSample::BASE_DISPLACEMENT,
        base_displacement_m: i as f64,
        relative_displacement_m: f64::NAN,
        mass_acceleration_mps2: f64::NAN,
        mass_displacement_m: f64::NAN,
        base_acceleration_mps2: f64::NAN,
        force_n: f64::NAN,
        drive_point_displacement_m: f64::NAN,
    }
}

/// Takes until nothing arrives for a second; returns the sample numbers in arrival order.
async fn take_all(sub: &Subscription<RigSample>) -> Vec<usize> {
    let mut got = Vec::new();
    while let Ok(Ok((m, _))) = tokio::time::timeout(Duration::from_secs(1), sub.async_take()).await
    {
        got.push(m.base_displacement_m as usize);
    }
    got
}

#[test]
fn a_subscriber_behind_by_three_writer_depths_loses_no_sample() {
    // A domain of its own, so that concurrent graph tests do not cross this one.
    // SAFETY: set before any thread of this test process reads the environment.
    unsafe { std::env::set_var("ROS_DOMAIN_ID", (150 + std::process::id() % 80).to_string()) };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        // Each reader in a participant of its own: the readers of one participant share
        // one cache per topic, as deep as the deepest of them.
        let mut deep_node = RosNode::start(setup("deep")).unwrap();
        let deep = deep_node
            .subscription::<RigSample>("samples", qos::samples_reader())
            .unwrap();
        let mut shallow_node = RosNode::start(setup("shallow")).unwrap();
        let shallow = shallow_node
            .subscription::<RigSample>("samples", qos::samples())
            .unwrap();
        let mut writer_node = RosNode::start(setup("writer")).unwrap();
        let publisher = writer_node
            .publisher::<RigSample>("samples", qos::samples())
            .unwrap();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        while publisher.get_subscription_count(&writer_node.node) < 2 {
            assert!(tokio::time::Instant::now() < deadline, "no match in 30 s");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        tokio::time::sleep(Duration::from_millis(300)).await;
        // Publishing blocks while the writer's window is full; nothing is taken meanwhile.
        let publisher = tokio::task::spawn_blocking(move || {
            for i in 0..SAMPLES {
                publisher.publish(sample(i)).unwrap();
            }
            publisher
        })
        .await
        .unwrap();
        tokio::time::sleep(Duration::from_secs(2)).await;
        let got = take_all(&deep).await;
        let shallow_got = take_all(&shallow).await;
        drop(publisher);
        assert_eq!(
            got,
            (0..SAMPLES).collect::<Vec<_>>(),
            "the readers' QoS lost or reordered samples"
        );
        assert!(
            shallow_got.len() <= qos::SAMPLES_DEPTH + 64 && shallow_got.len() < SAMPLES,
            "a reader with the writer's depth kept {} of {SAMPLES} untaken samples: the cache does not evict unread samples here, so the readers' deeper history may not be needed",
            shallow_got.len()
        );
    });
}

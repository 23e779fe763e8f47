//! A node stops on SIGTERM even when the signal arrives while it is busy between two waits
//! (the launcher's SIGTERM must never be lost). Alone in its test binary: it signals its own
//! process.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::time::Duration;

#[test]
fn a_sigterm_that_came_before_the_wait_is_not_lost() {
    forcemap_nodes::ros::run_node(|| async {
        // SIGTERM this process while nothing waits for it (as when a node is busy handling a
        // message), then wait: the wait must end at once. The bound only ends a failing run.
        let status = std::process::Command::new("kill")
            .args(["-TERM", &std::process::id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        tokio::time::sleep(Duration::from_millis(300)).await;
        let waited = tokio::time::timeout(
            Duration::from_secs(20),
            forcemap_nodes::ros::shutdown_signal(),
        )
        .await;
        anyhow::ensure!(waited.is_ok(), "the SIGTERM sent before the wait was lost");
        Ok(())
    })
    .unwrap();
    // Later waits see it too (every loop of a node asks again).
    forcemap_nodes::ros::run_node(|| async {
        let waited = tokio::time::timeout(
            Duration::from_secs(20),
            forcemap_nodes::ros::shutdown_signal(),
        )
        .await;
        anyhow::ensure!(waited.is_ok(), "a later wait missed the SIGTERM");
        Ok(())
    })
    .unwrap();
}

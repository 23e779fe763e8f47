//! The graph split over two hosts: the sensor in one network namespace, the harmonic node,
//! identifier and monitor in another, joined by a veth link with a multicast route (RustDDS
//! discovers peers by multicast only; see docs/graph.md). The theta that crosses the link
//! equals `forcemap identify` on the same bag. The namespaces are created by the test, which
//! needs root (CAP_SYS_ADMIN and CAP_NET_ADMIN); elsewhere it is skipped with a message.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;

/// Two network namespaces joined by a veth pair, 10.77.<n>.1 and .2, each with a multicast
/// route over the link; removed on drop.
struct TwoHosts {
    names: [String; 2],
    veth: [String; 2],
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

impl TwoHosts {
    fn create() -> Result<TwoHosts, String> {
        let id = std::process::id() % 10_000;
        let names = [format!("fm_a{id}"), format!("fm_b{id}")];
        let veth = [format!("fmva{id}"), format!("fmvb{id}")];
        let hosts = TwoHosts {
            names: names.clone(),
            veth: veth.clone(),
        };
        let subnet = id % 250;
        for n in &names {
            ip(&["netns", "add", n])?;
        }
        ip(&[
            "link", "add", &veth[0], "type", "veth", "peer", "name", &veth[1],
        ])?;
        for (i, (ns, dev)) in names.iter().zip(&veth).enumerate() {
            ip(&["link", "set", dev, "netns", ns])?;
            let addr = format!("10.77.{subnet}.{}/24", i + 1);
            ip(&["-n", ns, "addr", "add", &addr, "dev", dev])?;
            ip(&["-n", ns, "link", "set", dev, "up"])?;
            ip(&["-n", ns, "link", "set", "lo", "up"])?;
            ip(&["-n", ns, "route", "add", "224.0.0.0/4", "dev", dev])?;
        }
        Ok(hosts)
    }
}

impl TwoHosts {
    /// Bytes host `i` has received over the link.
    fn received_bytes(&self, i: usize) -> u64 {
        let out = Command::new("ip")
            .args([
                "-n",
                &self.names[i],
                "-j",
                "-s",
                "link",
                "show",
                "dev",
                &self.veth[i],
            ])
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v[0]["stats64"]["rx"]["bytes"].as_u64().unwrap()
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        // Deleting a namespace deletes the veth end inside it, and with it the pair.
        for n in &self.names {
            let _ = ip(&["netns", "del", n]);
        }
    }
}

#[test]
fn rig_bag_played_on_one_host_is_identified_on_another() {
    let uid = Command::new("id").arg("-u").output().unwrap().stdout;
    if String::from_utf8_lossy(&uid).trim() != "0" {
        eprintln!("skipped: creating network namespaces needs root");
        return;
    }
    let hosts = match TwoHosts::create() {
        Ok(h) => h,
        Err(e) => {
            eprintln!("skipped: cannot create two network namespaces here ({e})");
            return;
        }
    };
    let [sensor_host, analysis_host] =
        [Some(hosts.names[0].as_str()), Some(hosts.names[1].as_str())];
    let d = domain(12);
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let bag = repo().join("bags/rig_40db");
    let mut monitor = NodeProcess::start_in(
        analysis_host,
        "monitor",
        d,
        &[
            format!("summary_json:={}", summary.display()),
            "quiet_s:=2.0".into(),
            "timeout_s:=120.0".into(),
        ],
    );
    let _harmonic = NodeProcess::start_in(analysis_host, "harmonic", d, &[]);
    let _identifier = NodeProcess::start_in(
        analysis_host,
        "identifier",
        d,
        &["model:=coulomb".into(), "method:=fd-multi".into()],
    );
    let mut sensor = NodeProcess::start_in(
        sensor_host,
        "sensor",
        d,
        &[
            "source:=bag".into(),
            format!("bag:={}", bag.display()),
            "rate_factor:=0.0".into(),
            "startup_timeout_s:=60.0".into(),
        ],
    );
    let status = sensor.wait_exit(Duration::from_secs(120));
    assert!(status.success(), "sensor: {}", sensor.lines().join("\n"));
    assert!(monitor.wait_exit(Duration::from_secs(60)).success());
    let live = summary_theta(&summary);
    let offline = offline_theta(&bag, &["--model", "coulomb", "--method", "fd-multi"]);
    assert_same_theta(&live, &offline, 1e-9);
    // The samples crossed the link: 15 600 samples of six channels, far more than discovery.
    let received = hosts.received_bytes(1);
    eprintln!("analysis host received {received} bytes over the link");
    assert!(
        received > 1_000_000,
        "{received} bytes received by the analysis host"
    );
}

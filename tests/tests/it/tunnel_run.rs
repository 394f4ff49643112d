//! `exo run` with `services.tunnel = true`: the tunnel is a watcher. When
//! its endpoint cannot be bound (a port in use) it stops with the endpoint
//! named and the run goes on to the end of its protocol with exit 0; on a
//! free endpoint it exports the run's samples and stops cleanly with it.
//! (Both ends of the tunnel, bit for bit: `services/tunnel/tests/`.)

use std::process::Command;

use exo_tests::*;

fn run_with_tunnel(tag: &str, port: u16) -> (bool, String) {
    let sc = Scenario::new(
        tag,
        &[
            ("experiments = [1, 7]", "experiments = [1]"),
            ("periods = [1, 4, 7]", "periods = [1]"),
        ],
    );
    sc.edit("recorder = true", "recorder = true\ntunnel = true");
    sc.append(&format!(
        "\n[tunnel]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n"
    ));
    let out = Command::new(workspace_bin("exo"))
        .args(["run", sc.config.to_str().unwrap(), "--no-report"])
        .output()
        .unwrap();
    (out.status.success(), stderr(&out))
}

#[test]
fn a_tunnel_on_a_port_in_use_stops_alone_and_the_run_goes_on() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let (ok, err) = run_with_tunnel("tunport", port);
    assert!(ok, "the run must go on: {err}");
    assert!(
        err.contains(&format!("tunnel: cannot listen on tcp/127.0.0.1:{port}")),
        "{err}"
    );
    assert!(err.contains("exo: tunnel stopped (exit code 1)"), "{err}");
    assert!(err.contains("controller: protocol done"), "{err}");
    drop(taken);
}

#[test]
fn a_tunnel_on_a_free_port_exports_the_run() {
    let (ok, err) = run_with_tunnel("tunfree", free_tcp_port());
    assert!(ok, "{err}");
    assert!(err.contains("controller: protocol done"), "{err}");
    assert!(!err.contains("tunnel stopped"), "{err}");
    let moved: u64 = err
        .lines()
        .find_map(|l| {
            l.split("tunnel: ")
                .nth(1)?
                .strip_suffix(" samples moved")?
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("no count of moved samples: {err}"));
    // One period of experiment 1 is thousands of control ticks, each a
    // sample and a command on the bus and on the control channels.
    assert!(moved > 10_000, "{moved} samples moved: {err}");
}

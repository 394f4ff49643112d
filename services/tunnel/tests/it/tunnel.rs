//! Channels to another host over Zenoh (`exo-tunnel`), both ends on this
//! machine over loopback: the exo computer's instance runs the control
//! path and exports; the "other computer" is a second instance whose
//! tunnel imports, and whose channels then carry the first one's samples
//! and commands, every one, bit for bit, in order (lockstep).

use std::time::Duration;

use exo_messages::channels::{COMMAND, SENSOR};
use exo_tests::*;

#[test]
fn another_host_receives_every_sample_over_zenoh() {
    let exo = Scenario::new("tunexo", &[("periods = [1, 4, 7]", "periods = [1]")]);
    let other = Scenario::new("tunother", &[]);
    let (mut export, mut import, endpoint) = start_tunnel(&exo, &other);
    let there_samples = other.collect(SENSOR);
    let there_commands = other.collect(COMMAND);
    let here_samples = exo.collect(SENSOR);
    let here_commands = exo.collect(COMMAND);

    exo.run_control_path();
    let here_samples = here_samples.finish();
    let here_commands = here_commands.finish();
    assert!(here_samples.len() > 5000);
    there_samples.wait_for(Duration::from_secs(120), "every sample there", |s| {
        s.len() >= here_samples.len()
    });
    there_commands.wait_for(Duration::from_secs(120), "every command there", |s| {
        s.len() >= here_commands.len()
    });
    terminate(&mut export);
    terminate(&mut import);
    let there_samples = there_samples.finish();
    let there_commands = there_commands.finish();
    assert_eq!(there_samples.len(), here_samples.len());
    assert!(there_samples == here_samples, "the samples differ");
    assert!(there_commands == here_commands, "the commands differ");
    let log = exo.log("exo-tunnel");
    assert!(log.contains(&endpoint), "{log}");
    assert!(
        !log.contains("other hosts can subscribe"),
        "loopback: {log}"
    );
}

/// An importer that stops reading (SIGSTOP: the link stalls and the export
/// waits on it) and an export killed with SIGKILL mid-run never disturb
/// control: the protocol runs to its end, every sample in order, none
/// flagged.
#[test]
fn a_stalled_importer_and_a_killed_export_never_disturb_control() {
    let exo = Scenario::new("tunkill", &[("periods = [1, 4, 7]", "periods = [1]")]);
    let other = Scenario::new("tunstalled", &[]);
    let (mut export, mut import, _) = start_tunnel(&exo, &other);
    signal(&import, SIGSTOP);

    let samples = exo.collect(SENSOR);
    let mut plant = exo.spawn("exo-plant-sim", &[]);
    let mut driver = exo.spawn("exo-sensor-driver", &[]);
    let mut controller = exo.spawn("exo-controller", &[]);
    samples.wait_for(Duration::from_secs(120), "2 s of samples", |s| {
        s.len() > 2000
    });
    kill_9(&mut export);
    let status = wait_exit(&mut controller, Duration::from_secs(600), "controller");
    assert!(
        status.success(),
        "control was disturbed: {}",
        exo.log("exo-controller")
    );
    terminate(&mut driver);
    terminate(&mut plant);
    signal(&import, SIGCONT);
    terminate(&mut import);
    let samples = samples.finish();
    assert!(samples.len() > 5000);
    assert!(samples.windows(2).all(|w| w[1].seq == w[0].seq + 1));
    assert!(
        samples.iter().all(|s| s.status == 0),
        "a sample carries a fault flag"
    );
}

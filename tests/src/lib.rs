//! Helpers for the workspace-level integration tests in `tests/tests/`: they
//! run the real exo binaries (built by `cargo test --workspace`) and watch
//! their channels through iceoryx2 like any other subscriber.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use exo_messages::channels::Topic;
use exo_messages::Message;

/// Path of a workspace binary in the same target directory as the running test.
pub fn workspace_bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("path of the running test binary");
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("test binary lives in target/<profile>/deps");
    let bin = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.exists(),
        "{} is not built: run the tests with `cargo test --workspace`",
        bin.display()
    );
    bin
}

/// Runs `exo` with `args` and returns its output.
pub fn exo(args: &[&str]) -> Output {
    Command::new(workspace_bin("exo"))
        .args(args)
        .output()
        .expect("failed to start exo")
}

/// Standard output as UTF-8 text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Standard error as UTF-8 text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The repository root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The project's Python (with `mcap` and `mcap-ros2-support`), set up by
/// `tools/python/ensure_venv.sh`.
pub fn python() -> String {
    let out = Command::new("bash")
        .arg(workspace_root().join("tools/python/ensure_venv.sh"))
        .output()
        .expect("ensure_venv.sh");
    assert!(
        out.status.success(),
        "Python with mcap and mcap-ros2-support is needed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

/// A command running `tools/python/SCRIPT` with the project's Python
/// ([`python`]); add its arguments, then run it with [`stdout_of`].
pub fn python_script(script: &str) -> Command {
    let mut c = Command::new(python());
    c.arg(workspace_root().join("tools/python").join(script));
    c
}

/// Runs `cmd`, asserts that it succeeded (naming it, with its standard
/// error), and returns its standard output.
pub fn stdout_of(cmd: &mut Command) -> Vec<u8> {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("starting {cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// The real human ankle recording beside the repository
/// (`../shared/data/ankle-stiffness-reklab`), checked to be there.
pub fn ankle_csv() -> PathBuf {
    let csv =
        workspace_root().join("../shared/data/ankle-stiffness-reklab/ankle_position_torque.csv");
    assert!(
        csv.is_file(),
        "the real recording is expected at {}",
        csv.display()
    );
    csv
}

/// Imports the real ankle recording ([`ankle_csv`]; torque sign flipped,
/// as README says) into `dir/ankle.mcap` with `exo import`, asserting it
/// succeeded; returns the recording's path.
pub fn import_ankle(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let rec = dir.join("ankle.mcap");
    let out = exo(&[
        "import",
        ankle_csv().to_str().unwrap(),
        "--flip-torque",
        "--subject",
        "ankle",
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    rec
}

/// The workspace's `configs/` directory.
pub fn configs_dir() -> PathBuf {
    workspace_root().join("configs")
}

/// A test's own directory, removed when the test passes
/// ([`exo_test_support::ScratchDir`]); here named `exo-it-{tag}-{pid}`.
pub use exo_test_support::ScratchDir;

/// `exo-it-{tag}-{pid}` under the system's temporary directory, created
/// empty (see [`ScratchDir`]).
pub fn scratch_dir(tag: &str) -> ScratchDir {
    ScratchDir::new(&format!("it-{tag}"))
}

/// A scratch directory for one test, with a run configuration derived from
/// `configs/default.toml` by textual replacements, and a unique instance so
/// parallel tests never share services.
pub struct Scenario {
    /// Directory (removed when the test passes, see [`ScratchDir`]).
    pub dir: ScratchDir,
    /// The run configuration file.
    pub config: PathBuf,
    /// Its iceoryx2 instance prefix.
    pub instance: String,
}

impl Scenario {
    /// Writes the scenario `tag` with `replacements` applied to the default run file.
    pub fn new(tag: &str, replacements: &[(&str, &str)]) -> Self {
        Self::of("default.toml", tag, replacements)
    }

    /// A replay scenario: no plant, driver or controller; the player plays
    /// a recording of three periods of a Python-written subject (K = 40,
    /// c = 0.4, 24 000 samples) at `pace_hz` samples a second.
    pub fn replay(tag: &str, pace_hz: f64) -> Self {
        let sc = Self::new(
            tag,
            &[
                ("plant_sim = true", "plant_sim = false"),
                ("sensor_driver = true", "sensor_driver = false"),
                ("controller = true", "controller = false\nplayer = true"),
            ],
        );
        let original = sc.dir.join("original.mcap");
        stdout_of(python_script("write_recording.py").arg(&original).args([
            "--k",
            "40",
            "--c",
            "0.4",
            "--periods",
            "3",
            "--subject",
            "PY",
        ]));
        sc.append(&format!(
            "\n[player]\nfile = \"{}\"\npace_hz = {pace_hz:?}\n",
            original.display()
        ));
        sc
    }

    /// Writes the scenario `tag` with `replacements` applied to the shipped
    /// run file `file` (in `configs/`): its paths made absolute, its
    /// instance unique, its recordings in the scenario's directory.
    pub fn of(file: &str, tag: &str, replacements: &[(&str, &str)]) -> Self {
        let instance = format!("t{}{}", tag.replace(['_', '-'], ""), std::process::id());
        let dir = ScratchDir::at(std::env::temp_dir().join(format!("exo-it-{instance}")));
        let cfgs = configs_dir();
        let mut text = std::fs::read_to_string(cfgs.join(file)).unwrap();
        text = text
            .replace("\"plants/", &format!("\"{}/plants/", cfgs.display()))
            .replace("\"subjects/", &format!("\"{}/subjects/", cfgs.display()))
            .replace(
                "\"experiments.toml\"",
                &format!("\"{}/experiments.toml\"", cfgs.display()),
            )
            .replace(
                "output_dir = \"out/runs\"",
                &format!("output_dir = \"{}\"", dir.display()),
            );
        text = text
            .lines()
            .map(|l| match l.starts_with("instance = ") {
                true => format!("instance = \"{instance}\""),
                false => l.to_string(),
            })
            .collect::<Vec<_>>()
            .join("\n");
        for (from, to) in replacements {
            assert!(
                text.contains(from),
                "scenario {tag}: `{from}` not in the default run file"
            );
            text = text.replacen(from, to, 1);
        }
        let config = dir.join("run.toml");
        std::fs::write(&config, text).unwrap();
        Scenario {
            dir,
            config,
            instance,
        }
    }

    /// Applies a textual replacement to the run configuration.
    pub fn edit(&self, from: &str, to: &str) {
        let text = std::fs::read_to_string(&self.config).unwrap();
        assert!(
            text.contains(from),
            "`{from}` not in {}",
            self.config.display()
        );
        std::fs::write(&self.config, text.replacen(from, to, 1)).unwrap();
    }

    /// Appends text to the run configuration.
    pub fn append(&self, text: &str) {
        let mut t = std::fs::read_to_string(&self.config).unwrap();
        t.push_str(text);
        std::fs::write(&self.config, t).unwrap();
    }

    /// Writes a file next to the run configuration.
    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// Starts one service binary with this configuration and `extra` arguments;
    /// its standard error goes to `<dir>/<name>.log`.
    pub fn spawn(&self, bin: &str, extra: &[&str]) -> Child {
        let log = std::fs::File::create(self.dir.join(format!("{bin}.log"))).unwrap();
        Command::new(workspace_bin(bin))
            .arg("--config")
            .arg(&self.config)
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .unwrap_or_else(|e| panic!("starting {bin}: {e}"))
    }

    /// The log of a service started with [`Scenario::spawn`].
    pub fn log(&self, bin: &str) -> String {
        std::fs::read_to_string(self.dir.join(format!("{bin}.log"))).unwrap_or_default()
    }

    /// The control path through the whole protocol: starts the plant, the
    /// sensor driver and the controller, waits (at most 600 s) for the
    /// controller to finish the protocol and requires it to exit cleanly,
    /// then stops the driver and the plant.
    pub fn run_control_path(&self) {
        let mut plant = self.spawn("exo-plant-sim", &[]);
        let mut driver = self.spawn("exo-sensor-driver", &[]);
        let mut controller = self.spawn("exo-controller", &[]);
        let status = wait_exit(&mut controller, Duration::from_secs(600), "controller");
        assert!(status.success(), "{}", self.log("exo-controller"));
        terminate(&mut driver);
        terminate(&mut plant);
    }

    /// A background subscriber collecting every sample of `topic`.
    pub fn collect<T: Message>(&self, topic: Topic<T>) -> Collector<T> {
        Collector::start(&self.instance, topic)
    }
}

/// Kills a child with SIGKILL and reaps it.
pub fn kill_9(child: &mut Child) {
    let _ = child.kill();
    let _ = child.wait();
}

/// Stops a child with SIGTERM and waits (up to 5 s, then SIGKILL); it is
/// reaped either way.
pub fn terminate(child: &mut Child) {
    let _ = exo_service_kit::child::stop_gracefully([child], Duration::from_secs(5));
}

/// Waits for a child to exit within `timeout`; kills it and panics otherwise.
pub fn wait_exit(child: &mut Child, timeout: Duration, what: &str) -> std::process::ExitStatus {
    let t = Instant::now();
    loop {
        if let Ok(Some(s)) = child.try_wait() {
            return s;
        }
        if t.elapsed() > timeout {
            kill_9(child);
            panic!("{what} did not finish within {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Collects every sample of one channel on a background thread
/// ([`exo_service_kit::collect::Collector`] with the tests' panicking API).
pub struct Collector<T: Copy + Send + 'static>(exo_service_kit::collect::Collector<T>);

impl<T: Message> Collector<T> {
    fn start(instance: &str, topic: Topic<T>) -> Self {
        let node = format!("collector_{}", std::process::id());
        Collector(
            exo_service_kit::collect::Collector::start(&node, instance, topic)
                .unwrap_or_else(|e| panic!("collector on {topic:?}: {e}")),
        )
    }

    /// A copy of what has arrived so far.
    pub fn snapshot(&self) -> Vec<T> {
        self.0.snapshot()
    }

    /// Waits until `pred` holds for the samples so far (or panics after `timeout`).
    pub fn wait_for(&self, timeout: Duration, what: &str, pred: impl Fn(&[T]) -> bool) {
        let t = Instant::now();
        while t.elapsed() < timeout {
            if pred(&self.0.snapshot()) {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("timed out after {timeout:?} waiting for {what}");
    }

    /// Stops collecting and returns everything.
    pub fn finish(self) -> Vec<T> {
        self.0.finish().expect("collector")
    }
}

/// Starts a tunnel from `exo` to `other` over loopback: `exo`'s run file
/// gets `[tunnel] listen` on a free port, its `exo-tunnel` exports, and
/// `other`'s imports `exo`'s instance. Returns (export, import, the
/// endpoint) once the link carries samples ([`wait_for_tunnel`]).
pub fn start_tunnel(exo: &Scenario, other: &Scenario) -> (Child, Child, String) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    exo.append(&format!("\n[tunnel]\nlisten = [\"{endpoint}\"]\n"));
    let export = exo.spawn("exo-tunnel", &[]);
    let import = other.spawn(
        "exo-tunnel",
        &[
            "--import-from",
            &endpoint,
            "--remote-instance",
            &exo.instance,
        ],
    );
    wait_for_tunnel(exo, other, Duration::from_secs(60));
    (export, import, endpoint)
}

/// Waits until a tunnel carries `from`'s channels onto `to`'s: markers
/// (identifier FRF points, which nothing reads while no identifier runs)
/// published on `from` every 50 ms until one arrives on `to`. Panics after
/// `timeout` with both tunnels' logs.
pub fn wait_for_tunnel(from: &Scenario, to: &Scenario, timeout: Duration) {
    use exo_messages::channels::IDENTIFIER_FRF;
    let markers = to.collect(IDENTIFIER_FRF);
    let ipc = exo_service_kit::ipc::Ipc::open(
        &format!("tunnel_marker_{}", std::process::id()),
        &from.instance,
        None,
    )
    .expect("marker node");
    let out = ipc.outbox(IDENTIFIER_FRF).expect("marker publisher");
    let t = Instant::now();
    let mut seq = 0;
    while markers.snapshot().is_empty() {
        assert!(
            t.elapsed() < timeout,
            "the tunnel did not connect: export {} import {}",
            from.log("exo-tunnel"),
            to.log("exo-tunnel")
        );
        seq += 1;
        out.send(exo_messages::FrfPoint {
            seq,
            ..Default::default()
        })
        .expect("marker");
        std::thread::sleep(Duration::from_millis(50));
    }
    markers.finish();
}

/// A TCP port on loopback that was free a moment ago (the OS's choice).
pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port on loopback")
        .port()
}

/// Signals a test may send with [`signal`].
pub use libc::{SIGCONT, SIGSTOP};

/// Sends `signal` (e.g. [`SIGSTOP`], [`SIGCONT`]) to a child.
pub fn signal(child: &Child, signal: i32) {
    let pid = i32::try_from(child.id()).expect("pid");
    // SAFETY: signalling our own child.
    let rc = unsafe { libc::kill(pid, signal) };
    assert_eq!(rc, 0, "kill({pid}, {signal})");
}

/// Tests of the EtherCAT backend in a user and network namespace of their
/// own (`unshare -rn`, no privileges needed): the test binary runs the test
/// again inside, where it builds the network and starts the emulated drive.
pub mod netns {
    use std::ffi::OsStr;
    use std::process::Command;

    /// In the parent: runs test `name` of this test binary again under
    /// `unshare -rn` (under `chrt -f 40` where permitted, as real time on a
    /// rig: builds sharing the CPUs then do not delay a cycle by a whole
    /// period), with `key=value` in its environment, and asserts it passed.
    /// A run whose output holds `timing_fault` (a fault of the machine's
    /// timing that the test did not provoke) is run again, `attempts` runs
    /// at most, each retry named on stderr.
    pub fn rerun_inside(name: &str, key: &str, value: &OsStr, timing_fault: &str, attempts: usize) {
        let fifo = Command::new("chrt")
            .args(["-f", "40", "true"])
            .status()
            .is_ok_and(|s| s.success());
        for attempt in 1..=attempts {
            let mut cmd = if fifo {
                let mut c = Command::new("chrt");
                c.args(["-f", "40", "unshare"]);
                c
            } else {
                Command::new("unshare")
            };
            let out = cmd
                .arg("-rn")
                .arg(std::env::current_exe().unwrap())
                .args(["--exact", name, "--nocapture", "--test-threads=1"])
                .env(key, value)
                .output()
                .expect("unshare");
            let text = format!("{}\n{}", crate::stdout(&out), crate::stderr(&out));
            if out.status.success() && text.contains("1 passed") {
                // Shown with `--nocapture`: what the run inside measured.
                eprintln!("{name} in its network namespace (attempt {attempt}):\n{text}");
                return;
            }
            assert!(
                text.contains(timing_fault) && attempt < attempts,
                "{name} in its network namespace (attempt {attempt}):\n{text}"
            );
            let fault: Vec<&str> = text
                .lines()
                .filter(|l| l.contains("exo: fault") || l.contains("latched"))
                .take(3)
                .collect();
            eprintln!(
                "{name}: attempt {attempt} met a timing fault it did not provoke; again ({})",
                fault.join(" | ")
            );
        }
    }

    /// Inside the namespace: the master's veth pair (`ecm0`) and the
    /// drive's (`ecs0`), joined by a bridge (with a direct pair, the drive
    /// emulator can die when the master's end goes down mid-frame), all up.
    pub fn bridge_master_and_drive() {
        for args in [
            "link add ecm0 type veth peer name ecm0b",
            "link add ecs0 type veth peer name ecs0b",
            "link add br0 type bridge",
            "link set ecm0b master br0",
            "link set ecs0b master br0",
            "link set lo up",
            "link set br0 up",
            "link set ecm0b up",
            "link set ecs0b up",
            "link set ecm0 up",
            "link set ecs0 up",
        ] {
            ip(args);
        }
    }

    /// Runs `ip args`, asserting it succeeded.
    pub fn ip(args: &str) {
        let ok = Command::new("ip")
            .args(args.split(' '))
            .status()
            .expect("ip");
        assert!(ok.success(), "ip {args}");
    }
}

//! A robot on two computers: two network namespaces joined by a veth pair, `armor run` in one
//! and `armor host` in the other, a system split across them (a counter on each side feeding a
//! checker on the other). Data flows both ways; a remote module killed is restarted through its
//! host; the host daemon killed takes its modules down, the supervisor says the host is lost,
//! and a daemon started again rejoins and gets its modules back; a supervisor killed has its
//! remote modules stopped by the daemon after its orphan time. `armor check` asks the host for
//! the types it lacks. `armor ctl teleop` reaches a teleop module on the other host.
//!
//! Namespaces need root (CAP_SYS_ADMIN) and `ip` (iproute2, which `scripts/test` installs):
//! where they cannot be made, each test fails saying why.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

use armor_tests::{
    PATIENCE, Proc, bin, bin_dir, control_address, field, process_alive, wait_until,
};

const SUPERVISOR_ADDR: &str = "10.77.0.1";
const HOST_ADDR: &str = "10.77.0.2";

/// Two namespaces joined by a veth pair (`10.77.0.1` in the first, `10.77.0.2` in the
/// second), deleted on drop with everything in them.
struct Namespaces {
    near: String,
    far: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let output = Command::new(armor_tests::tools::program("ip"))
        .args(args)
        .output()
        .map_err(|err| format!("cannot run `ip`: {err}"))?;
    if output.status.success() {
        Ok(())
    } else {
        Err(format!(
            "`ip {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        ))
    }
}

impl Namespaces {
    /// The pair, or why it cannot be made here.
    fn make() -> Result<Namespaces, String> {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let tag = format!(
            "{}_{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let namespaces = Namespaces {
            near: format!("armor_near_{tag}"),
            far: format!("armor_far_{tag}"),
        };
        ip(&["netns", "add", &namespaces.near])?;
        ip(&["netns", "add", &namespaces.far])?;
        ip(&[
            "link",
            "add",
            "veth_near",
            "netns",
            &namespaces.near,
            "type",
            "veth",
            "peer",
            "name",
            "veth_far",
            "netns",
            &namespaces.far,
        ])?;
        for (ns, dev, addr) in [
            (&namespaces.near, "veth_near", SUPERVISOR_ADDR),
            (&namespaces.far, "veth_far", HOST_ADDR),
        ] {
            ip(&["-n", ns, "addr", "add", &format!("{addr}/24"), "dev", dev])?;
            ip(&["-n", ns, "link", "set", dev, "up"])?;
            ip(&["-n", ns, "link", "set", "lo", "up"])?;
        }
        Ok(namespaces)
    }

    /// A command run inside a namespace (`ip netns exec` execs it: its pid is the command's),
    /// with the run's secret in its environment: a daemon beyond loopback requires one.
    fn command(ns: &str, program: &Path) -> Command {
        let mut command = Command::new(armor_tests::tools::program("ip"));
        command.args(["netns", "exec", ns]).arg(program);
        command.env("ARMOR_MODULE_PATH", bin_dir());
        command.env(armor_module_api::auth::ENV_SECRET_FILE, shared_secret());
        command
    }
}

/// The secret every command in the namespaces shares (a file of this test process, mode 600).
fn shared_secret() -> &'static Path {
    static SECRET: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    let dir = SECRET.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("secret");
        std::fs::write(&file, "the secret the two namespaces share").unwrap();
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
        dir
    });
    // A static's folder is never dropped: the file lives as long as the test process.
    Box::leak(dir.path().join("secret").into_boxed_path())
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        let _ = ip(&["netns", "del", &self.near]);
        let _ = ip(&["netns", "del", &self.far]);
    }
}

/// The namespaces; the test fails saying why when they cannot be made (a test skipped
/// quietly would pass on a machine where it proved nothing).
fn namespaces(test: &str) -> Namespaces {
    Namespaces::make().unwrap_or_else(|why| {
        panic!(
            "{test}: cannot make network namespaces here ({why}); these tests need root: run \
             `scripts/test` as root (it installs iproute2)"
        )
    })
}

const SPLIT_SYSTEM: &str = r#"<system name="split" host="10.77.0.1">
  <host name="robot1" address="10.77.0.2"/>
  <module name="near" type="counter">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="far_checker" type="checker" host="robot1"/>
  <module name="far" type="counter" host="robot1">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="near_checker" type="checker"/>
  <link from="near.count" to="far_checker.input"/>
  <link from="far.count" to="near_checker.input"/>
</system>
"#;

fn write_system(text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("split.xml");
    std::fs::write(&file, text).unwrap();
    (dir, file)
}

fn start_host(namespaces: &Namespaces, extra: &[&str]) -> Proc {
    let host = Proc::start(
        Namespaces::command(&namespaces.far, &bin("armor"))
            .args(["host", "--name", "robot1", "--listen"])
            .arg(format!("{HOST_ADDR}:7410"))
            .args(extra),
    );
    host.wait_for("with its address", PATIENCE, |line| {
        line.starts_with(armor_runtime::host::HOST_READY_PREFIX)
    });
    host
}

fn start_run(namespaces: &Namespaces, file: &Path, extra: &[&str]) -> Proc {
    Proc::start(
        Namespaces::command(&namespaces.near, &bin("armor"))
            .arg("run")
            .arg(file)
            .args(["--lease-secs", "1", "--no-run-folder"])
            .args(extra),
    )
}

fn in_order(checker: &'static str) -> impl Fn(&str) -> bool {
    move |line: &str| {
        line.starts_with(&format!("[{checker}]"))
            && line.contains("received ")
            && line.ends_with("in order")
    }
}

/// The pid the daemon logged for `module`, at or after line `skip` of its output.
fn started_on_host(host: &Proc, skip: usize, module: &str) -> i32 {
    let line = host.wait_for_from(
        skip,
        &format!("saying {module} started"),
        PATIENCE,
        |line| line.contains("module started") && field(line, "module") == Some(module),
    );
    field(&line, "pid").unwrap().parse().unwrap()
}

#[test]
fn a_system_split_over_two_hosts_runs_and_recovers() {
    let namespaces = namespaces("a_system_split_over_two_hosts_runs_and_recovers");
    let (_dir, file) = write_system(SPLIT_SYSTEM);
    let mut host = start_host(&namespaces, &["--orphan-secs", "1"]);
    let run = start_run(&namespaces, &file, &[]);
    // The clock is measured when the host joins (both namespaces share one clock).
    let joined = run.wait_for("the host's clock", PATIENCE, |line| {
        line.contains("host `robot1`") && line.contains("clock offset")
    });
    assert!(joined.contains("10.77.0.2:7410"), "{joined}");
    // Data both ways: near → far_checker (on robot1), far (on robot1) → near_checker.
    run.wait_for("far_checker's report", PATIENCE, in_order("far_checker"));
    run.wait_for("near_checker's report", PATIENCE, in_order("near_checker"));
    // `armor ctl status` says where each module runs.
    let control = control_address(&run);
    let status = Namespaces::command(&namespaces.near, &bin("armor"))
        .args(["ctl", "--addr", &control, "status"])
        .output()
        .unwrap();
    let status = String::from_utf8_lossy(&status.stdout);
    assert!(
        status.contains("far (counter): running on host `robot1`")
            && status.contains("near (counter): running,"),
        "{status}"
    );
    let far = started_on_host(&host, 0, "far");
    // Both remote modules really run in the other namespace, under the daemon.
    let under_daemon = armor_tests::children_of(host.pid());
    assert!(under_daemon.contains(&far), "{under_daemon:?} lacks {far}");

    // A remote module killed: its host reports the end, the supervisor restarts it there.
    let before_run = run.line_count();
    let before_host = host.line_count();
    armor_tests::signal(far, 9);
    run.wait_for_from(before_run, "the crash of far", PATIENCE, |line| {
        line.contains("module was killed by signal 9") && field(line, "module") == Some("far")
    });
    let again = started_on_host(&host, before_host, "far");
    assert_ne!(again, far);
    let relinked = run.line_count();
    run.wait_for_from(
        relinked,
        "near_checker after far's restart",
        PATIENCE,
        in_order("near_checker"),
    );

    // The host daemon killed: its modules go with it, the supervisor says the host is lost.
    let remote_pids: Vec<i32> = armor_tests::children_of(host.pid());
    assert!(!remote_pids.is_empty());
    let before_run = run.line_count();
    host.signal(9);
    host.wait_exit(PATIENCE);
    run.wait_for_from(before_run, "the host lost", PATIENCE, |line| {
        line.contains("host `robot1`") && line.contains("lost")
    });
    for pid in &remote_pids {
        wait_until("the daemon's modules to stop", PATIENCE, || {
            !process_alive(*pid)
        });
    }
    // The local side runs on meanwhile.
    assert!(process_alive(run.pid()));

    // A daemon started again: it rejoins and its modules come back, data flows again.
    let before_run = run.line_count();
    let host = start_host(&namespaces, &["--orphan-secs", "1"]);
    run.wait_for_from(before_run, "the host rejoining", PATIENCE, |line| {
        line.contains("host `robot1`") && line.contains("joined")
    });
    started_on_host(&host, 0, "far");
    started_on_host(&host, 0, "far_checker");
    run.wait_for_from(
        before_run,
        "far_checker after the host came back",
        PATIENCE,
        in_order("far_checker"),
    );
    run.wait_for_from(
        before_run,
        "near_checker after the host came back",
        PATIENCE,
        in_order("near_checker"),
    );

    // The supervisor killed: the daemon stops its modules after its orphan time.
    let remote_pids = armor_tests::children_of(host.pid());
    assert!(!remote_pids.is_empty());
    run.signal(9);
    host.wait_for("the daemon stopping its modules", PATIENCE, |line| {
        line.contains("stopping") && line.contains("module")
    });
    for pid in &remote_pids {
        wait_until("the orphaned modules to stop", PATIENCE, || {
            !process_alive(*pid)
        });
    }
    assert!(process_alive(host.pid()), "the daemon itself stays up");
}

#[test]
fn hosts_authenticate_with_the_runs_secret() {
    let namespaces = namespaces("hosts_authenticate_with_the_runs_secret");
    let (dir, file) = write_system(SPLIT_SYSTEM);
    let secret = dir.path().join("secret");
    std::fs::write(&secret, "a secret long enough for the run").unwrap();
    let other = dir.path().join("other");
    std::fs::write(&other, "another secret, not the run's one").unwrap();
    for path in [&secret, &other] {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    // A daemon with another secret refuses the run: its modules never start there.
    {
        let host = start_host(&namespaces, &["--secret", other.to_str().unwrap()]);
        let run = start_run(&namespaces, &file, &["--secret", secret.to_str().unwrap()]);
        run.wait_for("the host refusing", PATIENCE, |line| {
            line.contains("host `robot1` unreachable") && line.contains("secret")
        });
        assert!(
            !host
                .lines()
                .iter()
                .any(|line| line.contains("module started")),
            "{}",
            host.lines().join("\n")
        );
    }
    // The same secret: the link is up, data flows both ways.
    let host = start_host(&namespaces, &["--secret", secret.to_str().unwrap()]);
    let run = start_run(&namespaces, &file, &["--secret", secret.to_str().unwrap()]);
    run.wait_for("far_checker's report", PATIENCE, in_order("far_checker"));
    run.wait_for("near_checker's report", PATIENCE, in_order("near_checker"));
    // The daemon handed its modules their keys over a pipe: none is in an environment, which
    // the modules' siblings could read.
    let modules = armor_tests::children_of(host.pid());
    assert!(!modules.is_empty(), "the daemon's modules");
    for pid in modules {
        let environ = std::fs::read(format!("/proc/{pid}/environ")).unwrap_or_default();
        let environ = String::from_utf8_lossy(&environ);
        assert!(environ.contains("ARMOR_KEY_FD=0"), "{environ}");
        assert!(!environ.contains("ARMOR_KEY="), "{environ}");
        assert!(!environ.contains("ARMOR_SECRET_FILE"), "{environ}");
    }
}

#[test]
fn armor_check_reports_a_module_type_missing_on_a_host() {
    let namespaces = namespaces("armor_check_reports_a_module_type_missing_on_a_host");
    // The daemon's module path holds only the counter.
    let modules = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(
        bin("armor-mod-counter"),
        modules.path().join("armor-mod-counter"),
    )
    .unwrap();
    let host = Proc::start(
        Namespaces::command(&namespaces.far, &bin("armor"))
            .args(["host", "--name", "robot1", "--listen"])
            .arg(format!("{HOST_ADDR}:7410"))
            .env("ARMOR_MODULE_PATH", modules.path()),
    );
    host.wait_for("with its address", PATIENCE, |line| {
        line.starts_with(armor_runtime::host::HOST_READY_PREFIX)
    });
    let (_dir, file) = write_system(SPLIT_SYSTEM);
    let output = Namespaces::command(&namespaces.near, &bin("armor"))
        .arg("check")
        .arg(&file)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(!output.status.success(), "{stdout}");
    // The checker's type is missing there, at its module's `type` attribute.
    assert!(
        stdout.contains(&format!(
            "{}:6:30: module type `checker` is not on host `robot1`",
            file.display()
        )),
        "{stdout}"
    );
    assert!(!stdout.contains("`counter` is not on host"), "{stdout}");
    // A query does not take the host over.
    assert!(
        !host
            .lines()
            .iter()
            .any(|line| line.contains("supervisor connected")),
        "{}",
        host.lines().join("\n")
    );
}

/// A daemon on loopback whose clock is `offset_ms` off (the daemon's test hook), and the port
/// it listens on.
fn loopback_host(offset_ms: i64) -> (Proc, u16) {
    let host = Proc::start(
        Command::new(bin("armor"))
            .args(["host", "--name", "robot1", "--listen", "127.0.0.1:0"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .env(
                armor_runtime::host::ENV_CLOCK_OFFSET_MS,
                offset_ms.to_string(),
            ),
    );
    let line = host.wait_for("with its address", PATIENCE, |line| {
        line.starts_with(armor_runtime::host::HOST_READY_PREFIX)
    });
    let addr: std::net::SocketAddr = line
        .trim_start_matches(armor_runtime::host::HOST_READY_PREFIX)
        .trim()
        .parse()
        .unwrap();
    (host, addr.port())
}

/// A mission with a delay over a system with its checker on `robot1` at `port`.
fn timed_mission(dir: &Path, port: u16) -> PathBuf {
    std::fs::write(
        dir.join("system.xml"),
        format!(
            r#"<system name="timed">
  <host name="robot1" address="127.0.0.1" port="{port}"/>
  <module name="counter" type="counter"><param name="period_secs" value="0.05"/></module>
  <module name="checker" type="checker" host="robot1"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#
        ),
    )
    .unwrap();
    let mission = dir.join("mission.xml");
    std::fs::write(
        &mission,
        r#"<mission name="timed" system="system.xml">
  <place name="counting" tokens="1"><module name="counter"/><module name="checker"/></place>
  <place name="done" final="true"/>
  <transition name="enough" delay_secs="1"><input place="counting"/><output place="done"/></transition>
</mission>
"#,
    )
    .unwrap();
    mission
}

#[test]
fn a_mission_with_time_constraints_is_refused_when_a_hosts_clock_is_off() {
    let dir = tempfile::tempdir().unwrap();
    let (_host, port) = loopback_host(400);
    let mission = timed_mission(dir.path(), port);
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&mission)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let status = run.wait_exit(PATIENCE);
    assert!(!status.success(), "{}", run.lines().join("\n"));
    let lines = run.lines().join("\n");
    assert!(
        lines.contains("host `robot1`'s clock is ") && lines.contains("more than 50 ms"),
        "{lines}"
    );
    // Told to accept the skew, it runs to its end (the offset is still reported).
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&mission)
            .args(["--no-run-folder", "--max-clock-skew-ms", "0"])
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let line = run.wait_for("the offset reported", PATIENCE, |line| {
        line.contains("clock offset ") && line.contains("host `robot1`")
    });
    // 400 ms, give or take half a round trip on a busy machine.
    let offset: f64 = line
        .split("clock offset ")
        .nth(1)
        .and_then(|rest| rest.split(" ms").next())
        .and_then(|number| number.parse().ok())
        .unwrap_or_else(|| panic!("no offset in `{line}`"));
    assert!((300.0..500.0).contains(&offset), "{line}");
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "{}", run.lines().join("\n"));
    assert!(
        run.lines()
            .iter()
            .any(|line| line.starts_with("[checker]") && line.contains("received")),
        "{}",
        run.lines().join("\n")
    );
}

#[test]
fn a_synchronised_host_runs_a_timed_mission() {
    let dir = tempfile::tempdir().unwrap();
    let (_host, port) = loopback_host(0);
    let mission = timed_mission(dir.path(), port);
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&mission)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "{}", run.lines().join("\n"));
}

/// The operator drives a teleop module that runs on the other computer: it listens on its
/// host's address, the supervisor relays `armor ctl teleop` there across the veth pair, over an
/// encrypted link with the module's key (the run has a secret).
#[test]
fn armor_ctl_teleop_reaches_a_teleop_module_on_another_host() {
    let namespaces = namespaces("armor_ctl_teleop_reaches_a_teleop_module_on_another_host");
    let world = armor_tests::workspace_root().join("assets/worlds/yard.world");
    let (_dir, file) = write_system(&format!(
        r#"<system name="remote-pad" host="{SUPERVISOR_ADDR}">
  <host name="robot1" address="{HOST_ADDR}"/>
  <module name="sim" type="sim"><param name="world" value="{}"/></module>
  <module name="pad" type="teleop" host="robot1"><param name="listen" value="{HOST_ADDR}:0"/></module>
  <link from="pad.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
        world.display()
    ));
    let _host = start_host(&namespaces, &[]);
    let run = start_run(&namespaces, &file, &[]);
    let control = control_address(&run);
    let ctl = |args: &[&str]| {
        let output = Namespaces::command(&namespaces.near, &bin("armor"))
            .args(["ctl", "--addr", &control])
            .args(args)
            .output()
            .unwrap();
        (
            output.status.success(),
            String::from_utf8_lossy(&output.stdout).into_owned(),
        )
    };
    // The module's endpoint is known from its registration, a moment before the host reports
    // it running (a fresh machine's status once showed `starting` with the endpoint): wait for
    // both.
    wait_until(
        "the remote teleop running, with its endpoint",
        PATIENCE,
        || {
            let status = ctl(&["status"]).1;
            status.contains(&format!("teleop at {HOST_ADDR}:"))
                && status.contains("pad (teleop): running on host `robot1`")
        },
    );
    let (ok, reply) = ctl(&["teleop", "0.3", "0"]);
    assert!(ok, "{reply}");
    assert_eq!(reply.trim(), "teleop `pad`: driving at 0.3 0");
    let (ok, reply) = ctl(&["teleop", "stop"]);
    assert!(ok, "{reply}");
}

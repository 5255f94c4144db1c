//! `armor-team radio`: a team's radio on one machine, for tests and benchmarks. This kernel has
//! no `tc netem`, so a radio is built from what it has: a network namespace for the station and
//! one per robot, each robot joined to the station by a veth pair of its own (`10.41.N.1` at
//! the station, `10.41.N.2` at robot N) that loses packets each way (iptables `statistic`),
//! carries a limited rate (`tbf`) and is delayed each way by a relay of our own
//! ([`relay`]) in the station's namespace, which the station reaches at `127.0.0.1:7447+N`.
//! `ip -n STATION link set radio_sN down` cuts robot N's link.
//!
//! `radio up` makes it and says what it made ([`Made`]); `radio down` kills what still runs in
//! its namespaces (the relays first) and deletes them, which removes their links and rules.
//! The tests and `armor-team bench` use the same code, so that they measure the same radio.

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use serde::{Deserialize, Serialize};

/// What every namespace a radio makes is called first: `radio down` refuses other names, so
/// that a slip of the keyboard cannot kill what runs in a namespace it did not make.
pub const PREFIX: &str = "armor_radio_";

/// The port a robot's bridge listens at in its namespace.
pub const ROBOT_PORT: u16 = 7447;

/// `armor-team radio`.
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    #[command(subcommand)]
    pub command: RadioCommand,
}

#[derive(Clone, Debug, clap::Subcommand)]
pub enum RadioCommand {
    /// Make a station's namespace and one per robot, joined by lossy, slow, delayed links
    /// (root only); print what was made.
    Up(UpOptions),
    /// Kill what still runs in the radio's namespaces and delete them (root only).
    Down(DownOptions),
    /// The delay relay: forward TCP from `--listen` to `--to`, each chunk held `--delay-ms`
    /// each way (what `radio up` runs in the station's namespace).
    Relay(RelayOptions),
}

/// A radio: how many robots and what their links do.
#[derive(Clone, Debug, clap::Args)]
pub struct Spec {
    /// How many robots (namespaces `…_r1`, `…_r2`, …).
    #[arg(long, default_value_t = 1)]
    pub robots: usize,
    /// Packets lost each way on each link, in percent (none when 0).
    #[arg(long = "loss", default_value_t = 0.0)]
    pub loss_pct: f64,
    /// Delay each way on each link, in milliseconds (no relay when 0).
    #[arg(long, default_value_t = 0)]
    pub delay_ms: u64,
    /// The rate of each link each way, in kbit/s (unlimited when not given).
    #[arg(long = "rate-kbit")]
    pub rate_kbit: Option<u32>,
}

#[derive(Clone, Debug, clap::Args)]
pub struct UpOptions {
    #[command(flatten)]
    pub spec: Spec,
    /// Print what was made as one JSON object ([`Made`]) instead of lines for people.
    #[arg(long)]
    pub json: bool,
}

#[derive(Clone, Debug, clap::Args)]
pub struct DownOptions {
    /// The namespaces to remove (those `radio up` printed).
    #[arg(required = true)]
    pub names: Vec<String>,
}

#[derive(Clone, Debug, clap::Args)]
pub struct RelayOptions {
    /// Where to listen (an address of the namespace it runs in).
    #[arg(long)]
    pub listen: SocketAddr,
    /// Where each connection goes.
    #[arg(long)]
    pub to: SocketAddr,
    /// How long each chunk is held, each way.
    #[arg(long)]
    pub delay_ms: u64,
}

/// What `radio up` made.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Made {
    /// The station's namespace.
    pub station: String,
    pub robots: Vec<RobotLink>,
}

/// A robot's namespace and its link to the station.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RobotLink {
    pub namespace: String,
    /// The robot's address in its namespace.
    pub address: String,
    /// Where the robot's bridge listens (`armor-team robot --listen`).
    pub listen: String,
    /// Where a station in the station's namespace connects to reach the robot (through the
    /// delay relay when there is a delay): `armor-team station --connect`.
    pub station_endpoint: String,
    /// The link's end in the station's namespace: `ip -n STATION link set DEVICE down` cuts it.
    pub station_device: String,
}

impl Made {
    /// Every namespace made, the station's first: what `radio down` takes.
    pub fn namespaces(&self) -> Vec<String> {
        std::iter::once(self.station.clone())
            .chain(self.robots.iter().map(|robot| robot.namespace.clone()))
            .collect()
    }
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    match &options.command {
        RadioCommand::Up(up_options) => {
            let radio = Radio::up(&up_options.spec)?;
            let made = radio.detach();
            if up_options.json {
                println!("{}", serde_json::to_string(&made)?);
            } else {
                println!("station namespace {}", made.station);
                for robot in &made.robots {
                    println!(
                        "robot namespace {}: its bridge listens at {}, the station connects to {} \
                         (cut with `ip -n {} link set {} down`)",
                        robot.namespace,
                        robot.listen,
                        robot.station_endpoint,
                        made.station,
                        robot.station_device
                    );
                }
                println!(
                    "remove it all with: armor-team radio down {}",
                    made.namespaces().join(" ")
                );
            }
            Ok(())
        }
        RadioCommand::Down(down_options) => down(&down_options.names),
        RadioCommand::Relay(relay_options) => relay(relay_options),
    }
}

/// Whether this process runs as root, which making namespaces needs.
pub fn is_root() -> bool {
    rustix::process::geteuid().is_root()
}

/// Why a radio cannot be made when this process is not root.
pub const NEEDS_ROOT: &str = "the radio needs root (it makes network namespaces, veth pairs, \
                              iptables rules and tc qdiscs): run it as root";

/// A radio made by this process: removed with everything in it when dropped, unless
/// [`Radio::detach`]ed.
pub struct Radio {
    made: Made,
    relays: Vec<Child>,
    detached: bool,
}

impl Radio {
    /// Makes the radio of `spec`; removes what it made so far when a step fails.
    pub fn up(spec: &Spec) -> anyhow::Result<Radio> {
        anyhow::ensure!(is_root(), NEEDS_ROOT);
        anyhow::ensure!(
            (1..=200).contains(&spec.robots),
            "--robots must be 1 to 200 (each robot is a subnet 10.41.N.0/24)"
        );
        anyhow::ensure!(
            (0.0..100.0).contains(&spec.loss_pct),
            "--loss must be at least 0 and below 100 (percent), not {}",
            spec.loss_pct
        );
        anyhow::ensure!(
            spec.rate_kbit.is_none_or(|rate| rate > 0),
            "--rate-kbit must be above 0 (leave it out for no limit)"
        );
        let tag = format!(
            "{}{}_{}",
            PREFIX,
            std::process::id(),
            armor_module_api::auth::hex(&armor_module_api::auth::random_bytes::<2>()?)
        );
        let mut radio = Radio {
            made: Made {
                station: format!("{tag}_station"),
                robots: Vec::new(),
            },
            relays: Vec::new(),
            detached: false,
        };
        // On an error, dropping `radio` removes whatever was made.
        radio.make(spec, &tag)?;
        Ok(radio)
    }

    fn make(&mut self, spec: &Spec, tag: &str) -> anyhow::Result<()> {
        let station = self.made.station.clone();
        tool("ip", &["netns", "add", &station])?;
        tool("ip", &["-n", &station, "link", "set", "lo", "up"])?;
        for n in 1..=spec.robots {
            let namespace = format!("{tag}_r{n}");
            tool("ip", &["netns", "add", &namespace])?;
            let address = format!("10.41.{n}.2");
            let listen = SocketAddr::new(address.parse().context("a robot's address")?, ROBOT_PORT);
            self.made.robots.push(RobotLink {
                namespace: namespace.clone(),
                address: address.clone(),
                listen: format!("tcp/{listen}"),
                station_endpoint: format!("tcp/{listen}"),
                station_device: format!("radio_s{n}"),
            });
            tool("ip", &["-n", &namespace, "link", "set", "lo", "up"])?;
            let (near, far) = (format!("radio_s{n}"), format!("radio_r{n}"));
            // Both ends are made in their namespaces at once, so that no name is ever taken
            // in this one (two radios at a time use the same device names).
            tool(
                "ip",
                &[
                    "link", "add", &near, "netns", &station, "type", "veth", "peer", "name", &far,
                    "netns", &namespace,
                ],
            )?;
            for (ns, dev, addr) in [
                (&station, &near, format!("10.41.{n}.1")),
                (&namespace, &far, address.clone()),
            ] {
                tool(
                    "ip",
                    &["-n", ns, "addr", "add", &format!("{addr}/24"), "dev", dev],
                )?;
                tool("ip", &["-n", ns, "link", "set", dev, "up"])?;
                if let Some(rate) = spec.rate_kbit {
                    // A bucket of 2 kB (above one packet) and at most 400 ms of queue.
                    tool(
                        "tc",
                        &[
                            "-n",
                            ns,
                            "qdisc",
                            "add",
                            "dev",
                            dev,
                            "root",
                            "tbf",
                            "rate",
                            &format!("{rate}kbit"),
                            "burst",
                            "16kbit",
                            "latency",
                            "400ms",
                        ],
                    )?;
                }
                if spec.loss_pct > 0.0 {
                    // Each end drops what comes in: the loss each way.
                    tool(
                        "ip",
                        &[
                            "netns",
                            "exec",
                            ns,
                            "iptables",
                            "-A",
                            "INPUT",
                            "-i",
                            dev,
                            "-m",
                            "statistic",
                            "--mode",
                            "random",
                            "--probability",
                            &format!("{}", spec.loss_pct / 100.0),
                            "-j",
                            "DROP",
                        ],
                    )?;
                }
            }
            if spec.delay_ms > 0 {
                let relay_at = SocketAddr::from(([127, 0, 0, 1], ROBOT_PORT + n as u16));
                self.relays
                    .push(start_relay(&station, relay_at, listen, spec.delay_ms)?);
                if let Some(robot) = self.made.robots.last_mut() {
                    robot.station_endpoint = format!("tcp/{relay_at}");
                }
            }
        }
        Ok(())
    }

    pub fn made(&self) -> &Made {
        &self.made
    }

    /// The packets its loss rules dropped so far, in all its namespaces (iptables' counters):
    /// what shows that a figure went through the loss rather than round it.
    pub fn dropped_packets(&self) -> anyhow::Result<u64> {
        let mut dropped = 0;
        for ns in self.made.namespaces() {
            let rules = tool_output(
                "ip",
                &[
                    "netns", "exec", &ns, "iptables", "-L", "INPUT", "-v", "-n", "-x",
                ],
            )?;
            dropped += rules
                .lines()
                .filter(|line| line.contains("DROP") && line.contains("statistic"))
                .filter_map(|line| line.split_whitespace().next()?.parse::<u64>().ok())
                .sum::<u64>();
        }
        Ok(dropped)
    }

    /// Leaves the radio up after this process (`radio up`): `radio down` removes it.
    pub fn detach(mut self) -> Made {
        self.detached = true;
        self.made.clone()
    }
}

impl Drop for Radio {
    fn drop(&mut self) {
        if self.detached {
            return;
        }
        if let Err(err) = down(&self.made.namespaces()) {
            eprintln!("armor-team radio: {err:#}");
        }
        // The relays were killed with their namespace: reap them.
        for relay in &mut self.relays {
            let _ = relay.kill();
            let _ = relay.wait();
        }
    }
}

/// `ip netns exec STATION armor-team radio relay …`, in a process group of its own (a Ctrl-C
/// at the terminal of `radio up` leaves it), once it listens.
fn start_relay(
    station: &str,
    listen: SocketAddr,
    to: SocketAddr,
    delay_ms: u64,
) -> anyhow::Result<Child> {
    use std::os::unix::process::CommandExt as _;
    let exe = std::env::current_exe().context("cannot locate armor-team")?;
    let mut child = Command::new("ip")
        .args(["netns", "exec", station])
        .arg(exe)
        .args([
            "radio",
            "relay",
            "--listen",
            &listen.to_string(),
            "--to",
            &to.to_string(),
            "--delay-ms",
            &delay_ms.to_string(),
        ])
        .process_group(0)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|err| not_installed("ip", err))?;
    let Some(stdout) = child.stdout.take() else {
        bail!("the delay relay's output was not captured");
    };
    let (sender, said) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = sender.send(line);
    });
    match said.recv_timeout(Duration::from_secs(10)) {
        Ok(line) if line.starts_with("relay listening") => Ok(child),
        outcome => {
            let _ = child.kill();
            let _ = child.wait();
            bail!(
                "the delay relay in {station} did not start listening at {listen} within 10 s \
                 ({})",
                match outcome {
                    Ok(line) if line.is_empty() => "it ended".to_owned(),
                    Ok(line) => format!("it said {:?}", line.trim()),
                    Err(_) => "it said nothing".to_owned(),
                }
            );
        }
    }
}

/// Kills whatever runs in each of `names` and deletes it; goes on after a failure and reports
/// them all at the end.
pub fn down(names: &[String]) -> anyhow::Result<()> {
    anyhow::ensure!(is_root(), NEEDS_ROOT);
    let mut failed = Vec::new();
    for name in names {
        if let Err(err) = down_one(name) {
            failed.push(format!("{name}: {err:#}"));
        }
    }
    anyhow::ensure!(failed.is_empty(), "not all removed: {}", failed.join("; "));
    Ok(())
}

fn down_one(name: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        name.starts_with(PREFIX) && !name.contains('/'),
        "not a namespace of `radio up` (theirs start with `{PREFIX}`): left alone"
    );
    let pids = tool_output("ip", &["netns", "pids", name])?;
    for pid in pids.split_whitespace() {
        let pid = pid
            .parse::<i32>()
            .ok()
            .and_then(rustix::process::Pid::from_raw);
        if let Some(pid) = pid {
            // Already gone is fine: the namespace goes either way.
            let _ = rustix::process::kill_process(pid, rustix::process::Signal::KILL);
        }
    }
    tool("ip", &["netns", "del", name])
}

/// Runs `program` with `args`; an error with what it said when it fails.
fn tool(program: &str, args: &[&str]) -> anyhow::Result<()> {
    tool_output(program, args).map(drop)
}

/// Runs `program` with `args`; its standard output, or an error with what it said.
fn tool_output(program: &str, args: &[&str]) -> anyhow::Result<String> {
    let output = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .map_err(|err| not_installed(program, err))?;
    anyhow::ensure!(
        output.status.success(),
        "`{program} {}` failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&output.stderr).trim()
    );
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

fn not_installed(program: &str, err: std::io::Error) -> anyhow::Error {
    let package = if program == "iptables" {
        "iptables"
    } else {
        "iproute2"
    };
    if err.kind() == std::io::ErrorKind::NotFound {
        anyhow::anyhow!("`{program}` is not installed (Debian package `{package}`)")
    } else {
        anyhow::anyhow!("cannot run `{program}`: {err}")
    }
}

/// `armor-team radio relay`: a TCP relay that holds every chunk `delay_ms` each way, in order,
/// as a slow radio does. It says `relay listening on ADDR` once it listens, then runs until
/// it is killed.
pub fn relay(options: &RelayOptions) -> anyhow::Result<()> {
    let listener = TcpListener::bind(options.listen)
        .with_context(|| format!("cannot listen at {}", options.listen))?;
    println!("relay listening on {}", options.listen);
    std::io::stdout().flush()?;
    let delay = Duration::from_millis(options.delay_ms);
    for client in listener.incoming() {
        let client = match client {
            Ok(client) => client,
            Err(err) => {
                eprintln!("armor-team radio relay: accept: {err}");
                continue;
            }
        };
        let to = options.to;
        // On a thread, so that a robot cut off (its connection waits) holds up no other.
        std::thread::spawn(move || {
            // A robot cut off is not there: the station's zenoh tries again.
            let Ok(server) = TcpStream::connect_timeout(&to, Duration::from_secs(5)) else {
                return;
            };
            if let Err(err) = join(client, server, delay) {
                eprintln!("armor-team radio relay: {err:#}");
            }
        });
    }
    Ok(())
}

/// Pumps `client` ⇄ `server`, each way delayed by `delay`.
fn join(client: TcpStream, server: TcpStream, delay: Duration) -> anyhow::Result<()> {
    // What zenoh writes goes at once: Nagle's wait would add to the delay asked for.
    client.set_nodelay(true)?;
    server.set_nodelay(true)?;
    pump(client.try_clone()?, server.try_clone()?, delay);
    pump(server, client, delay);
    Ok(())
}

/// One direction: `from`'s chunks are read as they come, stamped, and written to `to` when
/// their time has come; the end (or an error) of either side ends both.
fn pump(mut from: TcpStream, mut to: TcpStream, delay: Duration) {
    let (chunks, delayed) = mpsc::channel::<(Instant, Vec<u8>)>();
    std::thread::spawn(move || {
        let mut buf = vec![0; 65536];
        while let Ok(n @ 1..) = from.read(&mut buf) {
            if chunks
                .send((Instant::now() + delay, buf[..n].to_vec()))
                .is_err()
            {
                break;
            }
        }
    });
    std::thread::spawn(move || {
        for (due, chunk) in delayed {
            // The link's delay itself, not a wait for something to happen.
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            if to.write_all(&chunk).is_err() {
                break;
            }
        }
        let _ = to.shutdown(Shutdown::Both);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The relay holds each chunk its delay each way, and keeps them in order.
    #[test]
    fn the_relay_delays_each_way_in_order() {
        let echo = TcpListener::bind("127.0.0.1:0").expect("listen");
        let echo_at = echo.local_addr().expect("address");
        std::thread::spawn(move || {
            if let Ok((mut stream, _)) = echo.accept() {
                let mut buf = [0; 1024];
                while let Ok(n @ 1..) = stream.read(&mut buf) {
                    if stream.write_all(&buf[..n]).is_err() {
                        break;
                    }
                }
            }
        });
        let front = TcpListener::bind("127.0.0.1:0").expect("listen");
        let front_at = front.local_addr().expect("address");
        let delay = Duration::from_millis(150);
        std::thread::spawn(move || {
            if let Ok((client, _)) = front.accept() {
                let server = TcpStream::connect(echo_at).expect("the echo");
                join(client, server, delay).expect("joined");
            }
        });
        let mut stream = TcpStream::connect(front_at).expect("the relay");
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .expect("a timeout");
        let sent = Instant::now();
        stream.write_all(b"one").expect("sent");
        stream.write_all(b"two").expect("sent");
        let mut got = Vec::new();
        let mut buf = [0; 16];
        while got.len() < 6 {
            let n = stream.read(&mut buf).expect("the echo back");
            assert!(n > 0, "the relay closed");
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"onetwo");
        let round_trip = sent.elapsed();
        assert!(
            round_trip >= 2 * delay,
            "back after {round_trip:?}, less than twice {delay:?}"
        );
    }

    /// `radio down` leaves a namespace it did not make alone.
    #[test]
    fn down_refuses_a_namespace_it_did_not_make() {
        let err = down_one("someone_elses").expect_err("refused");
        assert!(format!("{err:#}").contains(PREFIX), "{err:#}");
    }
}

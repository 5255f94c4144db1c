//! `armor`: the ArMoR command line.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use armor_model::plural;
use armor_runtime::{agent, load, mission, probe, replay, supervisor};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "armor",
    version,
    about = "ArMoR: run, check, operate and convert modular robot systems, missions and plans"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum CtlCommand {
    /// Every module's state, and the mission's marking and what each enabled transition waits
    /// for.
    Status {
        /// Print the whole status as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Start a controllable module by hand, whatever the mission wants, until released.
    Start { module: String },
    /// Stop a controllable module by hand, until released.
    Stop { module: String },
    /// Give a module started or stopped by hand back to the mission.
    Release { module: String },
    /// Hold every controllable module; fire nothing until resumed.
    Pause,
    /// Resume a paused mission.
    Resume,
    /// End the mission now (armor run exits non-zero).
    Abort,
    /// Fire an enabled transition now, whatever its condition.
    Fire { transition: String },
    /// Update the running plan: the run checks PLAN as `armor check` does (its system, world
    /// and base map found from the running plan's folder) and moves the mission to it between
    /// two firings: legs done stay done, the leg in force goes on or is replaced at once, new
    /// legs and areas take effect. A plan that does not check, or whose legs done are not its
    /// first legs by name, is refused with the reason and the run goes on unchanged
    /// (docs/plans.md, "Updates to a running mission").
    Update {
        /// The updated plan file.
        plan: PathBuf,
    },
    /// Report a no-go area (another unit reports a minefield): `area NAME X,Y X,Y X,Y…`, its
    /// corners in the map frame (metres). The run adds it to the running plan and takes that
    /// as an update; an area that leaves the leg being driven no way blocks it
    /// (docs/plans.md, "Areas reported from outside").
    #[command(allow_negative_numbers = true)]
    Area {
        name: String,
        /// The corners, `X,Y` each, in metres.
        corners: Vec<String>,
    },
    /// Apply option N of the repair the mission proposes (`status` lists them, numbered, with
    /// their costs): each is a plan update, taken as `update` takes one (docs/plans.md,
    /// "Repair").
    Repair {
        /// The option's number, from 1.
        option: u32,
    },
    /// Tell the localiser where the robot is (as rviz's "2D Pose Estimate"): `set-pose X Y
    /// HEADING_DEG` in the map frame (metres, degrees counter-clockwise from east).
    #[command(allow_negative_numbers = true)]
    SetPose {
        x_m: f64,
        y_m: f64,
        heading_deg: f64,
        /// The localiser, when the run has several.
        #[arg(long)]
        module: Option<String>,
    },
    /// Drive the robot through the run's teleop module: `teleop LINEAR ANGULAR` (m/s, rad/s,
    /// counter-clockwise) or `teleop stop`. The module holds a command for its dead-man time
    /// (half a second of run time by default), then stops the robot: give `--for SECS` to keep
    /// sending it that long.
    #[command(allow_negative_numbers = true)]
    Teleop {
        /// Linear speed in m/s, or `stop`.
        linear: String,
        /// Turning speed in rad/s (counter-clockwise); not with `stop`.
        angular: Option<f64>,
        /// Send the command ten times a second for this many seconds (real time), then stop.
        #[arg(long = "for", value_name = "SECS")]
        for_secs: Option<f64>,
        /// The teleop module to drive, when the run has several.
        #[arg(long)]
        module: Option<String>,
    },
}

#[derive(Subcommand)]
enum SecretCommand {
    /// Write a new secret for a run (mode 600): 32 random bytes, as 64 hex digits. With
    /// --passphrase, a passphrase read from standard input stretched with Argon2id (64 MiB)
    /// instead, for a secret a person must be able to type again on another computer.
    New {
        /// The secret file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Stretch a passphrase (one line on standard input) with Argon2id and a salt; the salt
        /// is printed, and is not secret: `--salt` with it makes the same secret elsewhere.
        #[arg(long)]
        passphrase: bool,
        /// With --passphrase: the salt (32 hex digits) a first `armor secret new --passphrase`
        /// printed; without it, a new random salt.
        #[arg(long, requires = "passphrase")]
        salt: Option<String>,
    },
    /// Write the key of a role at the control interface (`armor ctl --key FILE`, the studio's
    /// attach): it proves that role and reveals neither the secret nor another role's key.
    Derive {
        /// `observer` (reads the run's status) or `operator` (may also command it).
        #[arg(long)]
        role: String,
        /// The run's shared secret.
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: PathBuf,
        /// The key file to write (mode 600).
        #[arg(short, long)]
        output: PathBuf,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Run a system, a mission, a plan or a PNML net: the agent, the config server and every
    /// module, until Ctrl-C (a system) or until the mission ends (a mission, a plan, a net).
    Run {
        /// The system, mission, plan or PNML file.
        file: PathBuf,
        /// Run time passes this many times faster than real time.
        #[arg(long, default_value_t = 1.0)]
        time_scale: f64,
        /// Stop after this many (real) seconds.
        #[arg(long = "for", value_name = "SECS")]
        duration_secs: Option<f64>,
        /// Address for the agent (default: a free port on the system's host).
        #[arg(long)]
        agent: Option<SocketAddr>,
        /// Address for the run's control interface, which every run serves (default: a free
        /// port).
        #[arg(long)]
        control: Option<SocketAddr>,
        /// Write a mission's timeline (every firing, start and stop) to this JSON file.
        #[arg(long)]
        report: Option<PathBuf>,
        /// The date the run starts at, for a mission's dates (appointments, deadlines), like
        /// 2026-11-23T08:00:00Z: rehearse a plan made for another day. Default: now, or the
        /// plan's own start when that day has passed.
        #[arg(long, value_name = "DATE")]
        start_at: Option<String>,
        /// A module that answers no ping for this long (stopped, or stuck in its own code) is
        /// killed and restarted like one that crashed; 0 turns the heartbeat off.
        #[arg(long, value_name = "SECS", default_value_t = 2.0)]
        lease_secs: f64,
        /// A file (readable by its owner only) with a shared secret: every connection of the
        /// run — agent, config server, control, module to module — must prove a key derived
        /// from it (each module the key of its own name) in a Noise handshake.
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: Option<PathBuf>,
        /// With --secret: encrypt every link between modules too (for links that cross a
        /// radio); the agent's and the config server's links are always encrypted.
        #[arg(long, requires = "secret")]
        encrypt: bool,
        /// A name outside the system that may subscribe to every output (and publish nothing)
        /// when the system has access lists: a monitor such as the studio's Run view, whose
        /// node is called `studio`. Repeat for several.
        #[arg(long = "observer", value_name = "NAME")]
        observers: Vec<String>,
        /// Where the run makes its own folder, `NAME-DATE` (its log, the mission's report, the
        /// plan's table of legs, and the files modules write under relative names, such as a
        /// recording).
        #[arg(long, value_name = "DIR", env = armor_runtime::run_dir::ENV_RUNS_DIR, default_value = "runs")]
        runs_dir: PathBuf,
        /// Make no run folder: modules write relative files into the current folder.
        #[arg(long)]
        no_run_folder: bool,
        /// A mission with dates or delays is refused when a host's clock (`armor host`) is off
        /// this machine's by more than this; 0 accepts any skew (it is still reported).
        #[arg(long, value_name = "MS", default_value_t = 50)]
        max_clock_skew_ms: u64,
        /// A host daemon stops this run's modules when it has heard nothing from the run for
        /// this long.
        #[arg(long, value_name = "SECS", default_value_t = 3.0)]
        host_orphan_secs: f64,
        /// When only an operator can take the mission on (a leg held after the robot was
        /// blocked: `armor ctl fire LEG_retry` or `LEG_skip`), the run says so and, after this
        /// many seconds (real time) with no answer, ends with a failure; 0 waits as long as it
        /// takes (an attended run).
        #[arg(long, value_name = "SECS", default_value_t = DEFAULT_HOLD_TIMEOUT_SECS)]
        hold_timeout: f64,
    },
    /// Run the host daemon of one computer of the robot: `armor run` starts, stops and watches
    /// the modules placed on it (`<module … host="NAME">`) through it.
    Host {
        /// Where to listen (the address of the host's `<host>` declaration, its port 7410 by
        /// default). Default: 0.0.0.0:7410 with a secret, 127.0.0.1:7410 without; an address
        /// beyond loopback is refused without a secret.
        #[arg(long)]
        listen: Option<SocketAddr>,
        /// The host's name, for its logs (default: the machine's host name).
        #[arg(long)]
        name: Option<String>,
        /// Accept only a supervisor that proves this shared secret (the run's --secret).
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: Option<PathBuf>,
        /// Stop every module after this long without a word from the supervisor (a robot must
        /// not drive on without its controller).
        #[arg(long, value_name = "SECS", default_value_t = 3.0)]
        orphan_secs: f64,
    },
    /// Compile a plan (waypoints, legs, actions, time constraints) into a mission net.
    Compile {
        /// The plan file.
        plan: PathBuf,
        /// The mission file to write.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Plan a plan file's objectives: order and time them within their windows, priorities,
    /// precedences and the robot's endurance, and write the best plan found (docs/plans.md).
    Plan {
        /// The plan file with `<objectives>`.
        objectives: PathBuf,
        /// The plan file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// How long to search for a better plan, in seconds.
        #[arg(long, value_name = "SECS", default_value_t = 10.0)]
        time_limit: f64,
    },
    /// Operate a run: status, start and stop modules; pause, resume, abort a mission, fire a
    /// transition by hand, or update its plan.
    Ctl {
        /// The run's control interface (printed by `armor run`; default: $ARMOR_CONTROL).
        #[arg(long, env = armor_protocol::ENV_CONTROL)]
        addr: SocketAddr,
        /// The run's shared secret, when it was started with one (acts as the operator).
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: Option<PathBuf>,
        /// A role's key instead of the secret (`armor secret derive`): an observer's reads the
        /// status, an operator's may also command.
        #[arg(long, value_name = "FILE", conflicts_with = "secret")]
        key: Option<PathBuf>,
        #[command(subcommand)]
        request: CtlCommand,
    },
    /// Keys derived from a run's secret.
    Secret {
        #[command(subcommand)]
        command: SecretCommand,
    },
    /// Check a system, mission or plan file: schema, module types, links, parameters, the files
    /// it names; for a plan, every leg planned on its world; for a mission, the names it uses
    /// and its behaviour (deadlocks, dead transitions, unboundedness). Exit 1 on any problem.
    Check {
        /// The system, mission or plan file.
        file: PathBuf,
        /// The run's shared secret, to ask the system's hosts (`armor host`) which module
        /// types they lack.
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: Option<PathBuf>,
    },
    /// Ask module binaries (files, or folders of armor-mod-* files) to describe themselves.
    Probe {
        /// Files or folders (default: the module path).
        paths: Vec<PathBuf>,
        /// Print each description as XML.
        #[arg(long)]
        xml: bool,
        /// Seconds a binary may take to answer.
        #[arg(long, default_value_t = 5.0)]
        timeout_secs: f64,
        /// Run every binary, even those described in the cache (kept in $ARMOR_PROBE_CACHE,
        /// else ~/.cache/armor/probe, keyed on path, size and modification time).
        #[arg(long)]
        no_cache: bool,
    },
    /// Export a mission net or a plan to another format, or a recording's map as a ROS map.
    #[command(group(clap::ArgGroup::new("format").required(true).args(["pnml", "gpx", "qgc", "kml", "ros_map"])))]
    Export {
        /// Write a mission (or a plan's net) as ISO/IEC 15909-2 PNML (a P/T net; our extra data
        /// in toolspecific elements).
        #[arg(long)]
        pnml: bool,
        /// Write a plan's waypoints and route as GPX 1.1.
        #[arg(long)]
        gpx: bool,
        /// Write a plan as a QGroundControl plan file (.plan: mission items, no-go areas as
        /// geofences, rally points).
        #[arg(long)]
        qgc: bool,
        /// Write a plan as KML 2.2 (Google Earth, ATAK): route, waypoints, areas, lines, units.
        #[arg(long)]
        kml: bool,
        /// Write a recording's last occupancy grid (the mapper's map) as a ROS map_server map:
        /// map.yaml and map.pgm in the folder given with -o.
        #[arg(long)]
        ros_map: bool,
        /// The mission, plan or recording file.
        file: PathBuf,
        /// The file (for --ros-map, the folder) to write.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Import a PNML P/T net as a mission, or a GPX file (waypoints, routes, tracks), a KML file
    /// (placemarks: points, paths, polygons) or a QGroundControl plan file (.plan) as a plan.
    Import {
        /// The PNML, GPX, KML or QGC plan file.
        file: PathBuf,
        /// The mission or plan file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// The system file the plan or mission runs (relative to it). Default for GPX, KML
        /// and QGC: system.xml; for PNML: the net's own (a net from another tool names none).
        #[arg(long)]
        system: Option<String>,
        /// For GPX, KML and QGC: the world file the plan is drawn on (default: the system's).
        #[arg(long)]
        world: Option<String>,
        /// For GPX and QGC: the plan's start (RFC 3339, UTC: 2026-11-23T08:00:00Z); a QGC delay
        /// until a time of day becomes an appointment on that day (dropped without it).
        #[arg(long)]
        start: Option<String>,
    },
    /// Publish a recording (an MCAP file of armor-mod-recorder) again, with its timing.
    Replay {
        /// The MCAP file.
        file: PathBuf,
        /// Play this many times faster than recorded.
        #[arg(long, default_value_t = 1.0)]
        time_scale: f64,
        /// The agent (default: $ARMOR_AGENT, else 127.0.0.1:7400).
        #[arg(long)]
        agent: Option<String>,
        /// Play again from the start after the end, until killed.
        #[arg(long = "loop")]
        looping: bool,
        /// Before playing, wait at most this long for every channel to have a subscriber.
        #[arg(long = "wait", value_name = "SECS", default_value_t = 0.0)]
        wait_secs: f64,
    },
    /// Run the central agent (name server) alone.
    Agent {
        /// Where to listen.
        #[arg(long, default_value = armor_module_api::DEFAULT_AGENT)]
        listen: SocketAddr,
        /// Accept only peers that prove this shared secret (a file readable by its owner only).
        #[arg(long, value_name = "FILE", env = armor_module_api::auth::ENV_SECRET_FILE)]
        secret: Option<PathBuf>,
    },
}

/// How long `armor run` waits for an operator alone by default: long enough for a person
/// watching to answer, short enough that a run nobody watches (a rehearsal, CI) ends.
const DEFAULT_HOLD_TIMEOUT_SECS: f64 = 300.0;

/// Degrees of latitude and longitude round (0°, 0°) where a plan's waypoints are taken for a
/// map's local coordinates with no geographic origin (0.1°: about 11 km).
const NULL_ISLAND_DEG: f64 = 0.1;

fn main() -> ExitCode {
    // `armor run`, its agent and `armor host` hold the run's secret: the modules they start run
    // as the same user, and must not read it from this process's memory (`/proc/PID/mem`).
    armor_module_api::hardening::make_non_dumpable();
    hide_secret_path();
    armor_runtime::console::init_logging();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// `--secret FILE` leaves the secret's path in `/proc/PID/cmdline`, which every process of the
/// same user reads (modules included): this process starts itself again, the same PID, with the
/// path in its environment instead (`ARMOR_SECRET_FILE`, which `--secret` reads too, and which
/// nobody else may read once the process is non-dumpable). It happens before any module or
/// thread exists, so no module ever sees the path.
fn hide_secret_path() {
    use std::os::unix::process::CommandExt as _;
    let mut args = std::env::args_os();
    let Some(program) = args.next() else {
        return;
    };
    let mut kept = Vec::new();
    let mut path = None;
    while let Some(arg) = args.next() {
        if arg == "--" {
            kept.push(arg);
            kept.extend(args.by_ref());
            break;
        }
        if arg == "--secret" {
            path = args.next();
            continue;
        }
        if let Some(value) = arg.to_str().and_then(|arg| arg.strip_prefix("--secret=")) {
            path = Some(value.into());
            continue;
        }
        kept.push(arg);
    }
    let Some(path) = path else {
        return;
    };
    let err = std::process::Command::new("/proc/self/exe")
        .arg0(program)
        .args(kept)
        .env(armor_module_api::auth::ENV_SECRET_FILE, path)
        .exec();
    eprintln!("error: could not start again without the secret's path in the command line: {err}");
    std::process::exit(1);
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Run {
            file,
            time_scale,
            duration_secs,
            agent,
            control,
            report,
            start_at,
            lease_secs,
            secret,
            encrypt,
            observers,
            runs_dir,
            no_run_folder,
            max_clock_skew_ms,
            host_orphan_secs,
            hold_timeout,
        } => {
            let lease = match lease_secs {
                0.0 => None,
                secs => Some(
                    Duration::try_from_secs_f64(secs)
                        .context("--lease-secs must be a number of seconds, 0 or more")?,
                ),
            };
            let start_at_unix_secs = start_at
                .map(|text| {
                    armor_model::net::parse_rfc3339(&text)
                        .map_err(|why| anyhow::anyhow!("--start-at `{text}`: {why}"))
                })
                .transpose()?;
            if !(time_scale.is_finite() && time_scale > 0.0) {
                anyhow::bail!("--time-scale must be a positive number, not {time_scale}");
            }
            let duration = duration_secs
                .map(|secs| {
                    Duration::try_from_secs_f64(secs)
                        .context("--for must be a positive number of seconds")
                })
                .transpose()?;
            supervisor::run(supervisor::RunOptions {
                file,
                module_path: probe::module_path(),
                time_scale,
                duration,
                agent_addr: agent,
                control_addr: control,
                report,
                start_at_unix_secs,
                lease,
                secret_file: secret.filter(|file| !file.as_os_str().is_empty()),
                encrypt,
                observers,
                runs_dir: (!no_run_folder).then_some(runs_dir),
                max_clock_skew: (max_clock_skew_ms > 0)
                    .then(|| Duration::from_millis(max_clock_skew_ms)),
                host_orphan: Duration::try_from_secs_f64(host_orphan_secs)
                    .context("--host-orphan-secs must be a positive number of seconds")?,
                hold_timeout: match hold_timeout {
                    0.0 => None,
                    secs => Some(
                        Duration::try_from_secs_f64(secs)
                            .context("--hold-timeout must be a number of seconds, 0 or more")?,
                    ),
                },
            })
        }
        Command::Check { file, secret } => {
            let secret = secret
                .filter(|file| !file.as_os_str().is_empty())
                .map(|file| armor_module_api::auth::Secret::load(&file))
                .transpose()?;
            Ok(check(&file, secret.as_ref()))
        }
        Command::Host {
            listen,
            name,
            secret,
            orphan_secs,
        } => {
            let secret = secret
                .filter(|file| !file.as_os_str().is_empty())
                .map(|file| armor_module_api::auth::Secret::load(&file))
                .transpose()?;
            let orphan = Duration::try_from_secs_f64(orphan_secs)
                .context("--orphan-secs must be a positive number of seconds")?;
            let listen =
                listen.unwrap_or_else(|| armor_runtime::host::default_listen(secret.is_some()));
            armor_runtime::host::check_listen(listen, secret.is_some())
                .map_err(anyhow::Error::msg)?;
            let listener = std::net::TcpListener::bind(listen)
                .with_context(|| format!("cannot listen on {listen}"))?;
            let addr = listener.local_addr()?;
            let name = name.unwrap_or_else(|| {
                std::fs::read_to_string("/proc/sys/kernel/hostname")
                    .map(|name| name.trim().to_owned())
                    .unwrap_or_else(|_| "host".to_owned())
            });
            let module_path = probe::module_path();
            println!("{}{addr}", armor_runtime::host::HOST_READY_PREFIX);
            tracing::info!(
                "host `{name}`: modules from {}{}",
                join_paths(&module_path),
                if secret.is_some() {
                    "; supervisors must prove the shared secret"
                } else {
                    ""
                }
            );
            armor_runtime::host::serve(armor_runtime::host::HostOptions {
                listener,
                name,
                module_path,
                secret,
                orphan,
            });
            Ok(ExitCode::SUCCESS)
        }
        Command::Secret {
            command:
                SecretCommand::New {
                    output,
                    passphrase,
                    salt,
                },
        } => secret_new(&output, passphrase, salt.as_deref()),
        Command::Secret {
            command:
                SecretCommand::Derive {
                    role,
                    secret,
                    output,
                },
        } => {
            let Some(role) = armor_module_api::auth::Role::parse(role.trim()) else {
                anyhow::bail!("--role {role}: expected `observer` or `operator`");
            };
            let secret = armor_module_api::auth::Secret::load(&secret)?;
            let key = armor_module_api::auth::RoleKey {
                role,
                key: secret.role_key(role),
            };
            write_private(&output, key.to_line().as_bytes())
                .with_context(|| format!("cannot write {}", output.display()))?;
            println!("wrote the {} key to {}", role.as_str(), output.display());
            Ok(ExitCode::SUCCESS)
        }
        Command::Ctl {
            addr,
            secret,
            key,
            request,
        } => {
            let secret = match key.filter(|file| !file.as_os_str().is_empty()) {
                Some(file) => Some(armor_protocol::key_from_file(&file)?),
                None => secret
                    .filter(|file| !file.as_os_str().is_empty())
                    .map(|file| armor_module_api::auth::Secret::load(&file))
                    .transpose()?
                    .map(|secret| armor_module_api::auth::RoleKey {
                        role: armor_module_api::auth::Role::Operator,
                        key: secret.role_key(armor_module_api::auth::Role::Operator),
                    }),
            };
            let json = matches!(request, CtlCommand::Status { json: true });
            if let CtlCommand::Teleop {
                linear,
                angular,
                for_secs,
                module,
            } = request
            {
                return ctl_teleop(addr, secret.as_ref(), &linear, angular, for_secs, module);
            }
            let request = match request {
                CtlCommand::Status { .. } => armor_protocol::Request::Status,
                CtlCommand::Start { module } => armor_protocol::Request::StartModule { module },
                CtlCommand::Stop { module } => armor_protocol::Request::StopModule { module },
                CtlCommand::Release { module } => armor_protocol::Request::ReleaseModule { module },
                CtlCommand::Pause => armor_protocol::Request::Pause,
                CtlCommand::Resume => armor_protocol::Request::Resume,
                CtlCommand::Abort => armor_protocol::Request::Abort,
                CtlCommand::Fire { transition } => armor_protocol::Request::Fire { transition },
                CtlCommand::Update { plan } => {
                    let text = std::fs::read_to_string(&plan)
                        .with_context(|| format!("cannot read {}", plan.display()))?;
                    if text.len() > armor_protocol::MAX_UPDATE_BYTES {
                        anyhow::bail!(
                            "{} is {} bytes: an update sent to a run holds at most {} bytes",
                            plan.display(),
                            text.len(),
                            armor_protocol::MAX_UPDATE_BYTES
                        );
                    }
                    armor_protocol::Request::Update {
                        file: plan.display().to_string(),
                        text,
                    }
                }
                CtlCommand::Area { name, corners } => armor_protocol::Request::Area {
                    name,
                    points_m: corners
                        .iter()
                        .enumerate()
                        .map(|(index, corner)| {
                            corner_m(corner).with_context(|| {
                                format!("corner {} of the area, `{corner}`", index + 1)
                            })
                        })
                        .collect::<anyhow::Result<_>>()?,
                },
                CtlCommand::Repair { option } => armor_protocol::Request::Repair { option },
                CtlCommand::SetPose {
                    x_m,
                    y_m,
                    heading_deg,
                    module,
                } => armor_protocol::Request::SetPose {
                    x_m,
                    y_m,
                    heading_deg,
                    module,
                },
                CtlCommand::Teleop { .. } => unreachable!("answered above"),
            };
            let reply =
                armor_protocol::Client::connect_with(addr, secret.as_ref())?.call(&request)?;
            // With --json, stdout is the JSON alone (for jq and scripts).
            if json {
                eprintln!("{}", reply.message);
            } else {
                println!("{}", reply.message);
            }
            match reply.status {
                Some(status) if json => println!("{}", serde_json::to_string_pretty(&status)?),
                Some(status) => print!("{}", status_text(&status)),
                None => {}
            }
            Ok(if reply.ok {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            })
        }
        Command::Probe {
            paths,
            xml,
            timeout_secs,
            no_cache,
        } => {
            let timeout = Duration::try_from_secs_f64(timeout_secs)
                .context("--timeout-secs must be positive")?;
            Ok(probe_command(paths, xml, timeout, !no_cache))
        }
        Command::Compile { plan, output } => compile(&plan, &output),
        Command::Plan {
            objectives,
            output,
            time_limit,
        } => armor_runtime::autoplan::run(&armor_runtime::autoplan::Request {
            objectives,
            output,
            limit: Duration::try_from_secs_f64(time_limit)
                .context("--time-limit must be a number of seconds, 0 or more")?,
            module_path: probe::module_path(),
        }),
        Command::Export {
            ros_map: true,
            file,
            output,
            ..
        } => {
            let (yaml, grid) = armor_runtime::ros_export::export(&file, &output)?;
            println!(
                "{}: ROS map written ({} × {} cells at {} m, image map.pgm beside it)",
                yaml.display(),
                grid.width,
                grid.height,
                grid.resolution_m
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Export {
            pnml,
            gpx,
            qgc,
            kml: _,
            ros_map: false,
            file,
            output,
        } => {
            let text = read_text(&file)?;
            let written = if pnml {
                let net = match mission::document_kind(&file) {
                    Ok(mission::DocumentKind::Plan) => {
                        match mission::load_mission(&file, &probe::module_path()) {
                            Ok(loaded) => loaded.net,
                            Err(diagnostics) => return Ok(report(diagnostics)),
                        }
                    }
                    _ => match armor_model::net::MissionNet::parse(&text) {
                        Ok(net) => net,
                        Err(problems) => {
                            return Ok(report(load::Diagnostics { file, problems }));
                        }
                    },
                };
                armor_model::net::to_pnml(&net)
            } else {
                let plan = match armor_model::plan::Plan::parse(&text) {
                    Ok(plan) => plan,
                    Err(problems) => return Ok(report(load::Diagnostics { file, problems })),
                };
                // A plan drawn on a map with no geographic origin has its coordinates round
                // (0°, 0°), in the Gulf of Guinea: a GPS tool would show it there.
                if !plan.waypoints.is_empty()
                    && plan.waypoints.iter().all(|waypoint| {
                        waypoint.position.lat_deg.abs() < NULL_ISLAND_DEG
                            && waypoint.position.lon_deg.abs() < NULL_ISLAND_DEG
                    })
                {
                    eprintln!(
                        "{}:{}: warning: every waypoint is within {NULL_ISLAND_DEG}° of (0°, 0°): \
                         the plan's world has no geographic origin (a ROS map with no \
                         `geo_origin: [LAT, LON]`), so other tools will show it in the Gulf of \
                         Guinea; give its world a geographic origin",
                        file.display(),
                        plan.pos
                    );
                }
                if gpx {
                    armor_model::plan::gpx::export(&plan)
                } else if qgc {
                    let exported = armor_model::plan::qgc::export(&plan);
                    for what in &exported.dropped {
                        eprintln!(
                            "{}: warning: not carried by a QGC plan: {what}",
                            file.display()
                        );
                    }
                    exported.text
                } else {
                    armor_model::plan::kml::export(&plan)
                }
            };
            armor_runtime::fs::write_atomically(&output, written.as_bytes())
                .with_context(|| format!("cannot write {}", output.display()))?;
            let format = match (pnml, gpx, qgc) {
                (true, _, _) => "PNML",
                (_, true, _) => "GPX",
                (_, _, true) => "QGC plan",
                _ => "KML",
            };
            println!("{}: {format} written", output.display());
            Ok(ExitCode::SUCCESS)
        }
        Command::Import {
            file,
            output,
            system,
            world,
            start,
        } => {
            let text = read_text(&file)?;
            let root_name = armor_module_api::xml::parse(&text)
                .ok()
                .map(|root| root.name.rsplit(':').next().unwrap_or_default().to_owned());
            let is_gpx = root_name.as_deref() == Some("gpx");
            let is_kml = root_name.as_deref() == Some("kml");
            // A QGC plan is JSON: an object, or a file named `.plan` whatever it holds.
            let is_qgc = text.trim_start().starts_with('{')
                || file.extension().is_some_and(|ext| ext == "plan");
            let start_unix_secs = start
                .map(|date| armor_model::net::parse_rfc3339(&date))
                .transpose()
                .map_err(|err| anyhow::anyhow!("--start: {err}"))?;
            let (written, summary) = if is_gpx || is_kml || is_qgc {
                let name = output
                    .file_stem()
                    .map(|stem| stem.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "plan".into());
                let system = system.unwrap_or_else(|| "system.xml".to_owned());
                let imported = if is_gpx {
                    armor_model::plan::gpx::import(&text, &name, &system)
                } else if is_kml {
                    armor_model::plan::kml::import(&text, &name, &system)
                } else {
                    match armor_model::plan::qgc::import_all(&text, &name, &system, start_unix_secs)
                    {
                        Ok(imported) => {
                            print_warnings(&file, &imported.warnings);
                            Ok(imported.plan)
                        }
                        // What was skipped is often why the plan is refused: say it too.
                        Err(failed) => {
                            print_warnings(&file, &failed.warnings);
                            Err(failed.problems)
                        }
                    }
                };
                let mut plan = match imported {
                    Ok(plan) => plan,
                    Err(problems) => return Ok(report(load::Diagnostics { file, problems })),
                };
                plan.world = world.unwrap_or_default();
                plan.start_unix_secs = plan.start_unix_secs.or(start_unix_secs);
                let areas = plan
                    .graphics
                    .iter()
                    .filter(|graphic| {
                        matches!(graphic.kind, armor_model::plan::GraphicKind::Area(_))
                    })
                    .count();
                let summary = format!(
                    "plan `{}` written ({}, {}, {})",
                    plan.name,
                    plural(plan.waypoints.len(), "waypoint"),
                    plural(plan.legs.len(), "leg"),
                    plural(areas, "area")
                );
                (plan.to_xml(), summary)
            } else {
                let mut net = match armor_model::net::read_pnml(&text) {
                    Ok((net, warnings)) => {
                        for warning in warnings {
                            eprintln!(
                                "{}:{}: warning: {}",
                                file.display(),
                                warning.pos,
                                warning.message
                            );
                        }
                        net
                    }
                    Err(problems) => return Ok(report(load::Diagnostics { file, problems })),
                };
                if let Some(system) = system {
                    net.system = system;
                } else if net.system.is_empty() {
                    eprintln!(
                        "{}: warning: the net names no system file: give `--system FILE` to \
                         check or run the mission",
                        file.display()
                    );
                }
                // A net with no token anywhere can never fire: the tool that wrote it may keep
                // its initial marking elsewhere (or it was drawn unfinished).
                if net.places.iter().all(|place| place.tokens == 0) {
                    eprintln!(
                        "{}:{}: warning: the net has no initial marking (no place holds a \
                         token): nothing can ever fire",
                        file.display(),
                        net.pos
                    );
                }
                let summary = format!(
                    "mission `{}` written ({}, {})",
                    net.name,
                    plural(net.places.len(), "place"),
                    plural(net.transitions.len(), "transition")
                );
                (net.to_xml(), summary)
            };
            armor_runtime::fs::write_atomically(&output, written.as_bytes())
                .with_context(|| format!("cannot write {}", output.display()))?;
            println!("{}: {summary}", output.display());
            Ok(ExitCode::SUCCESS)
        }
        Command::Replay {
            file,
            time_scale,
            agent,
            looping,
            wait_secs,
        } => {
            let wait_for_subscribers = Duration::try_from_secs_f64(wait_secs)
                .context("--wait must be a number of seconds, 0 or more")?;
            replay::run(&replay::Options {
                file,
                time_scale,
                agent,
                looping,
                wait_for_subscribers,
            })?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Agent { listen, secret } => {
            // `armor run` hands its agent the secret over a pipe (`ARMOR_KEY_FD`), never a path.
            let secret = match armor_module_api::auth::Secret::from_fd_env()? {
                Some(secret) => Some(secret),
                None => secret
                    .filter(|file| !file.as_os_str().is_empty())
                    .map(|file| armor_module_api::auth::Secret::load(&file))
                    .transpose()?,
            };
            let listener = std::net::TcpListener::bind(listen)
                .with_context(|| format!("cannot listen on {listen}"))?;
            let addr = listener.local_addr()?;
            println!("{}{addr}", armor_runtime::AGENT_READY_PREFIX);
            let acl = agent::Acl::from_env()
                .with_context(|| format!("{} is not a valid access list", agent::ENV_ACL))?;
            agent::serve(listener, secret, acl);
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Compiles a plan, checks the net against its system and writes it as a mission file whose
/// `system` path is right from where the mission is written.
fn compile(plan: &std::path::Path, output: &std::path::Path) -> anyhow::Result<ExitCode> {
    let loaded = match mission::load_mission(plan, &probe::module_path()) {
        Ok(loaded) => loaded,
        Err(diagnostics) => return Ok(report(diagnostics)),
    };
    print_warnings(plan, loaded.warnings());
    let mut net = loaded.net;
    let output_dir = output
        .parent()
        .filter(|dir| !dir.as_os_str().is_empty())
        .unwrap_or_else(|| std::path::Path::new("."));
    net.system = armor_runtime::fs::relative_path(&loaded.system_file, output_dir)
        .to_string_lossy()
        .into_owned();
    armor_runtime::fs::write_atomically(output, net.to_xml().as_bytes())
        .with_context(|| format!("cannot write {}", output.display()))?;
    println!(
        "{}: mission `{}` written ({}, {}, {} reachable)",
        output.display(),
        net.name,
        plural(net.places.len(), "place"),
        plural(net.transitions.len(), "transition"),
        plural(loaded.states, "marking")
    );
    Ok(ExitCode::SUCCESS)
}

fn print_warnings(file: &std::path::Path, warnings: &[armor_module_api::xml::Located]) {
    for warning in warnings {
        eprintln!(
            "{}:{}: warning: {}",
            file.display(),
            warning.pos,
            warning.message
        );
    }
}

fn check(file: &std::path::Path, secret: Option<&armor_module_api::auth::Secret>) -> ExitCode {
    let module_path = probe::module_path();
    // A large plan takes a while: every leg is planned and the net's states explored.
    let spinner = armor_runtime::console::Spinner::start(format!(
        "checking {}: describing the modules, planning each leg, exploring the net",
        file.display()
    ));
    // A world (a ROS map's YAML, or our .world) is checked as one: what a plan or a simulator
    // will find in it.
    if armor_model::ros_map::is_map_yaml(file) || file.extension().is_some_and(|ext| ext == "world")
    {
        let loaded = armor_model::world_file::load(file, &mut |path| std::fs::read(path));
        drop(spinner);
        return match loaded {
            Ok(world) => {
                let bounds = world.bounds();
                let start = world.start();
                let mm = armor_model::geo::round_mm;
                println!(
                    "{}: ok (world `{}`: {} to {} m east, {} to {} m north; the simulated robot \
                     starts at ({}, {}))",
                    file.display(),
                    world.name(),
                    mm(bounds.min_x),
                    mm(bounds.max_x),
                    mm(bounds.min_y),
                    mm(bounds.max_y),
                    mm(start.x_m),
                    mm(start.y_m)
                );
                ExitCode::SUCCESS
            }
            Err(err) => {
                println!("{err}");
                eprintln!("1 problem");
                ExitCode::FAILURE
            }
        };
    }
    // A plan of objectives is checked for what `armor plan` starts from.
    if let Some(checked) = armor_runtime::autoplan::check(file, &module_path) {
        drop(spinner);
        return match checked {
            Ok(summary) => {
                println!("{}: ok ({summary})", file.display());
                ExitCode::SUCCESS
            }
            Err(diagnostics) => report(diagnostics),
        };
    }
    let summary = match mission::document_kind(file) {
        Ok(mission::DocumentKind::System) => load::load_system(file, &module_path)
            .and_then(|loaded| check_hosts(file, &loaded.system, secret).map(|()| loaded))
            .map(|loaded| {
                (
                    format!(
                        "system `{}`: {}, {}",
                        loaded.system.name,
                        plural(loaded.system.modules.len(), "module"),
                        plural(loaded.system.links.len(), "link")
                    ),
                    Vec::new(),
                )
            }),
        Ok(_) => match mission::load_mission_counted(file, &module_path) {
            Ok(mission) => Ok((
                format!(
                    "mission `{}`: {}, {}, {} reachable",
                    mission.net.name,
                    plural(mission.net.places.len(), "place"),
                    plural(mission.net.transitions.len(), "transition"),
                    plural(mission.states, "marking")
                ),
                mission.warnings().to_vec(),
            )),
            Err((diagnostics, states)) => {
                drop(spinner);
                let code = report(diagnostics);
                // A net that ends has dead markings, so it fails the check: its state space is
                // still worth comparing with the published one.
                if let Some(states) = states {
                    println!(
                        "{}: {} reachable (counted although the check failed)",
                        file.display(),
                        plural(states, "marking")
                    );
                }
                return code;
            }
        },
        Err(diagnostics) => Err(diagnostics),
    };
    drop(spinner);
    match summary {
        Ok((summary, warnings)) => {
            print_warnings(file, &warnings);
            println!("{}: ok ({summary})", file.display());
            ExitCode::SUCCESS
        }
        Err(diagnostics) => report(diagnostics),
    }
}

/// Asks every declared host that has modules placed on it which of their types it lacks: a
/// missing one is a problem at the module; a host that does not answer is only said.
fn check_hosts(
    file: &std::path::Path,
    system: &armor_model::SystemConfig,
    secret: Option<&armor_module_api::auth::Secret>,
) -> Result<(), load::Diagnostics> {
    let mut problems = Vec::new();
    for host in &system.hosts {
        let placed: Vec<&armor_model::ModuleInstance> = system
            .modules
            .iter()
            .filter(|module| {
                system
                    .placement(module)
                    .is_some_and(|at| at.name == host.name)
            })
            .collect();
        if placed.is_empty() {
            continue;
        }
        let mut types: Vec<String> = placed.iter().map(|m| m.module_type.clone()).collect();
        types.sort();
        types.dedup();
        match armor_runtime::hosts::missing_types(host, secret, types) {
            Ok(missing) => {
                for module in placed {
                    if missing.contains(&module.module_type) {
                        problems.push(armor_module_api::xml::Located::new(
                            module.type_pos,
                            format!(
                                "module type `{}` is not on host `{}` (its `armor host` finds no armor-mod-{} on its module path)",
                                module.module_type, host.name, module.module_type
                            ),
                        ));
                    }
                }
            }
            Err(err) => eprintln!(
                "{}: note: host `{}` at {} not asked for its module types: {err:#}",
                file.display(),
                host.name,
                host.daemon_addr()
            ),
        }
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(load::Diagnostics {
            file: file.to_path_buf(),
            problems,
        })
    }
}

/// Prints every problem of a file and returns the failure status.
fn report(diagnostics: load::Diagnostics) -> ExitCode {
    println!("{diagnostics}");
    eprintln!("{}", plural(diagnostics.problems.len(), "problem"));
    ExitCode::FAILURE
}

fn read_text(file: &std::path::Path) -> anyhow::Result<String> {
    std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))
}

fn probe_command(paths: Vec<PathBuf>, xml: bool, timeout: Duration, cached: bool) -> ExitCode {
    let paths = if paths.is_empty() {
        probe::module_path()
    } else {
        paths
    };
    let binaries = probe::list_modules(&paths);
    if binaries.is_empty() {
        eprintln!(
            "error: no module binaries (armor-mod-*) in {}",
            join_paths(&paths)
        );
        return ExitCode::FAILURE;
    }
    let mut failed = false;
    let spinner = armor_runtime::console::Spinner::start(format!(
        "describing {} module {} (each answers within {} s)",
        binaries.len(),
        if binaries.len() == 1 {
            "binary"
        } else {
            "binaries"
        },
        timeout.as_secs_f64()
    ));
    let results = if cached {
        probe::probe_all_cached(&binaries, timeout)
    } else {
        probe::probe_all(&binaries, timeout)
    };
    drop(spinner);
    for (binary, result) in results {
        match result {
            Ok(description) if xml => print!("{}", description.to_xml()),
            Ok(description) => print!("{}", summary(&binary, &description)),
            Err(err) => {
                failed = true;
                eprintln!("error: {}: {err}", binary.display());
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// `armor secret new`: a random secret, or a passphrase (standard input) stretched with
/// Argon2id and a salt, written as hex to `output` (mode 600).
fn secret_new(
    output: &std::path::Path,
    passphrase: bool,
    salt: Option<&str>,
) -> anyhow::Result<ExitCode> {
    use armor_module_api::auth::{
        KEY_BYTES, SALT_BYTES, hex, random_bytes, stretch_passphrase, unhex,
    };
    let secret = if passphrase {
        let salt = match salt {
            Some(text) => unhex::<SALT_BYTES>(text).with_context(|| {
                format!("--salt {text}: expected {} hex digits", SALT_BYTES * 2)
            })?,
            None => random_bytes::<SALT_BYTES>()?,
        };
        eprintln!("passphrase (one line, then Enter):");
        let mut line = String::new();
        std::io::stdin()
            .read_line(&mut line)
            .context("cannot read the passphrase from standard input")?;
        let typed = line.trim_end_matches(['\n', '\r']);
        if typed.is_empty() {
            anyhow::bail!("an empty passphrase: type one on standard input");
        }
        let stretched = stretch_passphrase(typed.as_bytes(), &salt)?;
        println!(
            "salt {} (not secret: `armor secret new --passphrase --salt {}` makes the same secret \
             from the same passphrase on another computer)",
            hex(&salt),
            hex(&salt)
        );
        stretched
    } else {
        random_bytes::<KEY_BYTES>()?
    };
    write_private(output, format!("{}\n", hex(&secret)).as_bytes())
        .with_context(|| format!("cannot write {}", output.display()))?;
    println!("wrote a new secret to {}", output.display());
    Ok(ExitCode::SUCCESS)
}

/// Writes a file only its owner may read, through a temporary file renamed over it (a key is
/// never readable by others, not even for a moment, and a failed write leaves the old file).
fn write_private(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write as _;
    use std::os::unix::fs::OpenOptionsExt as _;
    let dir = path
        .parent()
        .filter(|dir| !dir.as_os_str().is_empty())
        .unwrap_or_else(|| std::path::Path::new("."));
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(format!(".{}.tmp", std::process::id()));
    let temporary = dir.join(name);
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&temporary)?;
    file.write_all(bytes)?;
    file.sync_all()?;
    std::fs::rename(&temporary, path)
}

/// `armor ctl teleop`: one command, or the same one ten times a second for `for_secs`, then
/// `stop`, over one connection to the control interface.
/// A corner of an area as `armor ctl area` takes it: `X,Y` in metres.
fn corner_m(text: &str) -> anyhow::Result<[f64; 2]> {
    let (x, y) = text
        .split_once(',')
        .context("expected X,Y in metres, as `12.5,-3`")?;
    let number = |part: &str| {
        part.trim()
            .parse::<f64>()
            .ok()
            .filter(|value| value.is_finite())
            .with_context(|| format!("`{part}` is not a number of metres"))
    };
    Ok([number(x)?, number(y)?])
}

fn ctl_teleop(
    addr: SocketAddr,
    secret: Option<&armor_module_api::auth::RoleKey>,
    linear: &str,
    angular: Option<f64>,
    for_secs: Option<f64>,
    module: Option<String>,
) -> anyhow::Result<ExitCode> {
    let (linear, angular) = match (linear.trim(), angular) {
        ("stop", None) => (0.0, 0.0),
        ("stop", Some(_)) => anyhow::bail!("`teleop stop` takes no turning speed"),
        (_, None) => {
            anyhow::bail!("expected `teleop LINEAR ANGULAR` (m/s, rad/s) or `teleop stop`")
        }
        (text, Some(angular)) => match text.parse::<f64>() {
            Ok(linear) if linear.is_finite() && angular.is_finite() => (linear, angular),
            _ => anyhow::bail!(
                "LINEAR `{text}` is not a number: expected `teleop LINEAR ANGULAR` or `teleop stop`"
            ),
        },
    };
    let hold = for_secs
        .map(|secs| {
            Duration::try_from_secs_f64(secs)
                .map_err(|_| anyhow::anyhow!("--for {secs}: expected seconds, 0 or more"))
        })
        .transpose()?;
    let mut client = armor_protocol::Client::connect_with(addr, secret)?;
    let request = |linear, angular| armor_protocol::Request::Teleop {
        linear,
        angular,
        module: module.clone(),
    };
    let started = std::time::Instant::now();
    let mut reply = client.call(&request(linear, angular))?;
    if let Some(hold) = hold {
        const EVERY: Duration = Duration::from_millis(100);
        while reply.ok && started.elapsed() < hold {
            std::thread::sleep(EVERY.min(hold.saturating_sub(started.elapsed())));
            reply = client.call(&request(linear, angular))?;
        }
        if reply.ok && (linear, angular) != (0.0, 0.0) {
            reply = client.call(&request(0.0, 0.0))?;
        }
    }
    println!("{}", reply.message);
    Ok(if reply.ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// A run's status as `armor ctl status` prints it.
fn status_text(status: &armor_protocol::Status) -> String {
    use std::fmt::Write as _;
    let mut out = format!(
        "system `{}` at {:.1} s of run time (×{})\n",
        status.system, status.run_secs, status.time_scale
    );
    for module in &status.modules {
        let _ = write!(
            out,
            "  {} ({}): {}",
            module.name,
            module.module_type,
            module.state.as_str()
        );
        if let Some(host) = &module.host {
            let _ = write!(out, " on host `{host}`");
        }
        match (module.manual, &module.why) {
            (Some(true), _) => out.push_str(", started by hand"),
            (Some(false), _) => out.push_str(", stopped by hand"),
            (None, Some(why)) => {
                let _ = write!(out, ", {why}");
            }
            (None, None) => out.push_str(", not needed"),
        }
        if module.restarts > 0 {
            let _ = write!(out, ", {}", plural(module.restarts as usize, "restart"));
        }
        if let Some(exit) = &module.last_exit {
            let _ = write!(out, " (last {exit})");
        }
        if let Some(behaviour) = module.behaviour {
            let _ = write!(out, ", behaviour {}", behaviour.as_str());
        }
        if let Some(winner) = &module.winner {
            let _ = write!(out, ", in control: {winner}");
        }
        for (name, address) in &module.endpoints {
            let _ = write!(out, ", {name} at {address}");
        }
        out.push('\n');
    }
    if let Some(mission) = &status.mission {
        let _ = writeln!(
            out,
            "mission `{}`{}: {}, {}",
            mission.name,
            if mission.paused { " (paused)" } else { "" },
            armor_model::net::marking_text(&mission.marking),
            plural(mission.firings_total, "firing")
        );
        for enabled in &mission.enabled {
            let _ = writeln!(out, "  enabled: {enabled}");
        }
        for line in armor_runtime::summary::update_lines(&mission.updates) {
            let _ = writeln!(out, "  {line}");
        }
        for line in mission
            .repair
            .iter()
            .flat_map(armor_runtime::summary::repair_lines)
        {
            let _ = writeln!(out, "  {line}");
        }
    }
    out
}

fn join_paths(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|path| path.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn summary(binary: &std::path::Path, description: &armor_module_api::ModuleDescription) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} {} [{}]{} ({}): {}",
        description.module_type,
        description.version,
        description.category,
        if description.controllable {
            ""
        } else {
            ", not controllable"
        },
        binary.display(),
        description.doc
    );
    for (kind, ports) in [
        ("input", &description.inputs),
        ("output", &description.outputs),
    ] {
        for port in ports {
            let _ = writeln!(
                out,
                "  {kind} {}: {} — {}",
                port.name, port.data_type, port.doc
            );
        }
    }
    for param in &description.params {
        let unit = if param.unit.is_empty() {
            String::new()
        } else {
            format!(" [{}]", param.unit)
        };
        let value = param.default.as_ref().map_or_else(
            || " (required)".to_owned(),
            |default| format!(" = {default}"),
        );
        let allowed = if param.is_limited() {
            format!(" ({})", param.range_text())
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "  param {}: {}{unit}{value}{allowed} — {}",
            param.name, param.param_type, param.doc
        );
    }
    for event in &description.events {
        let _ = writeln!(out, "  event {} — {}", event.name, event.doc);
    }
    out
}

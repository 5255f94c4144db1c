//! An operator's station: it opens a session with each robot it is given (proving its role),
//! beats so that the robots know their operator is there, prints a line per robot each second
//! (its state, leg, the age of its last report, what it costs), and sends commands read from
//! its standard input, one a line: `ROBOT|all COMMAND [ARGS]`.

use std::collections::BTreeMap;
use std::io::BufRead as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::auth::RoleKey;
use armor_protocol::Request;
use zenoh::Wait as _;

use crate::net::z;
use crate::seal::{Channel, Hello};
use crate::wire::{self, CommandReply, Down, RobotStatus, SID_BYTES, Up};

/// `armor-team station`: an operator's computer.
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// A role's key (`armor secret derive --role observer|operator`) or the secret itself (the
    /// operator).
    #[arg(long)]
    pub key: PathBuf,
    /// A robot of the team; repeat.
    #[arg(long = "robot", required = true)]
    pub robots: Vec<String>,
    /// zenoh endpoints to listen at; repeat.
    #[arg(long)]
    pub listen: Vec<String>,
    /// zenoh endpoints of the robots (or routers) to connect to; repeat.
    #[arg(long)]
    pub connect: Vec<String>,
    /// Beats a second to each robot.
    #[arg(long, default_value_t = 2.0)]
    pub beat_hz: f64,
    /// Seconds between two printed lines of a robot.
    #[arg(long, default_value_t = 1.0)]
    pub print_every_secs: f64,
    /// Send this command (`ROBOT|all COMMAND [ARGS]`) and end, rather than watch and read
    /// commands on standard input; repeat.
    #[arg(long)]
    pub send: Vec<String>,
}

/// How long a station waits for a robot's answer to a hello or a command.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(5);
/// A session whose robot sent nothing for this long is opened again (the robot's bridge may
/// have started again and forgotten it).
const SILENT_RESTART: Duration = Duration::from_secs(30);

/// What the station knows of one robot.
#[derive(Default)]
struct View {
    session: Option<(String, Channel)>,
    opened: Option<Instant>,
    status: Option<RobotStatus>,
    pose: Option<(f64, f64, f64)>,
    outputs: BTreeMap<String, usize>,
    heard: Option<Instant>,
    /// Sealed bytes received, and since when, for the line's kbit/s.
    bytes: u64,
    since: Option<Instant>,
    refusal: Option<String>,
}

type Views = Arc<Mutex<BTreeMap<String, View>>>;

fn lock(views: &Views) -> MutexGuard<'_, BTreeMap<String, View>> {
    views.lock().unwrap_or_else(PoisonError::into_inner)
}

pub fn run(options: &Options, stop: &AtomicBool) -> anyhow::Result<()> {
    for robot in &options.robots {
        anyhow::ensure!(
            wire::is_robot_name(robot),
            "`{robot}` cannot name a robot: use 1 to 64 letters, digits, `_` or `-`"
        );
    }
    anyhow::ensure!(
        !options.robots.is_empty(),
        "name the robots: --robot NAME, once each"
    );
    let key = armor_protocol::key_from_file(&options.key)
        .with_context(|| format!("the station's key {}", options.key.display()))?;
    let session = crate::net::open(&options.listen, &options.connect)?;
    let views: Views = Arc::new(Mutex::new(
        options
            .robots
            .iter()
            .map(|robot| (robot.clone(), View::default()))
            .collect(),
    ));
    println!(
        "station: {} role, robots {}",
        key.role.as_str(),
        options.robots.join(", ")
    );

    for robot in options.robots.clone() {
        let views = Arc::clone(&views);
        let session = session.clone();
        let key = key.clone();
        let beat_every = Duration::from_secs_f64(1.0 / options.beat_hz);
        std::thread::spawn(move || keep_session(&session, &robot, &key, &views, beat_every));
    }

    if !options.send.is_empty() {
        return send_all(&session, &options.robots, &views, &options.send);
    }
    {
        let views = Arc::clone(&views);
        let session = session.clone();
        let robots = options.robots.clone();
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                let line = line.trim();
                if line.is_empty() {
                    continue;
                }
                match parse_command(line, &robots) {
                    Ok((targets, request)) => {
                        for robot in targets {
                            let answer = command(&session, &robot, &views, &request);
                            match answer {
                                Ok(reply) if reply.ok => {
                                    println!("{robot}: done: {}", reply.message)
                                }
                                Ok(reply) => println!("{robot}: refused: {}", reply.message),
                                Err(err) => println!("{robot}: no answer: {err:#}"),
                            }
                        }
                    }
                    Err(err) => println!("station: {err:#}"),
                }
            }
        });
    }

    let print_every = Duration::from_secs_f64(options.print_every_secs);
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        for (robot, view) in lock(&views).iter() {
            println!("{}", line(robot, view, now));
        }
        std::thread::sleep(print_every);
    }
    Ok(())
}

/// Sends each of `lines` once the robots it names have a session (or could not get one in
/// [`ANSWER_TIMEOUT`] and more), printing each answer; fails if one was not done.
fn send_all(
    session: &zenoh::Session,
    robots: &[String],
    views: &Views,
    lines: &[String],
) -> anyhow::Result<()> {
    let mut failed = 0;
    for line in lines {
        let (targets, request) = parse_command(line, robots)?;
        let deadline = Instant::now() + ANSWER_TIMEOUT * 2;
        while Instant::now() < deadline
            && lock(views)
                .iter()
                .any(|(robot, view)| targets.contains(robot) && view.session.is_none())
        {
            std::thread::sleep(Duration::from_millis(50));
        }
        for robot in targets {
            match command(session, &robot, views, &request) {
                Ok(reply) if reply.ok => println!("{robot}: done: {}", reply.message),
                Ok(reply) => {
                    failed += 1;
                    println!("{robot}: refused: {}", reply.message);
                }
                Err(err) => {
                    failed += 1;
                    println!("{robot}: no answer: {err:#}");
                }
            }
        }
    }
    anyhow::ensure!(failed == 0, "{failed} command(s) not done");
    Ok(())
}

/// One robot's line: its state, leg, localisation, the age of its last report (a report older
/// than 2 s is shown as the last known state), what it costs.
fn line(robot: &str, view: &View, now: Instant) -> String {
    let Some(heard) = view.heard else {
        return match (&view.session, &view.refusal) {
            (Some(_), _) => format!("robot {robot} | session open, no report yet"),
            (None, Some(why)) => format!("robot {robot} | no session: {why}"),
            (None, None) => format!("robot {robot} | no session yet"),
        };
    };
    let age = now.duration_since(heard).as_secs_f64();
    let kbit = view.since.map_or(0.0, |since| {
        view.bytes as f64 * 8.0 / 1000.0 / now.duration_since(since).as_secs_f64().max(1.0)
    });
    let mut text = format!("robot {robot} |");
    if age > 2.0 {
        text.push_str(" last known:");
    }
    if let Some(status) = &view.status {
        text.push_str(&format!(
            " state {} | leg {} | localisation {} | firings {}",
            status.state,
            status.leg.as_deref().unwrap_or("-"),
            status.localisation.as_deref().unwrap_or("-"),
            status.firings_total,
        ));
        if let Some(firing) = &status.last_firing {
            text.push_str(&format!(" | last fired {firing}"));
        }
        if status.link_lost {
            text.push_str(" | link lost (robot's view)");
        }
    }
    if let Some((x_m, y_m, _)) = view.pose {
        text.push_str(&format!(" | at ({x_m:.1}, {y_m:.1})"));
    }
    text.push_str(&format!(" | report {age:.1} s ago | {kbit:.1} kbit/s"));
    text
}

/// Takes a sample the robot sealed for this station's session `sid`.
fn take(views: &Views, robot: &str, sid: &str, bytes: &[u8]) {
    let mut views = lock(views);
    let Some(view) = views.get_mut(robot) else {
        return;
    };
    let Some((own, channel)) = &mut view.session else {
        return;
    };
    if own != sid {
        return;
    }
    let Ok(plain) = channel.open(bytes) else {
        return;
    };
    let now = Instant::now();
    view.heard = Some(now);
    view.bytes += bytes.len() as u64;
    view.since.get_or_insert(now);
    match serde_json::from_slice::<Up>(&plain) {
        Ok(Up::Status(status)) => view.status = Some(status),
        Ok(Up::Pose {
            x_m,
            y_m,
            heading_rad,
        }) => view.pose = Some((x_m, y_m, heading_rad)),
        Ok(Up::Output { name, base64, .. }) => {
            view.outputs.insert(name, base64.len() * 3 / 4);
        }
        Err(_) => {}
    }
}

/// Opens a session with `robot` (again when it fell silent) and beats on it, for ever. The
/// station subscribes to its own session's samples only: on a shared radio, another
/// station's never come its way.
fn keep_session(
    session: &zenoh::Session,
    robot: &str,
    key: &RoleKey,
    views: &Views,
    beat_every: Duration,
) {
    let mut subscriber = None;
    loop {
        let now = Instant::now();
        let stale = {
            let views = lock(views);
            views.get(robot).is_some_and(|view| {
                view.session.is_none()
                    || view
                        .heard
                        .or(view.opened)
                        .is_some_and(|last| now.duration_since(last) > SILENT_RESTART)
            })
        };
        if stale {
            match hello(session, robot, key) {
                Ok((sid, channel)) => {
                    let sink = Arc::clone(views);
                    let (name, own) = (robot.to_owned(), sid.clone());
                    let declared = session
                        .declare_subscriber(wire::up_key(robot, &sid))
                        .callback(move |sample| {
                            take(&sink, &name, &own, &sample.payload().to_bytes());
                        })
                        .wait();
                    match declared {
                        Ok(declared) => {
                            // The previous session's subscriber goes with it.
                            if let Some(old) = subscriber.replace(declared) {
                                let _ = old.undeclare().wait();
                            }
                            let mut views = lock(views);
                            if let Some(view) = views.get_mut(robot) {
                                view.session = Some((sid, channel));
                                view.opened = Some(Instant::now());
                                view.refusal = None;
                            }
                        }
                        Err(err) => tracing::warn!("cannot subscribe to {robot}: {err}"),
                    }
                }
                Err(err) => {
                    if let Some(view) = lock(views).get_mut(robot) {
                        view.refusal = Some(format!("{err:#}"));
                    }
                }
            }
        }
        let beat = {
            let mut views = lock(views);
            views.get_mut(robot).and_then(|view| {
                let (sid, channel) = view.session.as_mut()?;
                let plain = serde_json::to_vec(&Down::Beat).ok()?;
                Some((wire::beat_key(robot, sid), channel.seal(&plain).ok()?))
            })
        };
        if let Some((key_expr, sealed)) = beat {
            let _ = session
                .put(key_expr, sealed)
                .congestion_control(zenoh::qos::CongestionControl::Drop)
                .wait();
        }
        std::thread::sleep(beat_every);
    }
}

/// One handshake with `robot`: its session's number and channel.
fn hello(
    session: &zenoh::Session,
    robot: &str,
    key: &RoleKey,
) -> anyhow::Result<(String, Channel)> {
    let (hello, body) = Hello::start(robot, key.role, &key.key)?;
    let replies = z(session
        .get(wire::hello_key(robot))
        .payload(body)
        .timeout(ANSWER_TIMEOUT)
        .wait())?;
    let Ok(reply) = replies.recv() else {
        anyhow::bail!("the robot does not answer (unreachable, or it holds another secret)");
    };
    let sample = reply
        .result()
        .map_err(|err| anyhow::anyhow!("the robot refused: {:?}", err.payload().to_bytes()))?;
    let answer = sample.payload().to_bytes();
    anyhow::ensure!(answer.len() > SID_BYTES, "the robot's answer is too short");
    let (sid, answer) = answer.split_at(SID_BYTES);
    let channel = hello.finish(answer)?;
    Ok((armor_module_api::auth::hex(sid), channel))
}

/// Sends `request` to `robot` over its session; the robot's sealed answer.
fn command(
    session: &zenoh::Session,
    robot: &str,
    views: &Views,
    request: &Request,
) -> anyhow::Result<CommandReply> {
    let (sid, sealed) = {
        let mut views = lock(views);
        let Some((sid, channel)) = views.get_mut(robot).and_then(|view| view.session.as_mut())
        else {
            anyhow::bail!("no session with the robot yet");
        };
        let plain = serde_json::to_vec(&Down::Command {
            request: request.clone(),
        })?;
        (sid.clone(), channel.seal(&plain)?)
    };
    let mut body = armor_module_api::auth::unhex::<SID_BYTES>(&sid)
        .context("a session number")?
        .to_vec();
    body.extend_from_slice(&sealed);
    let replies = z(session
        .get(wire::cmd_key(robot))
        .payload(body)
        .timeout(ANSWER_TIMEOUT)
        .wait())?;
    let Ok(reply) = replies.recv() else {
        anyhow::bail!("the robot did not answer in {} s", ANSWER_TIMEOUT.as_secs());
    };
    let sample = reply
        .result()
        .map_err(|_| anyhow::anyhow!("the robot answered with an error"))?;
    let bytes = sample.payload().to_bytes();
    let plain = {
        let mut views = lock(views);
        let Some((_, channel)) = views.get_mut(robot).and_then(|view| view.session.as_mut()) else {
            anyhow::bail!("the session closed");
        };
        channel.open(&bytes)?
    };
    Ok(serde_json::from_slice(&plain)?)
}

/// `ROBOT|all COMMAND [ARGS]`: the robots it is for, and the request.
fn parse_command(line: &str, robots: &[String]) -> anyhow::Result<(Vec<String>, Request)> {
    let mut words = line.split_whitespace();
    let target = words.next().unwrap_or_default();
    let targets = if target == "all" {
        robots.to_vec()
    } else if robots.iter().any(|robot| robot == target) {
        vec![target.to_owned()]
    } else {
        anyhow::bail!(
            "`{target}` is not a robot of this station ({}), nor `all`",
            robots.join(", ")
        );
    };
    let command = words.next().unwrap_or_default();
    let rest: Vec<&str> = words.collect();
    let request = match (command, rest.as_slice()) {
        ("status", []) => Request::Status,
        ("pause", []) => Request::Pause,
        ("resume", []) => Request::Resume,
        ("abort", []) => Request::Abort,
        ("fire", [transition]) => Request::Fire {
            transition: (*transition).to_owned(),
        },
        ("update", [file]) => Request::Update {
            file: (*file).to_owned(),
            text: read_plan(Path::new(file))?,
        },
        _ => anyhow::bail!(
            "commands: status, pause, resume, abort, fire TRANSITION, update PLAN.xml (not `{}`)",
            line
        ),
    };
    Ok((targets, request))
}

fn read_plan(path: &Path) -> anyhow::Result<String> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    anyhow::ensure!(
        text.len() <= armor_protocol::MAX_UPDATE_BYTES,
        "{}: {} bytes, more than the {} an update may hold",
        path.display(),
        text.len(),
        armor_protocol::MAX_UPDATE_BYTES
    );
    Ok(text)
}

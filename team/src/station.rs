//! An operator's station: it opens a session with each robot it is given (proving its role),
//! beats so that the robots know their operator is there, prints a line per robot each second
//! (its state, leg, the age of its last report, what it costs), and sends commands read from
//! its standard input, one a line: `ROBOT|all COMMAND [ARGS]`.

use std::collections::{BTreeMap, VecDeque};
use std::io::BufRead as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::auth::RoleKey;
use armor_protocol::Request;
use armor_protocol::team::{CameraSeen, LINK_WINDOW_SECS, LinkQuality, RobotReport, StationEvent};
use zenoh::Wait as _;

use crate::net::z;
use crate::seal::{Channel, Hello};
use crate::wire::{self, CommandReply, Down, RobotStatus, RoutePoint, SID_BYTES, Up};

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
    /// Print JSON lines (`armor_protocol::team::StationEvent`) rather than text: what the
    /// studio's station view reads.
    #[arg(long)]
    pub json: bool,
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
    route: Vec<RoutePoint>,
    /// Sealed bytes received (but the camera's), and since when, for the line's kbit/s.
    bytes: u64,
    since: Option<Instant>,
    refusal: Option<String>,
    /// The session's counts of samples opened and sent, taken every second or so over the last
    /// [`LINK_WINDOW_SECS`], for the link's quality.
    counts: VecDeque<(Instant, u64, u64)>,
    /// The camera's name and its frames of the last [`LINK_WINDOW_SECS`].
    camera: Option<(String, VecDeque<Frame>)>,
}

/// A camera frame received: when, its sealed size, and its size on the robot's wire.
type Frame = (Instant, usize, usize);

type Views = Arc<Mutex<BTreeMap<String, View>>>;

/// Called with each status a station opens (the benchmark's latency probe).
pub type OnStatus = Arc<dyn Fn(&str, &RobotStatus) + Send + Sync>;

/// A station's sessions with its robots, kept open and beating in threads of their own.
pub struct Station {
    session: zenoh::Session,
    views: Views,
    robots: Vec<String>,
}

impl Station {
    /// Opens a session with each of `robots` over `session` (again when one falls silent),
    /// beating `beat_hz` times a second on each.
    pub fn start(
        session: &zenoh::Session,
        key: &RoleKey,
        robots: &[String],
        beat_hz: f64,
        on_status: Option<OnStatus>,
    ) -> Station {
        let views: Views = Arc::new(Mutex::new(
            robots
                .iter()
                .map(|robot| (robot.clone(), View::default()))
                .collect(),
        ));
        for robot in robots {
            let robot = robot.clone();
            let views = Arc::clone(&views);
            let session = session.clone();
            let key = key.clone();
            let on_status = on_status.clone();
            let beat_every = Duration::from_secs_f64(1.0 / beat_hz);
            std::thread::spawn(move || {
                keep_session(
                    &session,
                    &robot,
                    &key,
                    &views,
                    beat_every,
                    on_status.as_ref(),
                )
            });
        }
        Station {
            session: session.clone(),
            views,
            robots: robots.to_vec(),
        }
    }

    /// What the station knows of each robot now.
    pub fn reports(&self) -> Vec<RobotReport> {
        let now = Instant::now();
        lock(&self.views)
            .iter_mut()
            .map(|(robot, view)| report(robot, view, now))
            .collect()
    }

    /// Sends `request` to `robot`; its answer.
    pub fn command(&self, robot: &str, request: &Request) -> anyhow::Result<CommandReply> {
        command(&self.session, robot, &self.views, request)
    }
}

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
    let station = Arc::new(Station::start(
        &session,
        &key,
        &options.robots,
        options.beat_hz,
        None,
    ));
    let out = Out { json: options.json };
    if options.json {
        out.event(&StationEvent::Station {
            role: key.role.as_str().to_owned(),
            robots: options.robots.clone(),
        });
    } else {
        println!(
            "station: {} role, robots {}",
            key.role.as_str(),
            options.robots.join(", ")
        );
    }

    if !options.send.is_empty() {
        return send_all(&station, &options.send, out);
    }
    {
        let station = Arc::clone(&station);
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                let line = line.trim();
                if line.is_empty() {
                    continue;
                }
                match parse_command(line, &station.robots) {
                    Ok((targets, request)) => {
                        for robot in targets {
                            out.answer(&robot, line, station.command(&robot, &request));
                        }
                    }
                    Err(err) => out.error(&err),
                }
            }
        });
    }

    let print_every = Duration::from_secs_f64(options.print_every_secs);
    while !stop.load(Ordering::Relaxed) {
        for report in station.reports() {
            if options.json {
                out.event(&StationEvent::Robot(Box::new(report)));
            } else {
                println!("{}", line(&report));
            }
        }
        std::thread::sleep(print_every);
    }
    Ok(())
}

/// Where the station's answers go: text lines, or JSON ones for the studio.
#[derive(Clone, Copy)]
struct Out {
    json: bool,
}

impl Out {
    fn event(self, event: &StationEvent) {
        // A line is one JSON object; a write to a closed pipe ends nothing here (the studio
        // that read it went away, and the process is then stopped).
        if let Ok(text) = serde_json::to_string(event) {
            println!("{text}");
        }
    }

    /// Prints a robot's answer to `line`; whether it was done.
    fn answer(self, robot: &str, line: &str, answer: anyhow::Result<CommandReply>) -> bool {
        let (ok, message, word) = match answer {
            Ok(reply) if reply.ok => (true, reply.message, "done"),
            Ok(reply) => (false, reply.message, "refused"),
            Err(err) => (false, format!("{err:#}"), "no answer"),
        };
        if self.json {
            self.event(&StationEvent::Answer {
                robot: robot.to_owned(),
                command: line.to_owned(),
                ok,
                message,
            });
        } else {
            println!("{robot}: {word}: {message}");
        }
        ok
    }

    fn error(self, err: &anyhow::Error) {
        if self.json {
            self.event(&StationEvent::Error {
                message: format!("{err:#}"),
            });
        } else {
            println!("station: {err:#}");
        }
    }
}

/// Sends each of `lines` once the robots it names have a session (or could not get one in
/// [`ANSWER_TIMEOUT`] and more), printing each answer; fails if one was not done.
fn send_all(station: &Station, lines: &[String], out: Out) -> anyhow::Result<()> {
    let mut failed = 0;
    for line in lines {
        let (targets, request) = parse_command(line, &station.robots)?;
        let deadline = Instant::now() + ANSWER_TIMEOUT * 2;
        while Instant::now() < deadline
            && lock(&station.views)
                .iter()
                .any(|(robot, view)| targets.contains(robot) && view.session.is_none())
        {
            std::thread::sleep(Duration::from_millis(50));
        }
        for robot in targets {
            if !out.answer(&robot, line, station.command(&robot, &request)) {
                failed += 1;
            }
        }
    }
    anyhow::ensure!(failed == 0, "{failed} command(s) not done");
    Ok(())
}

/// What the station knows of one robot now; takes a count of its samples for the link's
/// quality.
fn report(robot: &str, view: &mut View, now: Instant) -> RobotReport {
    let window = Duration::from_secs_f64(LINK_WINDOW_SECS);
    let mut link = LinkQuality::default();
    if let Some((_, channel)) = &view.session {
        let (opened, sent) = channel.counts();
        while view
            .counts
            .front()
            .is_some_and(|(at, ..)| now.duration_since(*at) > window)
        {
            view.counts.pop_front();
        }
        let (_, opened_then, sent_then) = view.counts.front().copied().unwrap_or((now, 0, 0));
        link = LinkQuality {
            received: opened.saturating_sub(opened_then),
            sent: sent.saturating_sub(sent_then),
        };
        if view
            .counts
            .back()
            .is_none_or(|(at, ..)| now.duration_since(*at) >= Duration::from_millis(900))
        {
            view.counts.push_back((now, opened, sent));
        }
    }
    let kbit_per_sec = view.since.map_or(0.0, |since| {
        view.bytes as f64 * 8.0 / 1000.0 / now.duration_since(since).as_secs_f64().max(1.0)
    });
    let camera = view.camera.as_mut().map(|(name, frames)| {
        while frames
            .front()
            .is_some_and(|(at, ..)| now.duration_since(*at) > window)
        {
            frames.pop_front();
        }
        // Between the first frame of the window and the last: each frame after the first
        // took its share of that time.
        let span_secs = match (frames.front(), frames.back()) {
            (Some((first, ..)), Some((last, ..))) => last.duration_since(*first).as_secs_f64(),
            _ => 0.0,
        };
        let after_first: usize = frames.iter().skip(1).map(|(_, sealed, _)| *sealed).sum();
        let per_sec = |value: f64| {
            if span_secs > 0.0 {
                value / span_secs
            } else {
                0.0
            }
        };
        CameraSeen {
            name: name.clone(),
            frames_per_sec: per_sec(frames.len().saturating_sub(1) as f64),
            kbit_per_sec: per_sec(after_first as f64 * 8.0 / 1000.0),
            frame_bytes: frames.back().map_or(0, |(_, _, bytes)| *bytes),
        }
    });
    RobotReport {
        robot: robot.to_owned(),
        session: view.session.is_some(),
        refusal: view.refusal.clone(),
        status: view.status.clone(),
        pose: view
            .pose
            .map(|(x_m, y_m, heading_rad)| [x_m, y_m, heading_rad]),
        route: view.route.clone(),
        report_age_secs: view
            .heard
            .map(|heard| now.duration_since(heard).as_secs_f64()),
        kbit_per_sec,
        link,
        camera,
    }
}

/// One robot's line: its state, leg, localisation, the age of its last report (a report older
/// than 2 s is shown as the last known state), the link's quality, what it costs.
fn line(report: &RobotReport) -> String {
    let robot = &report.robot;
    let Some(age) = report.report_age_secs else {
        return match (report.session, &report.refusal) {
            (true, _) => format!("robot {robot} | session open, no report yet"),
            (false, Some(why)) => format!("robot {robot} | no session: {why}"),
            (false, None) => format!("robot {robot} | no session yet"),
        };
    };
    let mut text = format!("robot {robot} |");
    if age > 2.0 {
        text.push_str(" last known:");
    }
    if let Some(status) = &report.status {
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
    if let Some([x_m, y_m, _]) = report.pose {
        text.push_str(&format!(" | at ({x_m:.1}, {y_m:.1})"));
    }
    let loss = report
        .link
        .loss()
        .map_or_else(String::new, |loss| format!(", loss {:.0} %", loss * 100.0));
    text.push_str(&format!(
        " | report {age:.1} s ago | link quality {}{loss} | {:.1} kbit/s",
        report.link.word(Some(age)),
        report.kbit_per_sec
    ));
    if let Some(camera) = &report.camera {
        text.push_str(&format!(
            " | camera {} {:.1} frames/s, {:.0} kbit/s",
            camera.name, camera.frames_per_sec, camera.kbit_per_sec
        ));
    }
    text
}

/// Takes a sample the robot sealed for this station's session `sid`.
fn take(views: &Views, robot: &str, sid: &str, bytes: &[u8], on_status: Option<&OnStatus>) {
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
    view.since.get_or_insert(now);
    let up = serde_json::from_slice::<Up>(&plain);
    // The robot's kbit/s are what its budget covers: the camera has a budget of its own.
    if !matches!(up, Ok(Up::Camera { .. })) {
        view.bytes += bytes.len() as u64;
    }
    match up {
        Ok(Up::Status(status)) => {
            if let Some(on_status) = on_status {
                on_status(robot, &status);
            }
            view.status = Some(status);
        }
        Ok(Up::Plan { route }) => view.route = route,
        Ok(Up::Camera { name, base64, .. }) => {
            let (_, frames) = view.camera.get_or_insert_with(|| (name, VecDeque::new()));
            frames.push_back((now, bytes.len(), base64.len() * 3 / 4));
        }
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
    on_status: Option<&OnStatus>,
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
                    let on_status = on_status.cloned();
                    let declared = session
                        .declare_subscriber(wire::up_key(robot, &sid))
                        .callback(move |sample| {
                            take(
                                &sink,
                                &name,
                                &own,
                                &sample.payload().to_bytes(),
                                on_status.as_ref(),
                            );
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
                                // The new session numbers its samples from 0 again.
                                view.counts.clear();
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

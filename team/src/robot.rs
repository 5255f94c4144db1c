//! The robot's side of the bridge: it attaches to its run as the studio does (the operator's
//! role on the control link, the operator's reader name at the agent), publishes the robot's
//! state to every station that proved a role, within a budget, and forwards an operator's
//! commands to the run. It also watches the operator's beats, and tells the run when the link
//! to its operator is lost and found again (`Request::Link`), which a plan's `link_lost`
//! contingency answers on the robot: the mission goes on without the radio.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::auth::{Role, RoleKey, Secret};
use armor_module_api::types::{LocalisationState, Odometry, Pose2D, PoseEstimate};
use armor_module_api::{Datum, Event, ModuleSpec, Node, Standalone};
use armor_protocol::{Client, Request, Status, allowed};
use zenoh::Wait as _;

use crate::net::z;
use crate::seal::{Admit, Channel};
use crate::wire::{self, CommandReply, Down, RobotStatus, RoutePoint, SID_BYTES, Up};

/// What the bridge publishes, and how often: the default budget of a robot. 2 reports and 5
/// poses a second take about 8 kbit/s; outputs share the rest of 50.
#[derive(Clone, Debug, clap::Args)]
pub struct Budget {
    /// Status reports a second (a few hundred bytes each).
    #[arg(long, default_value_t = 2.0)]
    pub status_hz: f64,
    /// Poses a second (about 100 bytes each).
    #[arg(long, default_value_t = 5.0)]
    pub pose_hz: f64,
    /// Samples a second of each chosen output, when it changed.
    #[arg(long, default_value_t = 1.0)]
    pub output_hz: f64,
    /// What the robot may send each station, in kbit/s: outputs wait when it is spent.
    #[arg(long = "budget-kbps", default_value_t = 50.0)]
    pub kbit_per_sec: f64,
    /// Frames a second of the `--camera`, at most.
    #[arg(long, default_value_t = 2.0)]
    pub camera_hz: f64,
    /// The camera's own budget per station, in kbit/s, apart from the robot's: a frame that
    /// does not fit waits for the next, so the rate falls rather than the budget overflows.
    #[arg(long = "camera-kbps", default_value_t = 400.0)]
    pub camera_kbit_per_sec: f64,
}

impl Default for Budget {
    /// The defaults of the command line.
    fn default() -> Budget {
        Budget {
            status_hz: 2.0,
            pose_hz: 5.0,
            output_hz: 1.0,
            kbit_per_sec: 50.0,
            camera_hz: 2.0,
            camera_kbit_per_sec: 400.0,
        }
    }
}

/// What a sample is, for the budget: a status or a pose always goes, an output waits for the
/// robot's budget, a camera frame for the camera's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    Essential,
    Output,
    Camera,
}

/// `armor-team robot`: on a robot, beside its `armor run`.
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// The robot's name in the team (`armor/team/NAME/…`).
    #[arg(long)]
    pub name: String,
    /// The run's control address (`armor run` prints it; also $ARMOR_CONTROL).
    #[arg(long, env = "ARMOR_CONTROL")]
    pub control: SocketAddr,
    /// The run's secret file: stations prove its role keys, the bridge its operator's.
    #[arg(long, env = "ARMOR_SECRET_FILE")]
    pub secret: PathBuf,
    /// zenoh endpoints to listen at (`tcp/0.0.0.0:7447`); repeat.
    #[arg(long)]
    pub listen: Vec<String>,
    /// zenoh endpoints of peers or routers to connect to; repeat.
    #[arg(long)]
    pub connect: Vec<String>,
    /// The data name of the robot's pose: a `PoseEstimate`, an `Odometry` or a `Pose2D`.
    #[arg(long, default_value = "localiser.estimate")]
    pub pose: String,
    /// An output to forward (sent when it changed, at --output-hz at most); repeat.
    #[arg(long = "output")]
    pub outputs: Vec<String>,
    /// A camera's images (an `Image` output) to forward at --camera-hz within --camera-kbps.
    #[arg(long)]
    pub camera: Option<String>,
    #[command(flatten)]
    pub budget: Budget,
    /// Seconds without an operator's beat before the run is told its link is lost.
    #[arg(long, default_value_t = 2.0)]
    pub lost_after_secs: f64,
}

/// A station's session at this robot.
struct Peer {
    role: Role,
    channel: Channel,
    /// Its first beat opened: a hello replayed by someone without the key never gets here,
    /// so nothing is published for it.
    confirmed: bool,
    heard: Instant,
    /// Bytes it may still be sent now (a token bucket refilled at the budget's rate).
    tokens: f64,
    /// The same for the camera's budget.
    camera_tokens: f64,
    refilled: Instant,
}

/// At most this many sessions at once; a new hello then closes an unconfirmed one, else the one
/// heard from longest ago.
const MAX_PEERS: usize = 32;
/// A session not heard from in this long is closed (a station that went away).
const PEER_IDLE: Duration = Duration::from_secs(120);

/// What the bridge's threads share: the stations' sessions and the run's latest data.
#[derive(Default)]
pub struct Shared {
    peers: BTreeMap<String, Peer>,
    operator_heard: Option<Instant>,
    pose: Option<(f64, f64, f64)>,
    localisation: Option<LocalisationState>,
    /// Chosen outputs that changed since they were last sent: name → (type, bytes).
    outputs: BTreeMap<String, (String, Vec<u8>)>,
    /// The camera's latest frame not sent yet: its name, type and bytes.
    camera: Option<(String, String, Vec<u8>)>,
    agent: Option<String>,
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The control link, opened again whenever it failed.
struct Control {
    addr: SocketAddr,
    key: RoleKey,
    client: Option<Client>,
}

impl Control {
    fn call(&mut self, request: &Request) -> anyhow::Result<armor_protocol::Reply> {
        if self.client.is_none() {
            self.client = Some(Client::connect_with(self.addr, Some(&self.key))?);
        }
        let Some(client) = &mut self.client else {
            unreachable!("connected above")
        };
        match client.call(request) {
            Ok(reply) => Ok(reply),
            Err(err) => {
                self.client = None;
                Err(err.into())
            }
        }
    }
}

pub fn run(options: &Options, stop: &AtomicBool) -> anyhow::Result<()> {
    anyhow::ensure!(
        wire::is_robot_name(&options.name),
        "`{}` cannot name a robot: use 1 to 64 letters, digits, `_` or `-`",
        options.name
    );
    let secret = Secret::load(&options.secret)
        .with_context(|| format!("the run's secret {}", options.secret.display()))?;
    let admit = Admit {
        operator: secret.role_key(Role::Operator),
        observer: secret.role_key(Role::Observer),
    };
    let control = Control {
        addr: options.control,
        key: RoleKey {
            role: Role::Operator,
            key: secret.role_key(Role::Operator),
        },
        client: None,
    };
    let session = crate::net::open(&options.listen, &options.connect)?;
    let shared = Arc::new(Mutex::new(Shared::default()));
    // The run's data: the pose and the chosen outputs, read as the studio reads them.
    {
        let shared = Arc::clone(&shared);
        let options = options.clone();
        std::thread::spawn(move || watch_data(&options, &shared));
    }
    let bridge = Bridge {
        robot: options.name.clone(),
        admit,
        budget: options.budget.clone(),
        lost_after: Duration::from_secs_f64(options.lost_after_secs),
    };
    bridge.serve(&session, Box::new(control), shared, stop)
}

/// The run a bridge serves: the real one over its control link, or a stand-in
/// ([`crate::stand_in`]) for tests and benchmarks that need many robots and no simulators.
pub trait RunLink: Send {
    /// A request on the run's control link, and its reply.
    fn call(&mut self, request: &Request) -> anyhow::Result<armor_protocol::Reply>;
    /// The route of the run's plan in its world frame; empty when the mission is not a plan
    /// or its frame cannot be placed.
    fn route(&mut self) -> anyhow::Result<Vec<RoutePoint>>;
    /// The robot's pose, for a run whose pose does not come from its agent (a stand-in).
    fn pose(&mut self) -> Option<(f64, f64, f64)> {
        None
    }
    /// A camera frame (name, type, bytes), for a run whose images do not come from its agent.
    fn camera(&mut self) -> Option<(String, String, Vec<u8>)> {
        None
    }
}

impl RunLink for Control {
    fn call(&mut self, request: &Request) -> anyhow::Result<armor_protocol::Reply> {
        Control::call(self, request)
    }

    fn route(&mut self) -> anyhow::Result<Vec<RoutePoint>> {
        let reply = self.call(&Request::Files)?;
        anyhow::ensure!(reply.ok, "the run sent no files: {}", reply.message);
        Ok(reply
            .files
            .map(|files| route_of(&files))
            .unwrap_or_default())
    }
}

/// The route of a run's plan in its world frame: its waypoints in the order the legs pass
/// them, placed from the world's origin (or the plan's own, on a real robot).
fn route_of(files: &armor_protocol::RunFiles) -> Vec<RoutePoint> {
    use armor_model::plan::Plan;
    let Some(mission) = &files.mission else {
        return Vec::new();
    };
    let Ok(plan) = Plan::parse(&mission.text) else {
        return Vec::new();
    };
    let world = files
        .params
        .iter()
        .find(|param| param.file.path.ends_with(".world"))
        .and_then(|param| {
            armor_model::world::World::parse(&param.file.text, &param.file.path).ok()
        });
    let Some(origin) = armor_model::plan::plan_origin(&plan, world.as_ref()) else {
        return Vec::new();
    };
    plan.route()
        .into_iter()
        .map(|waypoint| {
            let at = waypoint.position.to_local(origin);
            RoutePoint {
                name: waypoint.name.clone(),
                x_m: at.x,
                y_m: at.y,
            }
        })
        .collect()
}

/// The part of a bridge that is the same whatever run it serves: the sessions, the budget,
/// the commands and the link to the operator.
pub struct Bridge {
    pub robot: String,
    pub admit: Admit,
    pub budget: Budget,
    /// How long without an operator's beat before the run is told its link is lost.
    pub lost_after: Duration,
}

/// How often the route is sent again: a station that opens its session later gets it within
/// this time.
const ROUTE_EVERY: Duration = Duration::from_secs(5);

impl Bridge {
    /// Serves `run` on `session` until `stop`.
    pub fn serve(
        self,
        session: &zenoh::Session,
        run: Box<dyn RunLink>,
        shared: Arc<Mutex<Shared>>,
        stop: &AtomicBool,
    ) -> anyhow::Result<()> {
        let Bridge {
            robot,
            admit,
            budget,
            lost_after,
        } = self;
        let control: Arc<Mutex<Box<dyn RunLink>>> = Arc::new(Mutex::new(run));

        // Hellos: a station proves a role and gets a session.
        let hellos = z(session.declare_queryable(wire::hello_key(&robot)).wait())?;
        {
            let shared = Arc::clone(&shared);
            let robot = robot.clone();
            std::thread::spawn(move || {
                while let Ok(query) = hellos.recv() {
                    let body = query
                        .payload()
                        .map(|p| p.to_bytes().into_owned())
                        .unwrap_or_default();
                    match crate::seal::accept(&robot, &admit, &body) {
                        Ok((role, channel, answer)) => {
                            let Ok(sid) = armor_module_api::auth::random_bytes::<SID_BYTES>()
                            else {
                                continue;
                            };
                            let sid_hex = armor_module_api::auth::hex(&sid);
                            let now = Instant::now();
                            let mut shared = lock(&shared);
                            if shared.peers.len() >= MAX_PEERS
                                && let Some(oldest) = shared
                                    .peers
                                    .iter()
                                    // Unconfirmed first: hellos replayed by someone without
                                    // the key never confirm, and must not push out stations
                                    // that do.
                                    .min_by_key(|(_, peer)| (peer.confirmed, peer.heard))
                                    .map(|(sid, _)| sid.clone())
                            {
                                shared.peers.remove(&oldest);
                            }
                            shared.peers.insert(
                                sid_hex,
                                Peer {
                                    role,
                                    channel,
                                    confirmed: false,
                                    heard: now,
                                    tokens: 0.0,
                                    camera_tokens: 0.0,
                                    refilled: now,
                                },
                            );
                            drop(shared);
                            let mut reply = sid.to_vec();
                            reply.extend_from_slice(&answer);
                            tracing::info!("a station proved the {} role", role.as_str());
                            let _ = query.reply(query.key_expr().clone(), reply).wait();
                        }
                        // A stranger gets no answer at all, not even a refusal.
                        Err(err) => tracing::debug!("hello refused: {err}"),
                    }
                }
            });
        }

        // Beats: the station is there; an operator's count for the link.
        let beats = z(session
            .declare_subscriber(format!("{}/{robot}/*/beat", wire::ROOT))
            .wait())?;
        {
            let shared = Arc::clone(&shared);
            std::thread::spawn(move || {
                while let Ok(sample) = beats.recv() {
                    let Some(sid) = sample
                        .key_expr()
                        .as_str()
                        .split('/')
                        .nth(3)
                        .map(str::to_owned)
                    else {
                        continue;
                    };
                    let bytes = sample.payload().to_bytes();
                    let mut shared = lock(&shared);
                    let Some(peer) = shared.peers.get_mut(&sid) else {
                        continue;
                    };
                    let Ok(plain) = peer.channel.open(&bytes) else {
                        continue;
                    };
                    if !matches!(serde_json::from_slice(&plain), Ok(Down::Beat)) {
                        continue;
                    }
                    let now = Instant::now();
                    peer.confirmed = true;
                    peer.heard = now;
                    if peer.role == Role::Operator {
                        shared.operator_heard = Some(now);
                    }
                }
            });
        }

        // Commands: opened, checked against the session's role, forwarded, answered sealed.
        let commands = z(session.declare_queryable(wire::cmd_key(&robot)).wait())?;
        {
            let shared = Arc::clone(&shared);
            let control = Arc::clone(&control);
            std::thread::spawn(move || {
                while let Ok(query) = commands.recv() {
                    let body = query
                        .payload()
                        .map(|p| p.to_bytes().into_owned())
                        .unwrap_or_default();
                    if body.len() < SID_BYTES {
                        continue;
                    }
                    let (sid, sealed) = body.split_at(SID_BYTES);
                    let sid = armor_module_api::auth::hex(sid);
                    let opened = {
                        let mut shared = lock(&shared);
                        let Some(peer) = shared.peers.get_mut(&sid) else {
                            continue;
                        };
                        match peer.channel.open(sealed) {
                            Ok(plain) => {
                                peer.heard = Instant::now();
                                Some((peer.role, plain))
                            }
                            Err(_) => None,
                        }
                    };
                    // Not from this session's station: no answer, as to a stranger.
                    let Some((role, plain)) = opened else {
                        continue;
                    };
                    let reply = match serde_json::from_slice::<Down>(&plain) {
                        Ok(Down::Command { request })
                            if allowed(role, &request) && !is_internal(&request) =>
                        {
                            match lock_control(&control).call(&request) {
                                Ok(reply) => CommandReply {
                                    ok: reply.ok,
                                    message: reply.message,
                                },
                                Err(err) => CommandReply {
                                    ok: false,
                                    message: format!(
                                        "the robot's bridge cannot reach its run: {err:#}"
                                    ),
                                },
                            }
                        }
                        Ok(Down::Command { .. }) => CommandReply {
                            ok: false,
                            message: format!(
                                "refused: the {} role may not command this robot",
                                role.as_str()
                            ),
                        },
                        Ok(Down::Beat) | Err(_) => CommandReply {
                            ok: false,
                            message: "not a command".to_owned(),
                        },
                    };
                    let sealed = {
                        let mut shared = lock(&shared);
                        let Some(peer) = shared.peers.get_mut(&sid) else {
                            continue;
                        };
                        serde_json::to_vec(&reply)
                            .map_err(anyhow::Error::from)
                            .and_then(|plain| Ok(peer.channel.seal(&plain)?))
                    };
                    match sealed {
                        Ok(sealed) => {
                            let _ = query.reply(query.key_expr().clone(), sealed).wait();
                        }
                        Err(err) => tracing::warn!("cannot answer a command: {err:#}"),
                    }
                }
            });
        }

        let mut next_status = Instant::now();
        let mut next_pose = Instant::now();
        let mut next_output = Instant::now();
        let mut next_route = Instant::now();
        let mut next_camera = Instant::now();
        let mut next_route_fetch = Instant::now();
        // The route is fetched again when the mission changes (another plan, an update taken).
        let mut route: Option<(String, usize, Vec<RoutePoint>)> = None;
        let mut link_lost = false;
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            // The link to the operator: lost once no beat came for `lost_after`, found again at
            // the next beat; the run hears each change once.
            let heard = lock(&shared).operator_heard;
            let lost_now = heard.is_some_and(|heard| now.duration_since(heard) > lost_after);
            if lost_now != link_lost {
                match lock_control(&control).call(&Request::Link { lost: lost_now }) {
                    Ok(reply) => {
                        link_lost = lost_now;
                        tracing::info!("{}", reply.message);
                    }
                    Err(err) => tracing::warn!("cannot tell the run about its link: {err:#}"),
                }
            }
            let mut ups = Vec::new();
            if now >= next_status {
                next_status = now + Duration::from_secs_f64(1.0 / budget.status_hz);
                let status = match lock_control(&control).call(&Request::Status) {
                    Ok(reply) => reply.status,
                    Err(err) => {
                        tracing::debug!("no status from the run: {err:#}");
                        None
                    }
                };
                if let Some(status) = &status {
                    lock(&shared).agent = Some(status.agent.clone());
                }
                if let Some(mission) = status.as_ref().and_then(|status| status.mission.as_ref()) {
                    let stale = route.as_ref().is_none_or(|(name, updates, _)| {
                        (name, *updates) != (&mission.name, mission.updates.len())
                    });
                    if stale && now >= next_route_fetch {
                        match lock_control(&control).route() {
                            Ok(points) => {
                                route = Some((mission.name.clone(), mission.updates.len(), points));
                                next_route = now;
                            }
                            Err(err) => {
                                tracing::debug!("no route from the run: {err:#}");
                                next_route_fetch = now + ROUTE_EVERY;
                            }
                        }
                    }
                }
                let shared = lock(&shared);
                ups.push((
                    Class::Essential,
                    Up::Status(robot_status(
                        &robot,
                        status.as_ref(),
                        &shared,
                        link_lost,
                        now,
                    )),
                ));
            }
            if now >= next_route {
                next_route = now + ROUTE_EVERY;
                if let Some((_, _, points)) = &route
                    && !points.is_empty()
                {
                    ups.push((
                        Class::Essential,
                        Up::Plan {
                            route: points.clone(),
                        },
                    ));
                }
            }
            if now >= next_camera {
                next_camera = now + Duration::from_secs_f64(1.0 / budget.camera_hz);
                let from_run = lock_control(&control).camera();
                let frame = from_run.or_else(|| lock(&shared).camera.take());
                if let Some((name, data_type, bytes)) = frame {
                    use base64::Engine as _;
                    ups.push((
                        Class::Camera,
                        Up::Camera {
                            name,
                            data_type,
                            base64: base64::engine::general_purpose::STANDARD.encode(bytes),
                        },
                    ));
                }
            }
            if now >= next_pose {
                next_pose = now + Duration::from_secs_f64(1.0 / budget.pose_hz);
                let pose = lock_control(&control).pose();
                if pose.is_some() {
                    lock(&shared).pose = pose;
                }
                if let Some((x_m, y_m, heading_rad)) = lock(&shared).pose {
                    ups.push((
                        Class::Essential,
                        Up::Pose {
                            x_m,
                            y_m,
                            heading_rad,
                        },
                    ));
                }
            }
            if now >= next_output {
                next_output = now + Duration::from_secs_f64(1.0 / budget.output_hz);
                for (name, (data_type, bytes)) in std::mem::take(&mut lock(&shared).outputs) {
                    use base64::Engine as _;
                    ups.push((
                        Class::Output,
                        Up::Output {
                            name,
                            data_type,
                            base64: base64::engine::general_purpose::STANDARD.encode(bytes),
                        },
                    ));
                }
            }
            if !ups.is_empty() {
                publish(session, &robot, &shared, &budget, &ups);
            }
            let wake = next_status
                .min(next_pose)
                .min(next_output)
                .min(next_route)
                .min(next_camera);
            std::thread::sleep(
                wake.saturating_duration_since(Instant::now())
                    .min(Duration::from_millis(100)),
            );
        }
        Ok(())
    }
}

/// A request only the bridge itself makes: a station does not say whether the link is up.
fn is_internal(request: &Request) -> bool {
    matches!(request, Request::Link { .. })
}

fn lock_control(control: &Mutex<Box<dyn RunLink>>) -> MutexGuard<'_, Box<dyn RunLink>> {
    control.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Seals each sample for every confirmed station and puts it: a status or a pose always, an
/// output when the robot's budget for that station is not in debt, a camera frame when the
/// camera's is not (each a token bucket refilled at its rate, holding a second's worth at
/// most).
fn publish(
    session: &zenoh::Session,
    robot: &str,
    shared: &Mutex<Shared>,
    budget: &Budget,
    ups: &[(Class, Up)],
) {
    let plains: Vec<(Class, Vec<u8>)> = ups
        .iter()
        .filter_map(|(class, up)| Some((*class, serde_json::to_vec(up).ok()?)))
        .collect();
    let now = Instant::now();
    let rate = budget.kbit_per_sec * 1000.0 / 8.0;
    let camera_rate = budget.camera_kbit_per_sec * 1000.0 / 8.0;
    let mut shared = lock(shared);
    shared
        .peers
        .retain(|_, peer| now.duration_since(peer.heard) < PEER_IDLE);
    let mut puts = Vec::new();
    for (sid, peer) in &mut shared.peers {
        if !peer.confirmed {
            continue;
        }
        let elapsed = now.duration_since(peer.refilled).as_secs_f64();
        peer.tokens = (peer.tokens + elapsed * rate).min(rate);
        peer.camera_tokens = (peer.camera_tokens + elapsed * camera_rate).min(camera_rate);
        peer.refilled = now;
        for (class, plain) in &plains {
            let cost = (plain.len() + 24) as f64;
            let tokens = match class {
                Class::Essential | Class::Output => &mut peer.tokens,
                Class::Camera => &mut peer.camera_tokens,
            };
            // A sample larger than a second's budget (a map, a camera frame) still goes, once
            // the budget is not in debt, and puts it in debt: over time the rate is the
            // budget's, whatever the sizes.
            if *class != Class::Essential && *tokens < 0.0 {
                continue;
            }
            *tokens -= cost;
            if let Ok(sealed) = peer.channel.seal(plain) {
                puts.push((wire::up_key(robot, sid), sealed));
            }
        }
    }
    drop(shared);
    for (key, sealed) in puts {
        // Dropped, not queued, when the link is congested: the next report supersedes it.
        if let Err(err) = session
            .put(key, sealed)
            .congestion_control(zenoh::qos::CongestionControl::Drop)
            .wait()
        {
            tracing::debug!("cannot publish: {err}");
        }
    }
}

fn robot_status(
    robot: &str,
    status: Option<&Status>,
    shared: &Shared,
    link_lost: bool,
    now: Instant,
) -> RobotStatus {
    let mut report = RobotStatus {
        robot: robot.to_owned(),
        localisation: shared.localisation.map(|state| state.as_str().to_owned()),
        operator_heard_secs_ago: shared
            .operator_heard
            .map(|heard| now.duration_since(heard).as_secs_f64()),
        link_lost,
        ..RobotStatus::default()
    };
    let Some(status) = status else {
        report.state = "run unreachable".to_owned();
        return report;
    };
    report.run_secs = status.run_secs;
    let Some(mission) = &status.mission else {
        report.state = "no mission".to_owned();
        return report;
    };
    report.places = mission.marking.keys().cloned().collect();
    // A plan's places are named after their leg (`LEG_drive`, `LEG_hold`…), and the compiler
    // makes leg names identifiers: the leg is the name before the place's role.
    report.leg = report.places.first().map(|place| leg_of(place).to_owned());
    report.state = if let Some(outcome) = &mission.outcome {
        outcome.clone()
    } else if mission.paused {
        "paused".to_owned()
    } else if report.places.iter().any(|place| place.ends_with("_hold")) {
        "holding".to_owned()
    } else {
        "running".to_owned()
    };
    report.firings_total = mission.firings_total;
    report.last_firing = mission
        .firings
        .last()
        .map(|firing| firing.transition.clone());
    report
}

/// The leg of a plan's place: its name without the role the compiler appends.
fn leg_of(place: &str) -> &str {
    const ROLES: [&str; 9] = [
        "_depart",
        "_drive_late",
        "_drive",
        "_return_hold",
        "_hold",
        "_return",
        "_arrival",
        "_wait",
        "_appointment",
    ];
    ROLES
        .iter()
        .find_map(|role| place.strip_suffix(role))
        .unwrap_or(place)
}

/// Reads the pose and the chosen outputs from the run, connecting again when the run's agent
/// goes away, until the process ends.
fn watch_data(options: &Options, shared: &Mutex<Shared>) {
    loop {
        let agent = lock(shared).agent.clone();
        if let Some(agent) = agent
            && let Err(err) = watch_once(options, &agent, shared)
        {
            tracing::debug!("the run's data: {err:#}");
        }
        std::thread::sleep(Duration::from_secs(1));
    }
}

fn watch_once(options: &Options, agent: &str, shared: &Mutex<Shared>) -> anyhow::Result<()> {
    let spec = ModuleSpec::new(Role::Operator.data_identity(), "ArMoR's team bridge.");
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some(Role::Operator.data_identity().to_owned()),
            agent: Some(agent.to_owned()),
            secret: Some(options.secret.clone()),
            ..Standalone::default()
        },
    )?;
    let pose = node.subscribe_raw_at_most(&options.pose, options.budget.pose_hz)?;
    let outputs = options
        .outputs
        .iter()
        .map(|name| {
            Ok((
                node.subscribe_raw_at_most(name, options.budget.output_hz)?,
                name.clone(),
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let camera = match &options.camera {
        Some(name) => Some((
            node.subscribe_raw_at_most(name, options.budget.camera_hz)?,
            name.clone(),
        )),
        None => None,
    };
    let mut last_sent: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    loop {
        let Event::Input(id) = node.next_event(Some(Duration::from_millis(500)))? else {
            continue;
        };
        if id == pose.id() {
            let Some(sample) = node.take_raw(&pose) else {
                continue;
            };
            let (pose, state) = match sample.data_type.as_str() {
                "PoseEstimate" => match PoseEstimate::decode(&sample.payload) {
                    Ok(estimate) => (estimate.pose_in_map, Some(estimate.state)),
                    Err(_) => continue,
                },
                "Odometry" => match Odometry::decode(&sample.payload) {
                    Ok(odometry) => (odometry.pose_in_odom, None),
                    Err(_) => continue,
                },
                "Pose2D" => match Pose2D::decode(&sample.payload) {
                    Ok(pose) => (pose, None),
                    Err(_) => continue,
                },
                _ => continue,
            };
            let mut shared = lock(shared);
            shared.pose = Some((pose.x_m, pose.y_m, pose.theta_rad));
            if state.is_some() {
                shared.localisation = state;
            }
        } else if let Some((input, name)) = camera.as_ref().filter(|(input, _)| input.id() == id) {
            // The latest frame replaces one not sent yet: a late frame is worth nothing.
            if let Some(sample) = node.take_raw(input) {
                lock(shared).camera = Some((name.clone(), sample.data_type, sample.payload));
            }
        } else if let Some((input, name)) = outputs.iter().find(|(input, _)| input.id() == id) {
            let Some(sample) = node.take_raw(input) else {
                continue;
            };
            // A map (or any output) is sent again only when it changed.
            if last_sent.get(name) == Some(&sample.payload) {
                continue;
            }
            last_sent.insert(name.clone(), sample.payload.clone());
            lock(shared)
                .outputs
                .insert(name.clone(), (sample.data_type, sample.payload));
        }
    }
}

//! Stand-in robots: the real bridge ([`crate::robot::Bridge`]: sessions, budget, sealing,
//! commands, the operator's link) serving a run that is only a clock, so that a test or a
//! benchmark can put 20 robots in front of one station on 2 cores, which cannot run 20
//! simulators. Each stand-in drives round a square of four waypoints at 0.5 m/s (its pose and
//! its legs follow the clock), pauses, resumes, aborts, fires and takes plan updates as a run
//! answers them, and has its own zenoh session, as a robot has its own radio.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::auth::{Role, Secret};
use armor_protocol::{FiringRecord, MissionStatus, Reply, Request, Status};

use crate::robot::{Bridge, Budget, RunLink, Shared};
use crate::seal::Admit;
use crate::wire::{self, RoutePoint};

/// `armor-team stand-ins`: robots that are only a clock, for tests and benchmarks.
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// How many robots: NAME-1, NAME-2, …
    #[arg(long, default_value_t = 20)]
    pub count: usize,
    /// The number of the first (another process's stand-ins then drive squares of their own).
    #[arg(long, default_value_t = 1)]
    pub first: usize,
    /// What their names start with.
    #[arg(long, default_value = "robot")]
    pub name: String,
    /// The team's secret file (stations prove its role keys).
    #[arg(long)]
    pub secret: std::path::PathBuf,
    /// zenoh endpoints each robot connects to (a station's `--listen`, or a router); repeat.
    #[arg(long)]
    pub connect: Vec<String>,
    /// A camera of frames of this many bytes (a JPEG of the simulated camera is 15 to 40 kB),
    /// sent at --camera-hz within --camera-kbps; none when 0.
    #[arg(long, default_value_t = 0)]
    pub camera_bytes: usize,
    #[command(flatten)]
    pub budget: Budget,
}

/// The speed stand-ins drive at, and the side of their square.
const SPEED_MPS: f64 = 0.5;
const SIDE_M: f64 = 8.0;

pub fn run(options: &Options, stop: &'static AtomicBool) -> anyhow::Result<()> {
    let secret = Secret::load(&options.secret)
        .with_context(|| format!("the team's secret {}", options.secret.display()))?;
    let epoch = Instant::now();
    let mut threads = Vec::new();
    for index in options.first.saturating_sub(1)..options.first.saturating_sub(1) + options.count {
        let name = format!("{}-{}", options.name, index + 1);
        anyhow::ensure!(
            wire::is_robot_name(&name),
            "`{name}` cannot name a robot: use 1 to 64 letters, digits, `_` or `-`"
        );
        let session = crate::net::open(&[], &options.connect)?;
        let bridge = bridge(&name, &secret, options.budget.clone());
        let run = StandIn::new(&name, index, epoch).with_camera(options.camera_bytes);
        let name = name.clone();
        threads.push(std::thread::spawn(move || {
            let shared = Arc::new(Mutex::new(Shared::default()));
            if let Err(err) = bridge.serve(&session, Box::new(run), shared, stop) {
                eprintln!("armor-team: stand-in {name}: {err:#}");
            }
        }));
    }
    println!("stand-ins: {} robots", options.count);
    for thread in threads {
        let _ = thread.join();
    }
    Ok(())
}

/// The bridge of a stand-in called `name`, admitting the roles of `secret`.
pub fn bridge(name: &str, secret: &Secret, budget: Budget) -> Bridge {
    Bridge {
        robot: name.to_owned(),
        admit: Admit {
            operator: secret.role_key(Role::Operator),
            observer: secret.role_key(Role::Observer),
        },
        budget,
        lost_after: Duration::from_secs(2),
    }
}

/// A run that is only a clock: its mission drives round a square, each side a leg.
pub struct StandIn {
    name: String,
    route: Vec<RoutePoint>,
    epoch: Instant,
    /// Seconds driven before the latest pause or resume, and since when it drives (none while
    /// paused).
    driven_secs: f64,
    driving_since: Option<Instant>,
    outcome: Option<String>,
    updates: usize,
    fired: Vec<FiringRecord>,
    /// The size of its camera's frames; none without a camera.
    camera_bytes: Option<usize>,
    frames: u64,
}

impl StandIn {
    /// The `index`th stand-in: its square lies on a grid of squares, five a row, so that 20
    /// robots are all in sight on one map. `epoch` is the clock its status reports (`run_secs`
    /// are seconds since it), which a benchmark in the same process reads latencies from.
    pub fn new(name: &str, index: usize, epoch: Instant) -> StandIn {
        let (x0, y0) = ((index % 5) as f64 * 12.0, (index / 5) as f64 * 12.0);
        let corners = [(0.0, 0.0), (SIDE_M, 0.0), (SIDE_M, SIDE_M), (0.0, SIDE_M)];
        let route = (0..=corners.len())
            .map(|i| {
                let (x, y) = corners[i % corners.len()];
                RoutePoint {
                    name: format!("wp{}", i % corners.len() + 1),
                    x_m: x0 + x,
                    y_m: y0 + y,
                }
            })
            .collect();
        StandIn {
            name: name.to_owned(),
            route,
            epoch,
            // Each starts at another place round its square, so that they do not move in step.
            driven_secs: index as f64 * 3.7,
            driving_since: Some(epoch),
            outcome: None,
            updates: 0,
            fired: Vec::new(),
            camera_bytes: None,
            frames: 0,
        }
    }

    /// The same with a camera of `bytes`-byte frames (none when 0).
    pub fn with_camera(mut self, bytes: usize) -> StandIn {
        self.camera_bytes = (bytes > 0).then_some(bytes);
        self
    }

    fn driven_secs(&self) -> f64 {
        self.driven_secs
            + self
                .driving_since
                .map_or(0.0, |since| since.elapsed().as_secs_f64())
    }

    /// The leg being driven (from 0) and the share of it done.
    fn on_leg(&self) -> (usize, f64) {
        let legs = self.route.len() - 1;
        let leg_secs = SIDE_M / SPEED_MPS;
        let laps = self.driven_secs() / leg_secs;
        ((laps.floor() as usize) % legs, laps.fract())
    }

    fn status(&self) -> Status {
        let (leg, _) = self.on_leg();
        let leg_name = format!("leg{}", leg + 1);
        let place = if self.driving_since.is_none() && self.outcome.is_none() {
            format!("{leg_name}_hold")
        } else {
            format!("{leg_name}_drive")
        };
        let legs_done = (self.driven_secs() / (SIDE_M / SPEED_MPS)).floor() as usize;
        Status {
            system: self.name.clone(),
            run_secs: self.epoch.elapsed().as_secs_f64(),
            time_scale: 1.0,
            mission: Some(MissionStatus {
                name: "square".to_owned(),
                paused: self.driving_since.is_none() && self.outcome.is_none(),
                marking: [(place, 1)].into_iter().collect(),
                firings_total: legs_done + self.fired.len(),
                firings: self.fired.clone(),
                outcome: self.outcome.clone(),
                ..MissionStatus::default()
            }),
            ..Status::default()
        }
    }
}

impl RunLink for StandIn {
    fn call(&mut self, request: &Request) -> anyhow::Result<Reply> {
        let now = Instant::now();
        let message = match request {
            Request::Status | Request::Link { .. } => "status".to_owned(),
            Request::Pause => {
                if let Some(since) = self.driving_since.take() {
                    self.driven_secs += now.duration_since(since).as_secs_f64();
                }
                "paused".to_owned()
            }
            Request::Resume => {
                if self.outcome.is_none() {
                    self.driving_since.get_or_insert(now);
                }
                "resumed".to_owned()
            }
            Request::Abort => {
                if let Some(since) = self.driving_since.take() {
                    self.driven_secs += now.duration_since(since).as_secs_f64();
                }
                self.outcome = Some("aborted".to_owned());
                "aborted".to_owned()
            }
            Request::Fire { transition } => {
                self.fired.push(FiringRecord {
                    run_secs: self.epoch.elapsed().as_secs_f64(),
                    transition: transition.clone(),
                    by_hand: true,
                });
                format!("fired `{transition}`")
            }
            Request::Update { file, .. } => {
                self.updates += 1;
                format!("update `{file}` taken")
            }
            _ => {
                return Ok(Reply {
                    ok: false,
                    message: "a stand-in robot does not do that".to_owned(),
                    status: None,
                    files: None,
                });
            }
        };
        Ok(Reply {
            ok: true,
            message,
            status: Some(self.status()),
            files: None,
        })
    }

    fn route(&mut self) -> anyhow::Result<Vec<RoutePoint>> {
        Ok(self.route.clone())
    }

    fn camera(&mut self) -> Option<(String, String, Vec<u8>)> {
        let bytes = self.camera_bytes?;
        self.frames += 1;
        // Bytes that do not compress, as a JPEG's do not: the frame's number, repeated through
        // a mixing step.
        let mut state = self.frames.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let frame = (0..bytes)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        Some(("camera.image".to_owned(), "Image".to_owned(), frame))
    }

    fn pose(&mut self) -> Option<(f64, f64, f64)> {
        let (leg, done) = self.on_leg();
        let (from, to) = (&self.route[leg], &self.route[leg + 1]);
        let (dx, dy) = (to.x_m - from.x_m, to.y_m - from.y_m);
        Some((from.x_m + dx * done, from.y_m + dy * done, dy.atan2(dx)))
    }
}

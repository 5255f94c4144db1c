//! `armor run`: starts the agent, the config server and every module process of a system,
//! streams their logs with a module prefix, restarts modules that crash, and stops everything on
//! Ctrl-C or SIGTERM. Children are in their own process group (Ctrl-C reaches only the
//! supervisor, which stops them in order) and die with it if it is killed (`PR_SET_PDEATHSIG`).

use std::collections::BTreeMap;
use std::io::{BufRead as _, BufReader, Read};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_model::RestartPolicy;
use armor_module_api::auth::{ENV_ENCRYPT, ENV_KEY_FD, ENV_SECRET_FILE, Secret};
use armor_module_api::clock::{ENV_EPOCH, ENV_TIME_SCALE, unix_now_ns};
use armor_module_api::protocol::FromSupervisor;
use armor_module_api::{Clock, ENV_AGENT, ENV_MODULE, ENV_RUN_DIR, ENV_SUPERVISOR};

use crate::agent::{Acl, ENV_ACL};
use crate::config_server::{ConfigServer, ServerEvent};
use crate::controller::{Controller, Outcome};
use crate::hosts::{HostLink, ModuleChild};
use crate::load::{Diagnostics, Loaded, load_system};
use crate::mission::{DocumentKind, LoadedMission, PlanMemory, document_kind, load_mission_kept};
use crate::process::hand_over;
use crate::progress::{self, Progress};
use crate::restart::{AfterCrash, Backoff, CRASH_WINDOW, FIRST_BACKOFF, MAX_BACKOFF};
use crate::{console, control, probe, run_dir};

const TICK: Duration = Duration::from_millis(20);
/// After asking modules to shut down, how long before SIGTERM, and then before SIGKILL.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);
const TERM_GRACE: Duration = Duration::from_secs(1);
const AGENT_START_TIMEOUT: Duration = Duration::from_secs(5);

pub struct RunOptions {
    pub file: PathBuf,
    pub module_path: Vec<PathBuf>,
    /// Run time passes this many times faster than real time.
    pub time_scale: f64,
    /// Stop after this much real time.
    pub duration: Option<Duration>,
    /// Where the agent listens; a free port on the system's host when `None`.
    pub agent_addr: Option<SocketAddr>,
    /// Where a mission's control interface listens; a free port on the system's host when `None`.
    pub control_addr: Option<SocketAddr>,
    /// Where to write a mission's timeline (JSON) when it ends.
    pub report: Option<PathBuf>,
    /// The date (Unix seconds) run time 0 stands for, against which a mission's dates are
    /// compared: to rehearse a plan made for another day. Now when `None`.
    pub start_at_unix_secs: Option<f64>,
    /// A module silent for this long (no answer to pings) is killed and handled as a crash;
    /// `None` turns the heartbeat off.
    pub lease: Option<Duration>,
    /// A file holding the shared secret every connection of the run must prove (see
    /// `armor_module_api::auth`); passed on to the agent; each module gets only the key of its
    /// own name, derived from it.
    pub secret_file: Option<PathBuf>,
    /// With a secret: every link between modules is encrypted too (the agent's and the config
    /// server's always are).
    pub encrypt: bool,
    /// Names outside the system that the access lists let subscribe to everything.
    pub observers: Vec<String>,
    /// The folder under which the run makes its own (`run_dir`): its log, report, summary and
    /// the files its modules write under relative names. `None`: no folder.
    pub runs_dir: Option<PathBuf>,
    /// Hosts (`armor host`) whose clock differs from ours by more than this refuse a mission
    /// with time constraints; `None`: any skew is only reported.
    pub max_clock_skew: Option<Duration>,
    /// How long a host daemon keeps its modules without hearing from this run.
    pub host_orphan: Duration,
    /// How long (real time) a mission may wait for an operator alone (a leg held) before the
    /// run ends; `None`: as long as it takes.
    pub hold_timeout: Option<Duration>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ProcState {
    Running,
    /// Crashed; will be started again at the given instant.
    Restarting(Instant),
    /// Crashed too often, or crashed with restart `never`.
    Failed,
    /// Ended on its own with success and is not to be restarted.
    Exited,
}

struct ModuleProc {
    name: String,
    module_type: String,
    /// The declared host it runs on (`armor host`), or `None` for this machine.
    host: Option<String>,
    restart: RestartPolicy,
    child: Option<ModuleChild>,
    state: ProcState,
    crashes: Backoff,
    restarts: u32,
    /// The process has its configuration (said `ready`).
    configured: bool,
    /// How the process last ended, when it crashed.
    last_exit: Option<String>,
}

/// What every child needs to join the run.
struct RunEnv {
    agent_addr: SocketAddr,
    supervisor_addr: SocketAddr,
    epoch_ns: u64,
    time_scale: f64,
    module_path: Vec<PathBuf>,
    secret: Option<Secret>,
    encrypt: bool,
    /// The run's folder, given to every module (`ARMOR_RUN_DIR`).
    run_dir: Option<PathBuf>,
    /// The links to the host daemons, by host name.
    hosts: BTreeMap<String, HostLink>,
}

/// A file to run: a system, or a mission over a system; what planning the mission's plan
/// found is kept in `memory`, for its updates.
fn load(
    options: &RunOptions,
    memory: &mut PlanMemory,
) -> Result<(Loaded, Option<LoadedMission>), Diagnostics> {
    match document_kind(&options.file)? {
        DocumentKind::System => Ok((load_system(&options.file, &options.module_path)?, None)),
        DocumentKind::Mission | DocumentKind::Pnml | DocumentKind::Plan => {
            let mission = load_mission_kept(&options.file, &options.module_path, memory)?;
            for warning in mission.warnings() {
                tracing::warn!(
                    "{}:{}: {}",
                    options.file.display(),
                    warning.pos,
                    warning.message
                );
            }
            Ok((mission.system.clone(), Some(mission)))
        }
    }
}

pub fn run(options: RunOptions) -> anyhow::Result<ExitCode> {
    // An absolute path, so that children started elsewhere find it too.
    let secret_file = options
        .secret_file
        .as_ref()
        .map(|file| std::path::absolute(file).unwrap_or_else(|_| file.clone()));
    let secret = secret_file
        .as_deref()
        .map(Secret::load)
        .transpose()
        .context("the run's secret")?;
    if secret.is_some() {
        tracing::info!("links are authenticated with the shared secret");
    }
    let mut memory = PlanMemory::default();
    let (loaded, mission) = match load(&options, &mut memory) {
        Ok(loaded) => loaded,
        Err(diagnostics) => {
            eprintln!("{diagnostics}");
            return Ok(ExitCode::FAILURE);
        }
    };
    let time_constraints = mission
        .as_ref()
        .is_some_and(|mission| crate::host_run::has_time_constraints(&mission.net));
    let epoch_ns = unix_now_ns();
    let run_folder = match &options.runs_dir {
        None => None,
        Some(parent) => {
            let name = mission
                .as_ref()
                .map_or(&loaded.system.name, |mission| &mission.net.name);
            let dir = run_dir::create(parent, name, epoch_ns as f64 / 1e9).with_context(|| {
                format!("cannot make the run's folder under {}", parent.display())
            })?;
            let log = std::fs::File::create(dir.join(run_dir::LOG))
                .with_context(|| format!("cannot write {}", dir.join(run_dir::LOG).display()))?;
            console::log_to(log);
            tracing::info!("this run's folder: {}", dir.display());
            Some(dir)
        }
    };
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .context("cannot install signal handlers")?;
    }
    let host = loaded.system.host_or_default().to_owned();
    let local = |port: u16| -> anyhow::Result<SocketAddr> {
        format!("{host}:{port}")
            .parse()
            .or_else(|_| format!("[{host}]:{port}").parse())
            .with_context(|| format!("bad host `{host}`"))
    };
    let clock = Clock::new(epoch_ns, options.time_scale);
    // A plan made for a day that has passed is rehearsed on that day, not run late.
    let start_at_unix_secs = options.start_at_unix_secs.or_else(|| {
        let planned = mission.as_ref()?.planned_start_unix_secs?;
        (planned < epoch_ns as f64 / 1e9).then(|| {
            tracing::info!(
                "the plan is made for {}, which has passed: rehearsed as if starting then \
                 (--start-at DATE to choose another day)",
                armor_model::net::format_rfc3339(planned)
            );
            planned
        })
    });
    let system_file = mission.as_ref().map_or_else(
        || options.file.clone(),
        |mission| mission.system_file.clone(),
    );
    // A plan's legs, for the summary printed when the run ends; updates replace them.
    let mut plan_legs = mission
        .as_ref()
        .and_then(|mission| Some((mission.plan.clone()?, mission.compiled.clone()?)));
    let mut running_plan = mission.as_ref().and_then(|mission| {
        Some(crate::update::Running {
            file: options.file.clone(),
            system_file: mission.system_file.clone(),
            plan: mission.plan.clone()?,
            compiled: mission.compiled.clone()?,
            memory: std::mem::take(&mut memory),
        })
    });
    let mut controller = mission.map(|mission| {
        let controllable = loaded
            .system
            .modules
            .iter()
            .filter(|module| {
                loaded
                    .descriptions
                    .get(&module.module_type)
                    .is_some_and(|description| description.controllable)
            })
            .map(|module| module.name.clone())
            .collect();
        tracing::info!(
            mission = mission.net.name,
            states = mission.states,
            "mission checked"
        );
        Controller::new(
            // A place that names a subsystem runs its modules.
            mission.net.with_subsystems_expanded(&loaded.system),
            controllable,
            clock,
            start_at_unix_secs.unwrap_or(epoch_ns as f64 / 1e9),
            options.report.is_some() || run_folder.is_some(),
        )
        .with_hold_timeout(options.hold_timeout)
    });
    for name in &options.observers {
        if loaded.system.module(name).is_some() {
            tracing::warn!("--observer `{name}` is a module of the system: it keeps its own lists");
        }
    }
    // The run's own node, which follows the robot for the progress line, watches like any
    // observer.
    let mut observers = options.observers.clone();
    if plan_legs.is_some() {
        observers.push(progress::NODE_NAME.to_owned());
    }
    let hosts = match crate::host_run::connect_hosts(
        &loaded.system,
        secret.clone(),
        options.host_orphan,
        time_constraints,
        options.max_clock_skew,
    ) {
        Ok(hosts) => hosts,
        Err(err) => {
            tracing::error!("{err:#}");
            return Ok(ExitCode::FAILURE);
        }
    };
    let mut agent = AgentProc::start(
        options.agent_addr.map_or_else(|| local(0), Ok)?,
        secret.clone(),
        run_acl(&loaded.system, &observers),
    )?;
    let control = controller
        .as_ref()
        .map(Controller::control)
        .unwrap_or_default();
    let (server, events) = ConfigServer::start(
        local(0)?,
        loaded.clone(),
        control,
        options.lease,
        secret.clone(),
        clock,
    )
    .context("cannot start the config server")?;
    if let Some(controller) = &mut controller {
        controller.note_demand(&server);
    }
    if let Err(err) = server.watch(&system_file, options.module_path.clone()) {
        tracing::warn!("cannot watch {} for changes: {err}", system_file.display());
    }
    let (requests_tx, requests) = mpsc::channel::<control::Incoming>();
    let control_addr = control::serve(
        options.control_addr.map_or_else(|| local(0), Ok)?,
        requests_tx,
        secret.clone(),
    )
    .context("cannot start the control interface")?;
    tracing::info!(addr = %control_addr, "control interface listening (armor ctl --addr {control_addr} status|start|stop|pause|resume|abort|fire NAME|update PLAN)");
    console::out_line(&format!("{}{control_addr}", crate::CONTROL_READY_PREFIX));
    let env = RunEnv {
        agent_addr: agent.addr,
        supervisor_addr: server.addr(),
        epoch_ns,
        time_scale: options.time_scale,
        module_path: options.module_path.clone(),
        secret: secret.clone(),
        encrypt: options.encrypt,
        run_dir: run_folder.clone(),
        hosts,
    };
    let start_unix_secs = start_at_unix_secs.unwrap_or(epoch_ns as f64 / 1e9);
    // In a simulated run, the simulator's true pose judges the rehearsal.
    let truth_source = plan_legs
        .as_ref()
        .and_then(|_| crate::rehearsal::truth_source(&loaded.system, &loaded.descriptions));
    let mut progress = plan_legs.as_ref().map(|(plan, compiled)| {
        let odometry = loaded
            .system
            .bindings(&plan.navigation.module, None)
            .and_then(|bindings| bindings.inputs.get("odometry").cloned());
        let truth = truth_source.clone().map(|source| {
            tracing::info!("the rehearsal is judged by the simulator's truth, `{source}`");
            let judge =
                crate::rehearsal::judge(plan, compiled, &loaded.system, &loaded.descriptions);
            (source, judge)
        });
        Progress::start(
            progress::leg_plans(plan, compiled, start_unix_secs),
            plan.navigation.speed_mps,
            progress::Watch {
                agent: env.agent_addr,
                secret_file: secret_file.clone(),
                odometry,
                truth,
            },
        )
    });
    // The updates and repairs go to the recording through the run's node.
    if let (Some(controller), Some(progress)) = (&mut controller, &progress) {
        controller.set_records(progress.records());
    }
    let started = Instant::now();
    tracing::info!(
        system = loaded.system.name,
        modules = loaded.system.modules.len(),
        config_server = %server.addr(),
        time_scale = options.time_scale,
        "run started"
    );
    let mut modules: BTreeMap<String, ModuleProc> = BTreeMap::new();
    add_modules(&mut modules, &loaded, &env);
    let teleop = crate::teleop_relay::start(secret.clone());
    let mut ready: Vec<String> = Vec::new();
    let mut all_ready_logged = false;
    // Plan updates asked for, taken one a turn of the loop (see `checked` below).
    let mut queued_updates = std::collections::VecDeque::new();
    let mut checked = None;
    // The repair proposed while a leg holds for want of a way (`crate::repair`).
    let mut proposal: Option<crate::repair::Proposal> = None;
    let outcome = loop {
        if stop.load(Ordering::Relaxed) {
            tracing::info!("stop requested");
            break ExitCode::SUCCESS;
        }
        if options
            .duration
            .is_some_and(|duration| started.elapsed() >= duration)
        {
            // A mission cut short has not done its job; a plain system run has.
            if controller.is_some() {
                tracing::error!("run duration reached before the mission ended");
                break ExitCode::FAILURE;
            }
            tracing::info!("run duration reached");
            break ExitCode::SUCCESS;
        }
        if let Some(controller) = &mut controller {
            controller.step(&server);
            if let Some(progress) = &mut progress {
                progress.tick(
                    clock.now_secs(),
                    controller.first_marked(),
                    controller.first_fired(),
                );
                controller.set_progress(progress.leg_progress());
                crate::repair::forecast_late(controller, progress.leg_progress().as_ref(), &server);
            }
            match controller.outcome() {
                None => {}
                Some(Outcome::Complete) => break ExitCode::SUCCESS,
                Some(Outcome::Aborted) => {
                    tracing::error!("mission aborted");
                    break ExitCode::FAILURE;
                }
                Some(Outcome::Deadlock { marking }) => {
                    tracing::error!("mission failed: deadlock in {marking}");
                    break ExitCode::FAILURE;
                }
                Some(Outcome::Failed { module }) => {
                    tracing::error!(
                        "mission failed: module `{module}` failed and nothing in the mission handles module.{module}.failed"
                    );
                    break ExitCode::FAILURE;
                }
                Some(Outcome::Unattended {
                    marking,
                    waited_secs,
                }) => {
                    tracing::error!(
                        "mission ended: it waited {waited_secs:.0} s for the operator in {marking} and nobody answered (--hold-timeout)"
                    );
                    break ExitCode::FAILURE;
                }
            }
        }
        // A leg that starts to hold gets its repair proposed; the plan's default is taken
        // first of the updates asked for, as the next one: checked already when it was to come
        // later, so that it is taken within a turn of this loop and its migration.
        if let (Some(controller), Some(running)) = (&mut controller, &mut running_plan) {
            let run_secs = clock.now_secs();
            match crate::repair::watch(
                &mut proposal,
                controller,
                running,
                progress.as_ref().and_then(Progress::robot_at),
                (run_secs, start_unix_secs + run_secs),
                |running| {
                    crate::update::world_of(running, &server.loaded().system, &options.module_path)
                },
            ) {
                Some(crate::repair::Due::Asked(asked)) => queued_updates.push_front((asked, None)),
                Some(crate::repair::Due::Checked {
                    checked: update, ..
                }) if checked.is_none() => {
                    checked = Some((*update, None));
                }
                // Another update is checked and waits to be swapped in: the default is taken
                // after it, checked again against the plan it makes.
                Some(crate::repair::Due::Checked { asked, .. }) => {
                    queued_updates.push_front((asked, None));
                }
                None => {}
            }
            if let Some(proposal) = &mut proposal {
                proposal.check_default(running, &options.module_path);
            }
        }
        while let Ok((request, reply)) = requests.try_recv() {
            let (ok, message) = match request {
                armor_protocol::Request::Status => (true, "status".to_owned()),
                armor_protocol::Request::StartModule { module } => {
                    set_override(&server, &module, Some(true))
                }
                armor_protocol::Request::StopModule { module } => {
                    set_override(&server, &module, Some(false))
                }
                armor_protocol::Request::ReleaseModule { module } => {
                    set_override(&server, &module, None)
                }
                armor_protocol::Request::SetPose {
                    x_m,
                    y_m,
                    heading_deg,
                    module,
                } => {
                    let value = format!("{x_m} {y_m} {heading_deg}");
                    match server.set_param(module.as_deref(), "localiser", "set_pose", &value) {
                        Ok(module) => (true, format!("`{module}`: pose set to {value}")),
                        Err(why) => (false, why),
                    }
                }
                armor_protocol::Request::Teleop {
                    linear,
                    angular,
                    module,
                } => {
                    let candidates =
                        modules
                            .values()
                            .map(|process| crate::teleop_relay::Candidate {
                                name: &process.name,
                                module_type: &process.module_type,
                                up: process.state == ProcState::Running && process.configured,
                            });
                    match crate::teleop_relay::target(
                        candidates,
                        &server.endpoints(),
                        module.as_deref(),
                    ) {
                        Ok((module, addr)) => {
                            // The relay answers: a slow module never holds up this loop.
                            let _ = teleop.send(crate::teleop_relay::Command {
                                module,
                                addr,
                                linear,
                                angular,
                                reply,
                            });
                            continue;
                        }
                        Err(why) => (false, why.to_string()),
                    }
                }
                armor_protocol::Request::Files => {
                    let plan = running_plan.as_ref().map(|running| &running.plan);
                    let _ = reply.send(run_files(&options.file, plan, &system_file, &server));
                    continue;
                }
                armor_protocol::Request::Repair { option } => {
                    match crate::repair::asked(proposal.as_ref(), option) {
                        // Taken as any update, in turn.
                        Ok(asked) if controller.is_some() => {
                            queued_updates.push_back((asked, Some(reply)));
                            continue;
                        }
                        Ok(_) => (false, "this run has no mission".to_owned()),
                        Err(why) => (false, why.to_string()),
                    }
                }
                request => match (crate::update::Asked::of(request), &mut controller) {
                    // Taken below, once the events before it are played: see `checked`.
                    (Ok(asked), Some(_)) if running_plan.is_some() => {
                        queued_updates.push_back((asked, Some(reply)));
                        continue;
                    }
                    (Ok(asked), Some(controller)) => crate::update::refuse(
                        controller,
                        &asked.label(),
                        "this run plays a mission net, not a plan: only a plan is updated",
                    ),
                    (Err(mission_request), Some(controller)) => {
                        // A held leg retried drives from where the robot is.
                        let rerouted = match (&mission_request, &mut running_plan) {
                            (armor_protocol::Request::Fire { transition }, Some(running)) => {
                                reroute_retry(
                                    controller,
                                    running,
                                    transition,
                                    progress.as_ref(),
                                    (&server, &options.module_path),
                                )
                            }
                            _ => None,
                        };
                        let (ok, message) = controller.handle(mission_request, &server);
                        match rerouted {
                            Some(how) if ok => (ok, format!("{message}: {how}")),
                            _ => (ok, message),
                        }
                    }
                    (_, None) => (false, "this run has no mission".to_owned()),
                },
            };
            if let Some(controller) = &mut controller {
                controller.note_demand(&server);
            }
            answer(
                &reply,
                ok,
                message,
                run_status(&modules, &server, controller.as_ref(), &env, &clock),
            );
        }
        // A plan update is checked and compiled first (the slow part); the module events that
        // came meanwhile are then played on the running net, one a turn as always, and only
        // once none is left is the update migrated and swapped in: an event of the old leg (its
        // `goal_reached`) is never taken for one of the new.
        if checked.is_none()
            && let Some((asked, reply)) = queued_updates.pop_front()
            && let (Some(controller), Some(running)) = (&mut controller, &mut running_plan)
        {
            match asked.check(running, &options.module_path) {
                Ok(update) => checked = Some((update, reply)),
                Err(why) => {
                    // An area that cuts a later leg is a fact: its repair is proposed, and
                    // taken with it at once when the plan names the default.
                    let run_secs = clock.now_secs();
                    let cut = match &asked {
                        crate::update::Asked::Area(area) => crate::update::with_area(running, area)
                            .ok()
                            .and_then(|plan| {
                                let world = crate::update::world_of(
                                    running,
                                    &server.loaded().system,
                                    &options.module_path,
                                )
                                .ok()?;
                                crate::repair::for_cut_leg(
                                    controller,
                                    running,
                                    &asked.label(),
                                    &plan,
                                    (run_secs, start_unix_secs + run_secs),
                                    world.as_ref(),
                                )
                            }),
                        _ => None,
                    };
                    match cut {
                        Some((made, Some(default))) => {
                            proposal = Some(made);
                            queued_updates.push_front((default, reply));
                        }
                        cut => {
                            let why = match cut {
                                Some((made, None)) => {
                                    let said = format!(
                                        "{}; a repair is proposed for leg `{}` (`armor ctl \
                                         status` lists the options, `armor ctl repair N` takes \
                                         one with the area)",
                                        why.0, made.shown.leg
                                    );
                                    proposal = Some(made);
                                    said
                                }
                                _ => why.0,
                            };
                            let (ok, message) =
                                crate::update::refuse(controller, &asked.label(), &why);
                            answer_update(reply.as_ref(), ok, message, || {
                                run_status(&modules, &server, Some(controller), &env, &clock)
                            });
                        }
                    }
                }
            }
        }
        let wake = controller.as_ref().and_then(Controller::next_wake);
        let timeout = if checked.is_some() {
            Duration::ZERO
        } else {
            wake.map_or(TICK, |at| {
                at.saturating_duration_since(Instant::now()).min(TICK)
            })
        };
        let event = events.recv_timeout(timeout);
        let no_event_left = matches!(event, Err(RecvTimeoutError::Timeout));
        match event {
            Ok(ServerEvent::Connected { module, pid }) => {
                tracing::debug!(module, pid, "module connected")
            }
            Ok(ServerEvent::Ready { module }) => {
                if let Some(process) = modules.get_mut(&module) {
                    process.configured = true;
                }
                if !ready.contains(&module) {
                    ready.push(module);
                }
                if !all_ready_logged && modules.keys().all(|name| ready.contains(name)) {
                    all_ready_logged = true;
                    tracing::info!(
                        elapsed_ms = (started.elapsed().as_secs_f64() * 1e4).round() / 10.0,
                        "all {} modules configured",
                        modules.len()
                    );
                }
            }
            Ok(ServerEvent::Event { module, name }) => {
                tracing::info!("event {module}.{name}");
                if let Some(progress) = &mut progress {
                    progress.on_event(&format!("{module}.{name}"));
                }
                if let Some(controller) = &mut controller {
                    controller.on_event(&format!("{module}.{name}"), &server);
                }
            }
            Ok(ServerEvent::AreaReported {
                module,
                name,
                points_m,
            }) => {
                tracing::info!("module `{module}` reports no-go area `{name}`");
                let area = crate::update::Asked::Area(crate::update::ReportedArea {
                    name,
                    points_m,
                    by: format!("module `{module}`"),
                });
                match &mut controller {
                    Some(_) if running_plan.is_some() => queued_updates.push_back((area, None)),
                    Some(controller) => {
                        crate::update::refuse(
                            controller,
                            &area.label(),
                            "this run plays a mission net, not a plan: only a plan is updated",
                        );
                    }
                    None => tracing::warn!(
                        "{}: dropped, this run has no mission to add it to",
                        area.label()
                    ),
                }
            }
            Ok(ServerEvent::Disconnected { module }) => {
                tracing::debug!(module, "module disconnected")
            }
            Ok(ServerEvent::Unresponsive { module, silent_for }) => {
                if let Some(process) = modules.get_mut(&module) {
                    tracing::error!(
                        "module `{module}` has not answered for {:.1} s (stopped or stuck): \
                         killing it",
                        silent_for.as_secs_f64()
                    );
                    process.kill();
                }
            }
            Ok(ServerEvent::Reloaded(loaded)) => {
                agent.set_acl(run_acl(&loaded.system, &observers));
                apply_reload(&mut modules, &loaded, &env, &server);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => bail!("the config server stopped"),
        }
        if no_event_left
            && let Some((update, reply)) = checked.take()
            && let (Some(controller), Some(running)) = (&mut controller, &mut running_plan)
        {
            let repair = update.is_repair();
            let (ok, mut message) = crate::update::take(
                controller,
                running,
                progress.as_mut(),
                update,
                &crate::update::Context {
                    module_path: &options.module_path,
                    server: &server,
                    start_unix_secs,
                    run_secs: clock.now_secs(),
                },
            );
            if ok {
                plan_legs = Some((running.plan.clone(), running.compiled.clone()));
                // The options were costed against the plan just replaced: a leg that still
                // holds gets them again, from the new one.
                if proposal.take().is_some() {
                    controller.set_repair(None);
                }
            }
            // A repair taken while the leg holds drives it again, from where the robot is.
            if ok
                && repair
                && let Some(retry) = crate::repair::retry_of(controller, running)
            {
                let how = reroute_retry(
                    controller,
                    running,
                    &retry,
                    progress.as_ref(),
                    (&server, &options.module_path),
                );
                let (fired, said) = controller.handle(
                    armor_protocol::Request::Fire {
                        transition: retry.clone(),
                    },
                    &server,
                );
                controller.note_repair(serde_json::json!({
                    "fired": retry,
                    "ok": fired,
                    "message": said,
                    "rerouted": how,
                }));
                message.push_str(&format!("; {said}"));
                if let Some(how) = how {
                    message.push_str(&format!(": {how}"));
                }
            }
            controller.note_demand(&server);
            answer_update(reply.as_ref(), ok, message, || {
                run_status(&modules, &server, Some(controller), &env, &clock)
            });
        }
        crate::host_run::take_notes(&env.hosts, &server);
        for module in modules.values_mut() {
            let before = module.state;
            module.supervise(&env);
            tell_health(&server, module, before);
            if before != ProcState::Failed
                && module.state == ProcState::Failed
                && let Some(controller) = &mut controller
            {
                controller.on_failed(&module.name, &server);
            }
        }
        agent.supervise();
        let finished = modules
            .values()
            .all(|module| matches!(module.state, ProcState::Exited | ProcState::Failed));
        if finished && !modules.is_empty() && controller.is_none() {
            let failed: Vec<&str> = modules
                .values()
                .filter(|module| module.state == ProcState::Failed)
                .map(|module| module.name.as_str())
                .collect();
            if failed.is_empty() {
                tracing::info!("every module has finished");
                break ExitCode::SUCCESS;
            }
            tracing::error!(?failed, "no module is left running");
            break ExitCode::FAILURE;
        }
    };
    let (extras, truth) = progress.map(Progress::finish).unzip();
    let truth = truth.flatten();
    stop_all(&mut modules, &server);
    agent.stop();
    // A rehearsal the simulator's truth contradicts has failed, whatever the robot believed.
    // Its words are the summary's last line.
    let outcome = match &truth {
        Some(verdict) if !verdict.passed => ExitCode::FAILURE,
        _ => outcome,
    };
    if let (Some(controller), Some((plan, compiled))) = (&controller, &plan_legs) {
        let legs = crate::summary::legs(
            &progress::leg_plans(plan, compiled, start_unix_secs),
            controller.first_fired(),
            controller.first_marked(),
            extras.as_deref().unwrap_or_default(),
        );
        let mut summary = format!(
            "plan `{}`, {}:\n{}",
            plan.name,
            controller.outcome().map_or("not finished", Outcome::as_str),
            crate::summary::table(&legs, truth.as_ref())
        );
        for line in crate::summary::update_lines(controller.updates()) {
            summary.push_str(&line);
            summary.push('\n');
        }
        for line in truth.iter().flat_map(crate::summary::truth_lines) {
            summary.push_str(&line);
            summary.push('\n');
        }
        console::out_line(summary.trim_end());
        if let Some(dir) = &run_folder {
            let file = dir.join(run_dir::SUMMARY);
            if let Err(err) = std::fs::write(&file, &summary) {
                tracing::error!("cannot write {}: {err}", file.display());
            }
        }
    }
    if let Some(controller) = &controller {
        let rehearsal = truth
            .as_ref()
            .zip(truth_source.as_deref())
            .map(|(verdict, source)| crate::rehearsal::report(verdict, source));
        let behaviour_changes = behaviour_changes(&server.behaviours(), &clock);
        let reports = options
            .report
            .iter()
            .cloned()
            .chain(run_folder.as_ref().map(|dir| dir.join(run_dir::REPORT)));
        for report in reports {
            match controller.write_report(&report, &behaviour_changes, rehearsal.as_ref()) {
                Ok(()) => tracing::info!(file = %report.display(), "mission report written"),
                Err(err) => tracing::error!("cannot write the report {}: {err}", report.display()),
            }
        }
    }
    if let Some(dir) = &run_folder {
        tracing::info!(
            "this run's folder: {} ({})",
            dir.display(),
            run_dir::listing(dir).join(", ")
        );
        console::close_log();
    }
    Ok(outcome)
}

/// [`crate::update::reroute_retry`] from where the run's node has the robot, on the running
/// plan's world.
fn reroute_retry(
    controller: &mut Controller,
    running: &mut crate::update::Running,
    transition: &str,
    progress: Option<&Progress>,
    (server, module_path): (&ConfigServer, &[PathBuf]),
) -> Option<String> {
    crate::update::reroute_retry(
        controller,
        running,
        transition,
        progress.and_then(Progress::robot_at),
        |running| crate::update::world_of(running, &server.loaded().system, module_path),
    )
}

/// The system's access lists (`Acl::of`), where the run's own node, an observer, may publish
/// its records of the plan updates and repairs, and nothing else.
fn run_acl(system: &armor_model::SystemConfig, observers: &[String]) -> Option<Acl> {
    let mut acl = Acl::of(system, observers)?;
    if let Some(own) = acl.modules.get_mut(progress::NODE_NAME) {
        own.publish = Some(vec![progress::UPDATES_DATA.to_owned()]);
    }
    Some(acl)
}

/// Answers a client's request with the run's status (a client gone is nothing to answer).
fn answer(
    reply: &mpsc::Sender<armor_protocol::Reply>,
    ok: bool,
    message: String,
    status: armor_protocol::Status,
) {
    let _ = reply.send(armor_protocol::Reply {
        ok,
        message,
        status: Some(status),
        files: None,
    });
}

/// Answers an update asked on the control link (`reply`); one a module asked for (an area it
/// reported) has no one to answer: the records say what became of it.
fn answer_update(
    reply: Option<&mpsc::Sender<armor_protocol::Reply>>,
    ok: bool,
    message: String,
    status: impl FnOnce() -> armor_protocol::Status,
) {
    if let Some(reply) = reply {
        answer(reply, ok, message, status());
    }
}

/// Puts on the health stream what supervising `module` changed since it was `before`: a
/// crash restarted (`restarting`) or given up (`gave_up`).
fn tell_health(server: &ConfigServer, module: &ModuleProc, before: ProcState) {
    let how = module.last_exit.as_deref().unwrap_or("ended");
    match module.state {
        ProcState::Restarting(at) if !matches!(before, ProcState::Restarting(_)) => {
            let in_ms = at.saturating_duration_since(Instant::now()).as_millis();
            server.report_health(
                &module.name,
                "restarting",
                &format!("{how}; started again in {in_ms} ms"),
            );
        }
        ProcState::Failed if before != ProcState::Failed => {
            server.report_health(&module.name, "gave_up", &format!("{how}; not restarted"));
        }
        _ => {}
    }
}

fn set_override(server: &ConfigServer, module: &str, active: Option<bool>) -> (bool, String) {
    match server.set_override(module, active) {
        Ok(()) => (
            true,
            match active {
                Some(true) => format!("`{module}` started by hand"),
                Some(false) => format!("`{module}` stopped by hand"),
                None => format!("`{module}` released"),
            },
        ),
        Err(message) => (false, message),
    }
}

/// The run's files, for a client that attaches without them ([`armor_protocol::Request::Files`]): the
/// system file and the mission (`target`, when it is not the system file itself) as they are
/// now, and the files the system's `file` parameters name, as the run found them. A file that
/// is not text (a ROS map's image) is left out. A plan is sent as it runs (`running`, the
/// updates taken so far in it), not as its file was: the studio draws the run's plan from it.
fn run_files(
    target: &Path,
    running: Option<&armor_model::plan::Plan>,
    system_file: &Path,
    server: &ConfigServer,
) -> armor_protocol::Reply {
    let read = |path: &Path| {
        std::fs::read_to_string(path)
            .map(|text| armor_protocol::FileText {
                path: path.display().to_string(),
                text,
            })
            .map_err(|err| format!("cannot read {}: {err}", path.display()))
    };
    let files = (|| {
        let system = read(system_file)?;
        let mission = match running {
            Some(plan) => Some(armor_protocol::FileText {
                path: target.display().to_string(),
                text: plan.to_xml(),
            }),
            None => (target != system_file).then(|| read(target)).transpose()?,
        };
        let loaded = server.loaded();
        let mut params = Vec::new();
        for module in &loaded.system.modules {
            let Some(description) = loaded.descriptions.get(&module.module_type) else {
                continue;
            };
            for param in &module.params {
                let names_file = description
                    .param(&param.name)
                    .is_some_and(|spec| spec.file.is_some());
                if !names_file || param.value.trim().is_empty() {
                    continue;
                }
                let path = Path::new(param.value.trim());
                match read(path) {
                    Ok(file) => params.push(armor_protocol::ParamFile {
                        module: module.name.clone(),
                        param: param.name.clone(),
                        beside: files_beside(path, &file.text),
                        file,
                    }),
                    Err(err) => tracing::debug!("not sent to the client: {err}"),
                }
            }
        }
        Ok::<_, String>(armor_protocol::RunFiles {
            system,
            mission,
            params,
            descriptions: loaded
                .descriptions
                .values()
                .map(armor_module_api::ModuleDescription::to_xml)
                .collect(),
        })
    })();
    match files {
        Ok(files) => armor_protocol::Reply {
            ok: true,
            message: format!("the run's files ({})", files.system.path),
            status: None,
            files: Some(files),
        },
        Err(message) => armor_protocol::Reply {
            ok: false,
            message,
            status: None,
            files: None,
        },
    }
}

/// The files a parameter's file names in turn: a ROS map's image (the only such file a world
/// has), read as bytes.
fn files_beside(path: &Path, text: &str) -> Vec<armor_protocol::BinaryFile> {
    use base64::Engine as _;
    let is_yaml = path
        .extension()
        .is_some_and(|extension| extension == "yaml" || extension == "yml");
    let Some(map) = is_yaml
        .then(|| armor_model::ros_map::parse_yaml(text, &path.display().to_string()).ok())
        .flatten()
    else {
        return Vec::new();
    };
    let folder = path.parent().unwrap_or_else(|| Path::new("."));
    match std::fs::read(folder.join(&map.image)) {
        Ok(bytes) => vec![armor_protocol::BinaryFile {
            name: map.image,
            base64: base64::engine::general_purpose::STANDARD.encode(bytes),
        }],
        Err(err) => {
            tracing::debug!("not sent to the client: {}: {err}", map.image);
            Vec::new()
        }
    }
}

/// The time line of behaviour states, on the run clock.
fn behaviour_changes(
    behaviours: &crate::behaviour::Behaviours,
    clock: &Clock,
) -> Vec<armor_protocol::BehaviourChange> {
    behaviours
        .changes()
        .map(|change| armor_protocol::BehaviourChange {
            run_secs: clock.at(change.at),
            module: change.module.clone(),
            state: change.state,
        })
        .collect()
}

/// The whole run as the control interface reports it.
fn run_status(
    modules: &BTreeMap<String, ModuleProc>,
    server: &ConfigServer,
    controller: Option<&Controller>,
    env: &RunEnv,
    clock: &Clock,
) -> armor_protocol::Status {
    let loaded = server.loaded();
    let activity = server.activity();
    let demand = server.demand();
    let mut stats = server.stats();
    let mut endpoints = server.endpoints();
    let behaviours = server.behaviours();
    let modules = modules
        .values()
        .map(|module| {
            let (active, manual) = activity.get(&module.name).copied().unwrap_or_default();
            let state = match module.state {
                ProcState::Running if !module.configured && module.restarts > 0 => {
                    armor_protocol::ModuleState::Restarting
                }
                ProcState::Running if !module.configured => armor_protocol::ModuleState::Starting,
                ProcState::Running if active => armor_protocol::ModuleState::Running,
                ProcState::Running => armor_protocol::ModuleState::Stopped,
                ProcState::Restarting(_) => armor_protocol::ModuleState::Crashed,
                ProcState::Failed => armor_protocol::ModuleState::Failed,
                ProcState::Exited => armor_protocol::ModuleState::Exited,
            };
            armor_protocol::ModuleStatus {
                name: module.name.clone(),
                module_type: module.module_type.clone(),
                state,
                controllable: loaded
                    .descriptions
                    .get(&module.module_type)
                    .is_some_and(|description| description.controllable),
                manual,
                pid: module.child.as_ref().and_then(ModuleChild::id),
                restarts: module.restarts,
                last_exit: module.last_exit.clone(),
                stats: stats.remove(&module.name),
                why: demand.get(&module.name).map(ToString::to_string),
                behaviour: behaviours.states().get(&module.name).copied(),
                winner: behaviours.winners().get(&module.name).cloned(),
                subsystems: loaded
                    .system
                    .subsystem_path(&module.name)
                    .into_iter()
                    .map(str::to_owned)
                    .collect(),
                host: module.host.clone(),
                endpoints: endpoints.remove(&module.name).unwrap_or_default(),
            }
        })
        .collect();
    let behaviour_changes = behaviour_changes(&behaviours, clock);
    armor_protocol::Status {
        system: loaded.system.name.clone(),
        run_secs: clock.now_secs(),
        time_scale: env.time_scale,
        agent: env.agent_addr.to_string(),
        modules,
        mission: controller.map(Controller::status),
        behaviour_changes,
    }
}

fn add_modules(modules: &mut BTreeMap<String, ModuleProc>, loaded: &Loaded, env: &RunEnv) {
    for instance in &loaded.system.modules {
        if modules.contains_key(&instance.name) {
            continue;
        }
        let mut module = ModuleProc {
            name: instance.name.clone(),
            module_type: instance.module_type.clone(),
            host: loaded
                .system
                .placement(instance)
                .map(|host| host.name.clone()),
            restart: instance.restart,
            child: None,
            state: ProcState::Restarting(Instant::now()),
            crashes: Backoff::default(),
            restarts: 0,
            configured: false,
            last_exit: None,
        };
        module.spawn(env);
        modules.insert(instance.name.clone(), module);
    }
}

/// Starts modules an edit added, stops those it removed, restarts those whose type changed.
fn apply_reload(
    modules: &mut BTreeMap<String, ModuleProc>,
    loaded: &Loaded,
    env: &RunEnv,
    server: &ConfigServer,
) {
    let wanted: BTreeMap<&str, _> = loaded
        .system
        .modules
        .iter()
        .map(|instance| (instance.name.as_str(), instance))
        .collect();
    let removed: Vec<String> = modules
        .values()
        .filter(|module| {
            wanted.get(module.name.as_str()).is_none_or(|instance| {
                instance.module_type != module.module_type
                    || loaded.system.placement(instance).map(|host| &host.name)
                        != module.host.as_ref()
            })
        })
        .map(|module| module.name.clone())
        .collect();
    for name in removed {
        if let Some(mut module) = modules.remove(&name) {
            tracing::info!(
                module = name,
                "stopping a module the edit removed or changed"
            );
            module.stop(server);
        }
    }
    for module in modules.values_mut() {
        if let Some(instance) = wanted.get(module.name.as_str()) {
            module.restart = instance.restart;
        }
    }
    add_modules(modules, loaded, env);
}

fn stop_all(modules: &mut BTreeMap<String, ModuleProc>, server: &ConfigServer) {
    for module in modules.values() {
        if module.child.is_some() {
            server.send(&module.name, &FromSupervisor::Shutdown);
        }
    }
    let mut children: Vec<(String, ModuleChild)> = modules
        .values_mut()
        .filter_map(|module| Some((module.name.clone(), module.child.take()?)))
        .collect();
    end_children(&mut children);
    tracing::info!("all modules stopped");
}

/// Waits for children to exit, then SIGTERM, then SIGKILL, so none is left behind.
fn end_children(children: &mut Vec<(String, ModuleChild)>) {
    let wait_until = |children: &mut Vec<(String, ModuleChild)>, deadline: Instant| {
        while !children.is_empty() && Instant::now() < deadline {
            children.retain_mut(|(_, child)| !matches!(child.try_wait(), Ok(Some(_))));
            if !children.is_empty() {
                std::thread::sleep(TICK);
            }
        }
    };
    wait_until(children, Instant::now() + SHUTDOWN_GRACE);
    for (name, child) in children.iter() {
        tracing::debug!(module = name, "sending SIGTERM");
        child.signal(libc::SIGTERM);
    }
    wait_until(children, Instant::now() + TERM_GRACE);
    for (name, child) in children.iter_mut() {
        tracing::warn!(module = name, "did not stop; killing it");
        child.kill_and_wait();
    }
}

fn signal(child: &Child, signal: libc::c_int) {
    if let Ok(pid) = libc::pid_t::try_from(child.id()) {
        crate::process::kill(pid, signal);
    }
}

impl ModuleProc {
    fn spawn(&mut self, env: &RunEnv) {
        if let Some(host) = &self.host {
            return self.spawn_remote(env, host.clone());
        }
        let Some(binary) = probe::find_module(&env.module_path, &self.module_type) else {
            tracing::error!(
                module = self.name,
                "no binary for module type `{}`",
                self.module_type
            );
            self.state = ProcState::Failed;
            return;
        };
        let mut command = Command::new(&binary);
        command
            .env(ENV_MODULE, &self.name)
            .env(ENV_AGENT, env.agent_addr.to_string())
            .env(ENV_SUPERVISOR, env.supervisor_addr.to_string())
            .env(ENV_EPOCH, env.epoch_ns.to_string())
            .env(ENV_TIME_SCALE, env.time_scale.to_string())
            .env_remove(ENV_RUN_DIR)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        // A module gets the key of its own name, never the secret: it can prove no other. The
        // key goes over a pipe, never in the environment, which its siblings can read.
        command.env_remove(ENV_SECRET_FILE).env_remove(ENV_ENCRYPT);
        command.env_remove(ENV_KEY_FD);
        if let Some(secret) = &env.secret
            && let Err(err) = hand_over(&mut command, &secret.module_key(&self.name).to_hex())
        {
            tracing::error!(
                module = self.name,
                "cannot hand the module its key: {err:#}"
            );
            self.state = ProcState::Failed;
            return;
        }
        if env.secret.is_some() && env.encrypt {
            command.env(ENV_ENCRYPT, "1");
        }
        if let Some(dir) = &env.run_dir {
            command.env(ENV_RUN_DIR, dir);
        }
        crate::process::die_with_parent(&mut command);
        match command.spawn() {
            Ok(mut child) => {
                tracing::info!(module = self.name, pid = child.id(), "module started");
                stream_lines(&self.name, child.stdout.take());
                stream_lines(&self.name, child.stderr.take());
                self.child = Some(ModuleChild::Local(child));
                self.state = ProcState::Running;
            }
            Err(err) => {
                tracing::error!(
                    module = self.name,
                    "cannot start {}: {err}",
                    binary.display()
                );
                self.crashed(None);
            }
        }
    }

    fn supervise(&mut self, env: &RunEnv) {
        match self.state {
            ProcState::Restarting(at) if Instant::now() >= at => {
                self.restarts += 1;
                self.spawn(env);
                return;
            }
            ProcState::Running => {}
            _ => return,
        }
        let Some(child) = &mut self.child else {
            return;
        };
        let status = match child.try_wait() {
            Ok(Some(status)) => status,
            Ok(None) => return,
            Err(err) => {
                tracing::error!(module = self.name, "cannot watch the process: {err}");
                return;
            }
        };
        let lost =
            matches!(&self.child, Some(ModuleChild::Remote(child)) if child.lost_with_host());
        self.child = None;
        if lost {
            // Not a crash of its own: it comes back when its host does.
            let host = self.host.as_deref().unwrap_or_default();
            self.last_exit = Some(format!("went with its host `{host}`"));
            self.state = ProcState::Restarting(Instant::now() + FIRST_BACKOFF);
            return;
        }
        if status.success() && self.restart != RestartPolicy::Always {
            tracing::info!(module = self.name, "module finished");
            self.state = ProcState::Exited;
        } else {
            self.crashed(Some(status));
        }
    }

    fn crashed(&mut self, status: Option<ExitStatus>) {
        let now = Instant::now();
        let how = status.map_or_else(|| "could not start".to_owned(), describe_exit);
        self.last_exit = Some(how.clone());
        if self.restart == RestartPolicy::Never {
            tracing::error!(
                module = self.name,
                "module {how}; restart policy is `never`"
            );
            self.state = ProcState::Failed;
            return;
        }
        match self.crashes.crashed(now) {
            AfterCrash::GiveUp { crashes } => {
                tracing::error!(
                    module = self.name,
                    "module {how}; {crashes} crashes within {CRASH_WINDOW:?}, giving up: module.{}.failed",
                    self.name
                );
                self.state = ProcState::Failed;
            }
            AfterCrash::RestartAt(at, backoff) => {
                tracing::warn!(
                    module = self.name,
                    "module {how}; restarting in {backoff:?}"
                );
                self.state = ProcState::Restarting(at);
            }
        }
    }

    /// Kills the module's process group at once (a module declared dead by the heartbeat);
    /// its exit is then handled as a crash, by its restart policy.
    fn kill(&mut self) {
        if let Some(child) = &self.child {
            child.kill_group();
        }
    }

    fn stop(&mut self, server: &ConfigServer) {
        server.send(&self.name, &FromSupervisor::Shutdown);
        if let Some(child) = self.child.take() {
            end_children(&mut vec![(self.name.clone(), child)]);
        }
    }

    /// Asks its host's daemon to start it, with the environment a local module gets (but no
    /// run folder: that is on this machine). While the host is away, it waits for it without
    /// counting a crash.
    fn spawn_remote(&mut self, env: &RunEnv, host: String) {
        let Some(link) = env.hosts.get(&host) else {
            tracing::error!(module = self.name, "no host `{host}` in this system");
            self.state = ProcState::Failed;
            return;
        };
        let run = crate::hosts::SpawnRun {
            agent: env.agent_addr,
            supervisor: env.supervisor_addr,
            epoch_ns: env.epoch_ns,
            time_scale: env.time_scale,
            encrypt: env.secret.is_some() && env.encrypt,
        };
        match link.spawn(&self.name, &self.module_type, &run) {
            Some(child) => {
                tracing::info!(module = self.name, host, "module started on host `{host}`");
                self.child = Some(ModuleChild::Remote(child));
                self.state = ProcState::Running;
            }
            None => {
                // Tried again soon, not counted as a restart; the host's loss was said once,
                // by its link.
                self.restarts = self.restarts.saturating_sub(1);
                self.state = ProcState::Restarting(Instant::now() + Duration::from_millis(250));
            }
        }
    }
}

fn describe_exit(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt as _;
    match (status.code(), status.signal()) {
        (Some(code), _) => format!("exited with status {code}"),
        (None, Some(signal)) => format!("was killed by signal {signal}"),
        (None, None) => "ended".to_owned(),
    }
}

/// Copies a child's output to ours, one line at a time, each prefixed with `[name] `.
fn stream_lines(name: &str, pipe: Option<impl Read + Send + 'static>) {
    let Some(pipe) = pipe else {
        return;
    };
    let prefix = format!("[{name}] ");
    crate::log_pump::pump_lines(pipe, move |line| {
        console::out_line(&format!("{prefix}{line}"));
    });
}

/// The agent, run as its own process so that it can die (and be restarted on the same address)
/// without taking anything else down.
struct AgentProc {
    addr: SocketAddr,
    child: Option<Child>,
    restart_at: Option<Instant>,
    backoff: Duration,
    secret: Option<Secret>,
    acl: Option<Acl>,
}

impl AgentProc {
    fn start(addr: SocketAddr, secret: Option<Secret>, acl: Option<Acl>) -> anyhow::Result<Self> {
        let (child, addr) = spawn_agent(addr, secret.as_ref(), acl.as_ref())?;
        Ok(Self {
            addr,
            child: Some(child),
            restart_at: None,
            backoff: FIRST_BACKOFF,
            secret,
            acl,
        })
    }

    /// A new access list (an edit of the system file): the agent restarts with it. Links keep
    /// flowing meanwhile, and modules register again.
    fn set_acl(&mut self, acl: Option<Acl>) {
        if acl == self.acl {
            return;
        }
        tracing::info!("the access lists changed: restarting the agent with them");
        self.acl = acl;
        if let Some(child) = &self.child {
            signal(child, libc::SIGTERM);
        }
    }

    fn supervise(&mut self) {
        if let Some(child) = &mut self.child {
            if let Ok(Some(status)) = child.try_wait() {
                tracing::warn!(
                    addr = %self.addr,
                    "agent {}; links keep flowing, restarting it in {:?}",
                    describe_exit(status),
                    self.backoff
                );
                self.child = None;
                self.restart_at = Some(Instant::now() + self.backoff);
            }
            return;
        }
        if self.restart_at.is_some_and(|at| Instant::now() >= at) {
            match spawn_agent(self.addr, self.secret.as_ref(), self.acl.as_ref()) {
                Ok((child, _)) => {
                    self.child = Some(child);
                    self.restart_at = None;
                    self.backoff = FIRST_BACKOFF;
                }
                Err(err) => {
                    self.backoff = (self.backoff * 2).min(MAX_BACKOFF);
                    tracing::warn!(
                        "cannot restart the agent: {err:#}; retrying in {:?}",
                        self.backoff
                    );
                    self.restart_at = Some(Instant::now() + self.backoff);
                }
            }
        }
    }

    fn stop(&mut self) {
        if let Some(child) = self.child.take() {
            signal(&child, libc::SIGTERM);
            end_children(&mut vec![("agent".to_owned(), ModuleChild::Local(child))]);
        }
    }
}

/// Gives a child the run's secret over a pipe (see [`hand_over`]), or makes sure it has none;
/// never the secret file's path, which its siblings could read in its environment.
fn pass_secret(command: &mut Command, secret: Option<&Secret>) -> std::io::Result<()> {
    command.env_remove(ENV_SECRET_FILE).env_remove(ENV_KEY_FD);
    match secret {
        Some(secret) => hand_over(command, &secret.to_hex()),
        None => Ok(()),
    }
}

/// Starts `armor agent` and reads the address it reports listening on.
fn spawn_agent(
    addr: SocketAddr,
    secret: Option<&Secret>,
    acl: Option<&Acl>,
) -> anyhow::Result<(Child, SocketAddr)> {
    let exe = std::env::current_exe().context("cannot find the armor executable")?;
    let mut command = Command::new(exe);
    command
        .args(["agent", "--listen", &addr.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    pass_secret(&mut command, secret).context("cannot hand the agent the secret")?;
    match acl {
        Some(acl) => command.env(ENV_ACL, serde_json::to_string(acl)?),
        None => command.env_remove(ENV_ACL),
    };
    crate::process::die_with_parent(&mut command);
    let mut child = command.spawn().context("cannot start the agent")?;
    stream_lines("agent", child.stderr.take());
    let stdout = child.stdout.take().context("agent has no stdout")?;
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(stdout).lines();
        let _ = tx.send(lines.next());
        // Keep draining so the agent never blocks on a full pipe.
        for _ in lines {}
    });
    let line = match rx.recv_timeout(AGENT_START_TIMEOUT) {
        Ok(Some(Ok(line))) => line,
        _ => {
            let _ = child.kill();
            let _ = child.wait();
            bail!("the agent did not report its address (is {addr} in use?)");
        }
    };
    let addr = line
        .strip_prefix(crate::AGENT_READY_PREFIX)
        .and_then(|addr| addr.trim().parse().ok())
        .with_context(|| format!("unexpected first line from the agent: `{line}`"))?;
    tracing::info!(pid = child.id(), %addr, "agent started");
    Ok((child, addr))
}

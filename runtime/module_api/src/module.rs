//! Declaring a module ([`ModuleSpec`]) and running it ([`run`]): describe mode, logging, and the
//! connection to the supervisor and the agent.

use std::io::Write as _;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use crate::clock::Clock;
use crate::core::{ApiError, Core, check_param};
use crate::describe::{Category, EventSpec, ModuleDescription, ParamSpec, PortSpec};
use crate::net::Net;
use crate::node::{Node, Transport};
use crate::protocol::{FromSupervisor, ModuleConfig, ToSupervisor};
use crate::types::Datum;
use crate::wire::blocking;

pub const ENV_MODULE: &str = "ARMOR_MODULE";
pub const ENV_AGENT: &str = "ARMOR_AGENT";
pub const ENV_SUPERVISOR: &str = "ARMOR_SUPERVISOR";
/// The folder of the run a module is part of (`armor run` makes one per run): where the files
/// it writes under relative names go (see [`output_path`]).
pub const ENV_RUN_DIR: &str = "ARMOR_RUN_DIR";
/// Where a module looks for the agent when nothing says otherwise.
pub const DEFAULT_AGENT: &str = "127.0.0.1:7400";
/// How long a module started under a supervisor tries to reach it before giving up.
const SUPERVISOR_PATIENCE: Duration = Duration::from_secs(10);

/// Where a module writes a file its parameters name: a relative `file` goes into the run's
/// folder when it has one (`ARMOR_RUN_DIR`), else it is taken from the current folder.
pub fn output_path(file: &std::path::Path) -> std::path::PathBuf {
    match std::env::var_os(ENV_RUN_DIR) {
        Some(dir) if file.is_relative() && !dir.is_empty() => std::path::Path::new(&dir).join(file),
        _ => file.to_path_buf(),
    }
}

/// What a module declares about itself: its ports, parameters and events.
#[derive(Clone, Debug)]
pub struct ModuleSpec {
    description: ModuleDescription,
}

impl ModuleSpec {
    pub fn new(module_type: &str, doc: &str) -> Self {
        Self {
            description: ModuleDescription::new(module_type, doc),
        }
    }

    pub fn version(mut self, version: &str) -> Self {
        self.description.version = version.to_owned();
        self
    }

    pub fn input<T: Datum>(mut self, name: &str, doc: &str) -> Self {
        self.description.inputs.push(port::<T>(name, doc));
        self
    }

    pub fn output<T: Datum>(mut self, name: &str, doc: &str) -> Self {
        self.description.outputs.push(port::<T>(name, doc));
        self
    }

    pub fn param(mut self, param: ParamSpec) -> Self {
        self.description.params.push(param);
        self
    }

    pub fn event(mut self, name: &str, doc: &str) -> Self {
        self.description.events.push(EventSpec {
            name: name.to_owned(),
            doc: doc.to_owned(),
        });
        self
    }

    /// An operator interface or safety module: the mission controller never stops it.
    pub fn not_controllable(mut self) -> Self {
        self.description.controllable = false;
        self
    }

    /// Its role, which tools show (the studio colours its blocks' headers by it).
    pub fn category(mut self, category: Category) -> Self {
        self.description.category = category;
        self
    }

    pub fn description(&self) -> &ModuleDescription {
        &self.description
    }
}

fn port<T: Datum>(name: &str, doc: &str) -> PortSpec {
    PortSpec {
        name: name.to_owned(),
        data_type: T::TYPE.to_owned(),
        doc: doc.to_owned(),
    }
}

/// The body of a module: it gets the connected node and returns when the module should exit.
pub type BodyResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;

const USAGE: &str = "\
usage: armor-mod-TYPE [--describe] [--name NAME] [--agent HOST:PORT] [--host ADDR] [--param NAME=VALUE]... [--bind INPUT=MODULE.OUTPUT]...

Run by `armor run`, a module takes everything from its supervisor. Run by hand, it takes its
instance name, parameters and input links from these options, finds the agent at --agent,
$ARMOR_AGENT, or 127.0.0.1:7400, and accepts subscribers on --host (127.0.0.1 by default).";

/// Settings of a module run without a supervisor (from the command line, or a benchmark or tool
/// that hosts a module in its own process). Unset fields come from the environment.
#[derive(Clone, Debug, Default)]
pub struct Standalone {
    /// Instance name; else `$ARMOR_MODULE`, else the module type.
    pub name: Option<String>,
    /// Agent address; else `$ARMOR_AGENT`, else [`DEFAULT_AGENT`].
    pub agent: Option<String>,
    /// Parameter values (`name`, `value`), checked against the declared types.
    pub params: Vec<(String, String)>,
    /// Input links (`input`, `module.output`).
    pub binds: Vec<(String, String)>,
    /// The address subscribers reach this node on (`--host`); 127.0.0.1 when `None`.
    pub host: Option<String>,
    /// The shared secret's file, for a run started with `armor run --secret` (the node
    /// proves the key of its name, derived from it); else the key behind `$ARMOR_KEY_FD`, else
    /// `$ARMOR_SECRET_FILE`, else none.
    pub secret: Option<std::path::PathBuf>,
    /// Encrypt every link (`armor run --encrypt`); also set by `ARMOR_ENCRYPT=1`.
    pub encrypt: bool,
}

/// Runs a module: answers `--describe`, sets up logging, connects, and runs `body`.
pub fn run(spec: ModuleSpec, body: impl FnOnce(&mut Node) -> BodyResult) -> ExitCode {
    // Before anything holds a key: a sibling of the same user must not read this process's
    // memory (see `hardening`).
    crate::hardening::make_non_dumpable();
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|arg| arg == "--describe") {
        let mut stdout = std::io::stdout().lock();
        return match stdout.write_all(spec.description.to_xml().as_bytes()) {
            Ok(()) => ExitCode::SUCCESS,
            Err(_) => ExitCode::FAILURE,
        };
    }
    if args.iter().any(|arg| arg == "--help" || arg == "-h") {
        println!("{}\n\n{USAGE}", spec.description.doc);
        return ExitCode::SUCCESS;
    }
    let options = match parse_options(&args) {
        Ok(options) => options,
        Err(message) => {
            eprintln!("error: {message}\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    init_logging();
    crate::memory::keep_freed_heap();
    let mut node = match connect(spec, options) {
        Ok(node) => node,
        Err(err) => {
            tracing::error!("cannot start: {err:#}");
            return ExitCode::FAILURE;
        }
    };
    match body(&mut node) {
        Ok(()) => {
            let _ = node.flush();
            ExitCode::SUCCESS
        }
        Err(err) => {
            tracing::error!("module failed: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Logs go to stderr without timestamps or colour: `armor run` prefixes each line with the
/// module's name. `ARMOR_LOG` (or `RUST_LOG`) sets the filter, `info` by default.
pub fn init_logging() {
    let filter = std::env::var("ARMOR_LOG")
        .or_else(|_| std::env::var("RUST_LOG"))
        .unwrap_or_else(|_| "info".to_owned());
    let _ = tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(filter))
        .with_writer(std::io::stderr)
        .with_ansi(false)
        .without_time()
        .with_target(false)
        .try_init();
}

fn parse_options(args: &[String]) -> Result<Standalone, String> {
    let mut options = Standalone::default();
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        let mut value = |flag: &str| {
            args.next()
                .cloned()
                .ok_or_else(|| format!("{flag} needs a value"))
        };
        let pair = |text: String, flag: &str| {
            text.split_once('=')
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .ok_or_else(|| format!("{flag} expects NAME=VALUE, not `{text}`"))
        };
        match arg.as_str() {
            "--name" => options.name = Some(value("--name")?),
            "--agent" => options.agent = Some(value("--agent")?),
            "--param" => options.params.push(pair(value("--param")?, "--param")?),
            "--bind" => options.binds.push(pair(value("--bind")?, "--bind")?),
            "--host" => options.host = Some(value("--host")?),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    Ok(options)
}

fn resolve(addr: &str) -> Result<SocketAddr, ApiError> {
    addr.to_socket_addrs()?.next().ok_or_else(|| {
        ApiError::Io(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("no address for `{addr}`"),
        ))
    })
}

fn connect(spec: ModuleSpec, options: Standalone) -> Result<Node, ApiError> {
    let description = spec.description;
    let name = options
        .name
        .or_else(|| std::env::var(ENV_MODULE).ok())
        .unwrap_or_else(|| description.module_type.clone());
    let agent = options
        .agent
        .or_else(|| std::env::var(ENV_AGENT).ok())
        .unwrap_or_else(|| DEFAULT_AGENT.to_owned());
    let agent = resolve(&agent)?;
    let clock = Clock::from_env();
    let credentials =
        crate::auth::Credentials::for_module(&name, options.secret.as_deref(), options.encrypt)?;
    let (config, supervisor) = match std::env::var(ENV_SUPERVISOR) {
        Ok(addr) => {
            let addr = resolve(&addr)?;
            let (config, kept, stream) = configure(&name, addr, credentials.as_ref())?;
            (config, Some((addr, stream, kept)))
        }
        Err(_) => (
            {
                let mut config =
                    standalone_config(&name, &description, options.params, options.binds)?;
                if let Some(host) = options.host {
                    config.host = host;
                }
                config
            },
            None,
        ),
    };
    let mut core = Core::new(name, description, config, clock);
    let supervisor = supervisor.map(|(addr, stream, kept)| {
        core.kept = kept;
        (addr, stream)
    });
    let net = Net::start(&mut core, agent, supervisor, credentials)?;
    let mut node = Node::from_parts(core, Transport::Net(Box::new(net)));
    if let Transport::Net(net) = &mut node.transport {
        net.tell_supervisor(&ToSupervisor::Ready);
    }
    tracing::debug!(module = node.name(), "configured");
    Ok(node)
}

impl Node {
    /// Connects a module hosted in this process, as `run` does for a module binary: under the
    /// supervisor named by `$ARMOR_SUPERVISOR` if set, else standalone with `options`.
    /// The process gets the heap policy of a module process too ([`crate::memory`]).
    pub fn connect(spec: ModuleSpec, options: Standalone) -> Result<Node, ApiError> {
        crate::memory::keep_freed_heap();
        connect(spec, options)
    }
}

/// Greets the supervisor and waits for this module's configuration ("wait for all parameters"),
/// and what an earlier process of this module kept, if it did (it comes before the
/// configuration).
fn configure(
    name: &str,
    addr: SocketAddr,
    credentials: Option<&crate::auth::Credentials>,
) -> Result<(ModuleConfig, Option<String>, blocking::SecureStream), ApiError> {
    let started = Instant::now();
    let stream = loop {
        match TcpStream::connect_timeout(&addr, Duration::from_secs(1)) {
            Ok(stream) => break stream,
            Err(_) if started.elapsed() < SUPERVISOR_PATIENCE => {
                std::thread::sleep(Duration::from_millis(50))
            }
            Err(_) => {
                return Err(ApiError::NoSupervisor {
                    addr: addr.to_string(),
                    waited_secs: started.elapsed().as_secs_f64(),
                });
            }
        }
    };
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(SUPERVISOR_PATIENCE))?;
    let dial = credentials.map(|credentials| credentials.dial(name));
    let mut stream = blocking::dial(stream, dial.as_ref())?;
    blocking::write_message(
        &mut stream,
        &ToSupervisor::Hello {
            module: name.to_owned(),
            pid: std::process::id(),
        },
    )?;
    let mut kept = None;
    loop {
        match blocking::read_message::<FromSupervisor>(&mut stream)? {
            FromSupervisor::Config(config) => {
                stream.get_ref().set_read_timeout(None)?;
                return Ok((config, kept, stream));
            }
            FromSupervisor::Kept { state } => kept = Some(state),
            FromSupervisor::Error { message } => return Err(ApiError::Refused(message)),
            other => tracing::debug!(?other, "ignored before configuration"),
        }
    }
}

fn standalone_config(
    name: &str,
    description: &ModuleDescription,
    params: Vec<(String, String)>,
    binds: Vec<(String, String)>,
) -> Result<ModuleConfig, ApiError> {
    let mut config = ModuleConfig {
        module_type: description.module_type.clone(),
        active: true,
        host: "127.0.0.1".to_owned(),
        ..ModuleConfig::default()
    };
    for param in &description.params {
        if let Some(default) = &param.default {
            config.params.insert(param.name.clone(), default.clone());
        }
    }
    for (param_name, value) in params {
        let spec = description
            .param(&param_name)
            .ok_or_else(|| ApiError::UnknownParam(param_name.clone()))?;
        check_param(spec, &value)?;
        config.params.insert(param_name, value);
    }
    for (input, data_name) in binds {
        if description.input(&input).is_none() {
            return Err(ApiError::UnknownPort {
                module: name.to_owned(),
                kind: "input",
                port: input,
            });
        }
        config.inputs.insert(input, data_name);
    }
    for output in &description.outputs {
        config
            .outputs
            .insert(output.name.clone(), format!("{name}.{}", output.name));
    }
    Ok(config)
}

/// The configuration a module gets when no configuration file names it otherwise: parameter
/// defaults, outputs named `name.output`, no inputs linked, active.
pub fn default_config(name: &str, description: &ModuleDescription) -> ModuleConfig {
    standalone_config(name, description, Vec::new(), Vec::new()).unwrap_or_default()
}

//! The central agent: a name server that answers "who serves this datum, at which address".
//!
//! It never carries data: modules connect to each other directly, so links keep flowing when the
//! agent dies. A registration lives as long as the module's connection to the agent: when a
//! module dies its entries go with it, and when the agent restarts, modules register again.
//!
//! **A data name belongs to one module**: `module.output` to `module` ([`owner`]), unless the
//! system grants it to another with an explicit `may_publish`. With a secret or an [`Acl`], the
//! agent registers a data name only for its owner, so a module that races another's restart
//! cannot take its names (`mux.cmd_vel` would let it drive).
//!
//! With an [`Acl`] (the system's `may_publish` and `may_subscribe` lists), the agent serves only
//! the system's modules: it refuses a registration of a data name the module may not publish,
//! and a lookup of one it may not subscribe to. Without a secret, names are the modules' own
//! word and the lists guard against mistakes only. With a secret, a connection proves the name
//! it claims in the handshake (its module key), registers only as that name, and each
//! `provider` answer carries the link key with which the asker, and it alone, gets into that
//! provider's data port: a module can reach no data port the lists do not give it. The link key
//! is derived from the key of the data name's owner, not of whoever registered it: a
//! subscriber sent to another module's port fails the handshake there.

use std::collections::{BTreeMap, HashMap};
use std::net::{SocketAddr, TcpListener};
use std::sync::{Arc, Mutex, PoisonError};

use armor_module_api::auth::{Admit, Listen, Role, Secret};
use armor_module_api::protocol::{Advert, FromAgent, ToAgent};
use armor_module_api::wire::blocking::{SecureStream, SecureWriter};
use armor_module_api::wire::{WireError, blocking};

/// The environment variable that carries the [`Acl`] (JSON) to `armor agent`.
pub const ENV_ACL: &str = "ARMOR_ACL";

/// What each module of the system may publish and subscribe to (`None`: no limit).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Acl {
    pub modules: BTreeMap<String, Permissions>,
}

#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Permissions {
    pub publish: Option<Vec<String>>,
    pub subscribe: Option<Vec<String>>,
}

impl Acl {
    /// The system's lists, or `None` when no module has one (then the agent serves anyone).
    /// Each of `observers` (a name outside the system, like the studio's node) may subscribe
    /// to everything and publish nothing; a module of the system keeps its own lists.
    pub fn of(system: &armor_model::SystemConfig, observers: &[String]) -> Option<Acl> {
        let limited = system
            .modules
            .iter()
            .any(|module| module.may_publish.is_some() || module.may_subscribe.is_some());
        limited.then(|| Acl {
            modules: system
                .modules
                .iter()
                .map(|module| {
                    (
                        module.name.clone(),
                        Permissions {
                            publish: module.may_publish.clone(),
                            subscribe: module.may_subscribe.clone(),
                        },
                    )
                })
                .chain(
                    observers
                        .iter()
                        .filter(|name| system.module(name).is_none())
                        .map(|name| {
                            (
                                name.clone(),
                                Permissions {
                                    publish: Some(Vec::new()),
                                    subscribe: None,
                                },
                            )
                        }),
                )
                .collect(),
        })
    }

    /// The ACL in `ARMOR_ACL`, if set and not empty.
    pub fn from_env() -> Result<Option<Acl>, serde_json::Error> {
        match std::env::var(ENV_ACL) {
            Ok(text) if !text.trim().is_empty() => serde_json::from_str(&text).map(Some),
            _ => Ok(None),
        }
    }

    fn check_publish(&self, module: &str, data_name: &str) -> Result<(), Refusal> {
        let permissions = self.permissions(module)?;
        let listed = match &permissions.publish {
            Some(patterns) => armor_model::system::allowed(Some(patterns), data_name),
            None => true,
        };
        if listed && owner(Some(self), data_name) == module {
            Ok(())
        } else {
            Err(Refusal::MayNotPublish {
                module: module.to_owned(),
                data_name: data_name.to_owned(),
            })
        }
    }

    fn check_subscribe(&self, module: Option<&str>, data_name: &str) -> Result<(), Refusal> {
        let module = module.ok_or(Refusal::NotRegistered)?;
        let permissions = self.permissions(module)?;
        if armor_model::system::allowed(permissions.subscribe.as_deref(), data_name) {
            Ok(())
        } else {
            Err(Refusal::MayNotSubscribe {
                module: module.to_owned(),
                data_name: data_name.to_owned(),
            })
        }
    }

    fn permissions(&self, module: &str) -> Result<&Permissions, Refusal> {
        self.modules
            .get(module)
            .ok_or_else(|| Refusal::UnknownModule(module.to_owned()))
    }
}

/// Why the access lists refuse a module's registration or lookup: its text is what the module
/// is told.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    #[error("register before looking a provider up")]
    NotRegistered,
    #[error("no module `{0}` in this system")]
    UnknownModule(String),
    #[error("module `{module}` may not publish `{data_name}`")]
    MayNotPublish { module: String, data_name: String },
    #[error("module `{module}` may not subscribe to `{data_name}`")]
    MayNotSubscribe { module: String, data_name: String },
}

/// The module a data name belongs to: the first module of the system (in `acl`) whose explicit
/// `may_publish` grants it, else the module its name starts with (`module.output`).
pub fn owner<'a>(acl: Option<&'a Acl>, data_name: &'a str) -> &'a str {
    let granted = acl.and_then(|acl| {
        acl.modules.iter().find_map(|(module, permissions)| {
            let patterns = permissions.publish.as_deref()?;
            // A module's own names are its own by default: a list naming them grants nothing.
            (!data_name.starts_with(&format!("{module}."))
                && armor_model::system::allowed(Some(patterns), data_name))
            .then_some(module.as_str())
        })
    });
    granted.unwrap_or_else(|| {
        data_name
            .split_once('.')
            .map_or(data_name, |(module, _)| module)
    })
}

/// Whether `module` may register `data_name` with no access list: with a secret, only names it
/// owns; without one, names are the modules' own word.
fn owns_by_default(secret: Option<&Secret>, module: &str, data_name: &str) -> bool {
    secret.is_none() || owner(None, data_name) == module
}

struct Entry {
    advert: Advert,
    module: String,
    conn_id: u64,
}

/// The writing half of a connection, shared by its own thread (replies) and by the threads of
/// registering modules (providers pushed to those who asked in vain).
type Writer = Arc<Mutex<SecureWriter>>;

/// A connection that asked for a data name not served yet.
struct Asker {
    conn_id: u64,
    writer: Writer,
    /// Its proven name, with a secret.
    identity: Option<String>,
}

#[derive(Default)]
struct Registry {
    by_data_name: HashMap<String, Entry>,
    next_conn_id: u64,
    /// Data names asked for and not yet served, with the connections that asked.
    waiting: HashMap<String, Vec<Asker>>,
}

fn write(writer: &Writer, message: &FromAgent) -> Result<(), WireError> {
    let mut stream = writer.lock().unwrap_or_else(PoisonError::into_inner);
    blocking::write_message(&mut *stream, message)
}

/// Serves agent connections until the process ends, one thread each once open; with a
/// `secret`, only peers that prove a module key, on encrypted links; with an `acl`, only within
/// it.
pub fn serve(listener: TcpListener, secret: Option<Secret>, acl: Option<Acl>) {
    let registry = Arc::new(Mutex::new(Registry::default()));
    let acl = acl.map(Arc::new);
    // The agent's answers carry link keys: its links are always encrypted.
    let listen = secret.clone().map(|secret| Listen {
        admit: Admit::Agent(secret),
        encrypt: true,
    });
    let open = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    crate::gate::serve_requests(listener, listen, MAX_REQUEST_BYTES, |stream, identity| {
        use std::sync::atomic::Ordering;
        // Each open connection has a thread: without a secret, whoever says hello is one, so
        // their number is bounded.
        if open.load(Ordering::Relaxed) >= MAX_CONNECTIONS {
            tracing::warn!("{MAX_CONNECTIONS} connections open: refused another");
            return;
        }
        open.fetch_add(1, Ordering::Relaxed);
        let open = Arc::clone(&open);
        let registry = Arc::clone(&registry);
        let secret = secret.clone();
        let acl = acl.clone();
        let conn_id = {
            let mut registry = registry.lock().unwrap_or_else(PoisonError::into_inner);
            registry.next_conn_id += 1;
            registry.next_conn_id
        };
        std::thread::spawn(move || {
            let peer = stream.get_ref().peer_addr().ok();
            let conn = Conn {
                registry: &registry,
                conn_id,
                secret: secret.as_ref(),
                acl: acl.as_deref(),
            };
            if let Err(err) = conn.serve(stream, identity) {
                match err {
                    WireError::Closed => {}
                    err => tracing::warn!(?peer, "dropped a connection: {err}"),
                }
            }
            forget(&registry, conn_id);
            open.fetch_sub(1, Ordering::Relaxed);
        });
    });
}

/// The most connections the agent serves at once (one per module, and the studio's).
const MAX_CONNECTIONS: usize = 1024;

/// Starts an agent on a thread of this process (for benchmarks and tests).
pub fn spawn(addr: SocketAddr) -> std::io::Result<SocketAddr> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    std::thread::spawn(move || serve(listener, None, None));
    Ok(local)
}

/// Starts an agent with a secret on a thread of this process (for benchmarks and tests).
pub fn spawn_with(addr: SocketAddr, secret: Option<Secret>) -> std::io::Result<SocketAddr> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    std::thread::spawn(move || serve(listener, secret, None));
    Ok(local)
}

fn forget(registry: &Mutex<Registry>, conn_id: u64) {
    let mut registry = registry.lock().unwrap_or_else(PoisonError::into_inner);
    for askers in registry.waiting.values_mut() {
        askers.retain(|asker| asker.conn_id != conn_id);
    }
    registry.waiting.retain(|_, askers| !askers.is_empty());
    registry.by_data_name.retain(|data_name, entry| {
        let gone = entry.conn_id == conn_id;
        if gone {
            tracing::info!(data_name, module = entry.module, "provider unregistered");
        }
        !gone
    });
}

/// One open connection's service.
struct Conn<'a> {
    registry: &'a Mutex<Registry>,
    conn_id: u64,
    secret: Option<&'a Secret>,
    acl: Option<&'a Acl>,
}

impl Conn<'_> {
    /// `advert` as told to `asker`: with a secret, with the link key of the asker's proven name
    /// for the data port of the data name's owner (whoever registered it).
    fn for_asker(&self, advert: &Advert, asker: Option<&str>) -> Advert {
        let key = match (self.secret, asker) {
            (Some(secret), Some(asker)) => Some(
                secret
                    .module_key(owner(self.acl, &advert.data_name))
                    .link_key(asker)
                    .to_hex(),
            ),
            _ => None,
        };
        Advert {
            key,
            ..advert.clone()
        }
    }

    fn serve(&self, stream: SecureStream, proven: Option<String>) -> Result<(), WireError> {
        let Conn {
            registry,
            conn_id,
            acl,
            ..
        } = *self;
        stream.get_ref().set_nodelay(true)?;
        let (mut stream, writer) = stream.split();
        let writer: Writer = Arc::new(Mutex::new(writer));
        // The module this connection registered as; with a secret, the name it proved.
        let mut identity: Option<String> = proven.clone();
        // With a secret, a role's key holder (an attached studio, say) proves its role's reader
        // name: it may look any data name up, and register none.
        let reader = proven.as_deref().and_then(Role::of_data_identity);
        loop {
            let reply =
                match blocking::read_message_at_most::<ToAgent>(&mut stream, MAX_REQUEST_BYTES)? {
                    ToAgent::Lookup { data_name } if data_name.len() > MAX_NAME_BYTES => {
                        FromAgent::Error {
                            message: format!(
                                "a data name of {} bytes: at most {MAX_NAME_BYTES}",
                                data_name.len()
                            ),
                        }
                    }
                    ToAgent::Lookup { .. } if waits_of(registry, conn_id) >= MAX_WAITS => {
                        FromAgent::Error {
                            message: format!(
                                "this connection already waits for {MAX_WAITS} data names"
                            ),
                        }
                    }
                    ToAgent::Register { module, .. }
                        if proven.as_ref().is_some_and(|proven| *proven != module) =>
                    {
                        let message = format!(
                            "this connection proved to be `{}`: it may not register as `{module}`",
                            proven.as_deref().unwrap_or_default()
                        );
                        tracing::warn!("refused a registration: {message}");
                        FromAgent::Error { message }
                    }
                    ToAgent::Register { outputs, .. } if let Some(role) = reader => {
                        if outputs.is_empty() {
                            FromAgent::Registered
                        } else {
                            let message = format!(
                                "an {}'s key reads the run's data: it publishes none",
                                role.as_str()
                            );
                            tracing::warn!("refused a registration: {message}");
                            FromAgent::Error { message }
                        }
                    }
                    ToAgent::Register { module, outputs }
                        if module.len() > MAX_NAME_BYTES
                            || outputs
                                .iter()
                                .any(|advert| advert.data_name.len() > MAX_NAME_BYTES) =>
                    {
                        FromAgent::Error {
                            message: format!("a name longer than {MAX_NAME_BYTES} bytes"),
                        }
                    }
                    ToAgent::Register { module, outputs } => {
                        let refused = match acl {
                            Some(acl) => outputs
                                .iter()
                                .find_map(|advert| {
                                    acl.check_publish(&module, &advert.data_name).err()
                                })
                                .or_else(|| acl.permissions(&module).err())
                                .map(|refusal| refusal.to_string()),
                            None => outputs
                                .iter()
                                .find(|advert| {
                                    !owns_by_default(self.secret, &module, &advert.data_name)
                                })
                                .map(|advert| {
                                    format!(
                                        "module `{module}` may not publish `{}`: a module \
                                         publishes its own names (`{module}.*`)",
                                        advert.data_name
                                    )
                                }),
                        };
                        match refused {
                            Some(message) => {
                                tracing::warn!(module, "refused a registration: {message}");
                                FromAgent::Error { message }
                            }
                            None => {
                                identity = Some(module.clone());
                                let (reply, pushes) =
                                    register(registry, conn_id, module.clone(), outputs);
                                for (asker, advert) in pushes {
                                    let advert = self.for_asker(&advert, asker.identity.as_deref());
                                    // An asker that went away is forgotten by its own thread.
                                    let _ = write(&asker.writer, &FromAgent::Provider(advert));
                                }
                                reply
                            }
                        }
                    }
                    ToAgent::Lookup { data_name }
                        if reader.is_none()
                            && let Some(Err(message)) = acl.map(|acl| {
                                acl.check_subscribe(identity.as_deref(), &data_name)
                            }) =>
                    {
                        tracing::warn!(module = identity.as_deref(), "refused a lookup: {message}");
                        FromAgent::Error {
                            message: message.to_string(),
                        }
                    }
                    ToAgent::Lookup { data_name } => {
                        let mut registry = registry.lock().unwrap_or_else(PoisonError::into_inner);
                        match registry.by_data_name.get(&data_name) {
                            Some(entry) => FromAgent::Provider(
                                self.for_asker(&entry.advert, identity.as_deref()),
                            ),
                            None => {
                                let askers = registry.waiting.entry(data_name.clone()).or_default();
                                if !askers.iter().any(|asker| asker.conn_id == conn_id) {
                                    askers.push(Asker {
                                        conn_id,
                                        writer: Arc::clone(&writer),
                                        identity: identity.clone(),
                                    });
                                }
                                FromAgent::Unknown { data_name }
                            }
                        }
                    }
                };
            write(&writer, &reply)?;
        }
    }
}

/// The longest request the agent reads (a registration lists a module's outputs).
const MAX_REQUEST_BYTES: usize = 1024 * 1024;
/// The longest data name looked up or registered.
const MAX_NAME_BYTES: usize = 256;
/// The most data names one connection may wait for (names no module serves yet).
const MAX_WAITS: usize = 1024;

/// How many data names connection `conn_id` waits for.
fn waits_of(registry: &Mutex<Registry>, conn_id: u64) -> usize {
    let registry = registry.lock().unwrap_or_else(PoisonError::into_inner);
    registry
        .waiting
        .values()
        .filter(|askers| askers.iter().any(|asker| asker.conn_id == conn_id))
        .count()
}

/// Registers `outputs`; the reply, and the providers to push to those who asked for them.
fn register(
    registry: &Mutex<Registry>,
    conn_id: u64,
    module: String,
    outputs: Vec<Advert>,
) -> (FromAgent, Vec<(Asker, Advert)>) {
    let mut registry = registry.lock().unwrap_or_else(PoisonError::into_inner);
    // A data name belongs to one module. The same module registering again (it restarted before
    // its old connection was noticed closed) takes it over; another module may not.
    if let Some(clash) = outputs.iter().find_map(|advert| {
        registry
            .by_data_name
            .get(&advert.data_name)
            .filter(|entry| entry.conn_id != conn_id && entry.module != module)
            .map(|entry| (advert.data_name.clone(), entry.module.clone()))
    }) {
        let (data_name, owner) = clash;
        tracing::warn!(module, data_name, owner, "refused a registration");
        let message = format!("`{data_name}` is already served by module `{owner}`");
        return (FromAgent::Error { message }, Vec::new());
    }
    registry
        .by_data_name
        .retain(|_, entry| entry.conn_id != conn_id);
    let mut pushes = Vec::new();
    for advert in outputs {
        tracing::info!(
            data_name = advert.data_name,
            addr = advert.addr,
            module,
            "provider registered"
        );
        for asker in registry
            .waiting
            .remove(&advert.data_name)
            .unwrap_or_default()
        {
            pushes.push((asker, advert.clone()));
        }
        registry.by_data_name.insert(
            advert.data_name.clone(),
            Entry {
                advert,
                module: module.clone(),
                conn_id,
            },
        );
    }
    (FromAgent::Registered, pushes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn acl(grants: &[(&str, Option<&str>)]) -> Acl {
        Acl {
            modules: grants
                .iter()
                .map(|(module, publish)| {
                    (
                        (*module).to_owned(),
                        Permissions {
                            publish: publish
                                .map(|list| list.split_whitespace().map(str::to_owned).collect()),
                            subscribe: None,
                        },
                    )
                })
                .collect(),
        }
    }

    #[test]
    fn a_name_belongs_to_its_module_unless_the_system_grants_it() {
        assert_eq!(owner(None, "mux.cmd_vel"), "mux");
        assert_eq!(owner(None, "nodot"), "nodot");
        let acl = acl(&[
            ("replay", Some("sim.*")),
            ("sim", None),
            ("nav", Some("nav.*")),
        ]);
        assert_eq!(owner(Some(&acl), "sim.odometry"), "replay");
        assert_eq!(owner(Some(&acl), "nav.cmd"), "nav");
        assert!(acl.check_publish("replay", "sim.odometry").is_ok());
        // The grant takes the name from its module; a module may not publish another's.
        assert!(acl.check_publish("sim", "sim.odometry").is_err());
        assert!(acl.check_publish("nav", "mux.cmd_vel").is_err());
        // Without a list, a module publishes its own names only.
        let open = acl_without_lists();
        assert!(open.check_publish("sim", "sim.odometry").is_ok());
        assert!(open.check_publish("sim", "mux.cmd_vel").is_err());
        // Without a list and without a secret, names are the modules' word.
        assert!(owns_by_default(None, "rogue", "counter.count"));
        let secret = Secret::from_bytes(&[7; 32]);
        assert!(!owns_by_default(Some(&secret), "rogue", "counter.count"));
        assert!(owns_by_default(Some(&secret), "counter", "counter.count"));
    }

    fn acl_without_lists() -> Acl {
        acl(&[("sim", None), ("mux", None)])
    }
}

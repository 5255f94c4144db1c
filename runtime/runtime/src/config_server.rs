//! The config server: each module connects to it at start, says who it is, and gets its port
//! bindings and parameters. The same connection carries control (start, stop, shutdown) to the
//! module and event reports back.
//!
//! It watches the system file (its parent folder, since editors save by renaming a new file over
//! the old) and reloads it on change: a valid edit reaches every module whose configuration it
//! changes; an invalid one is reported with `FILE:LINE:COL` and the last good one stays in force.

use std::collections::HashMap;
use std::io::Write as _;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use armor_module_api::protocol::{FromSupervisor, ModuleConfig, ToSupervisor};
use armor_module_api::wire::{WireError, blocking};
use notify::{RecursiveMode, Watcher as _};

use crate::load::{Loaded, load_system};

const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// Editors write a file in several steps; wait for this much quiet before reloading.
const SETTLE: Duration = Duration::from_millis(50);

/// What the config server tells the supervisor.
#[derive(Debug)]
pub enum ServerEvent {
    /// A module connected and got its configuration.
    Connected {
        module: String,
        pid: u32,
    },
    Ready {
        module: String,
    },
    Event {
        module: String,
        name: String,
    },
    Disconnected {
        module: String,
    },
    /// A valid edit of the system file is now in force.
    Reloaded(Arc<Loaded>),
}

struct ModuleConn {
    conn_id: u64,
    writer: TcpStream,
    sent: ModuleConfig,
}

struct State {
    loaded: Arc<Loaded>,
    conns: HashMap<String, ModuleConn>,
    next_conn_id: u64,
}

#[derive(Clone)]
pub struct ConfigServer {
    state: Arc<Mutex<State>>,
    events: Sender<ServerEvent>,
    addr: SocketAddr,
}

impl ConfigServer {
    /// Listens on `addr` and serves `loaded` until the process ends.
    pub fn start(
        addr: SocketAddr,
        loaded: Loaded,
    ) -> std::io::Result<(Self, Receiver<ServerEvent>)> {
        let listener = TcpListener::bind(addr)?;
        let (events, receiver) = mpsc::channel();
        let server = Self {
            state: Arc::new(Mutex::new(State {
                loaded: Arc::new(loaded),
                conns: HashMap::new(),
                next_conn_id: 0,
            })),
            events,
            addr: listener.local_addr()?,
        };
        let accepting = server.clone();
        std::thread::spawn(move || accepting.accept_loop(listener));
        Ok((server, receiver))
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn loaded(&self) -> Arc<Loaded> {
        Arc::clone(&self.lock().loaded)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Sends a control message to a connected module. Returns whether it was connected.
    pub fn send(&self, module: &str, message: &FromSupervisor) -> bool {
        let mut state = self.lock();
        let Some(conn) = state.conns.get_mut(module) else {
            return false;
        };
        blocking::write_message(&mut conn.writer, message).is_ok()
    }

    fn accept_loop(&self, listener: TcpListener) {
        for stream in listener.incoming() {
            match stream {
                Ok(stream) => {
                    let server = self.clone();
                    std::thread::spawn(move || server.serve(stream));
                }
                Err(err) => tracing::warn!("config server: accept failed: {err}"),
            }
        }
    }

    fn serve(&self, mut stream: TcpStream) {
        let peer = stream.peer_addr().ok();
        let conn_id = {
            let mut state = self.lock();
            state.next_conn_id += 1;
            state.next_conn_id
        };
        let mut module = None;
        if let Err(err) = self.serve_module(&mut stream, conn_id, &mut module) {
            match err {
                WireError::Closed => {}
                err => tracing::warn!(?peer, ?module, "config server dropped a connection: {err}"),
            }
        }
        if let Some(module) = module {
            let mut state = self.lock();
            if state
                .conns
                .get(&module)
                .is_some_and(|conn| conn.conn_id == conn_id)
            {
                state.conns.remove(&module);
                drop(state);
                let _ = self.events.send(ServerEvent::Disconnected { module });
            }
        }
    }

    fn serve_module(
        &self,
        stream: &mut TcpStream,
        conn_id: u64,
        module: &mut Option<String>,
    ) -> Result<(), WireError> {
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
        blocking::read_hello(stream)?;
        blocking::write_hello(stream)?;
        let ToSupervisor::Hello { module: name, pid } = blocking::read_message(stream)? else {
            let message = "the first message must be `hello`".to_owned();
            blocking::write_message(stream, &FromSupervisor::Error { message })?;
            return Ok(());
        };
        stream.set_read_timeout(None)?;
        {
            let mut state = self.lock();
            let config = state
                .loaded
                .system
                .module(&name)
                .and_then(|instance| state.loaded.module_config(instance));
            let Some(config) = config else {
                drop(state);
                let message = format!("no module `{name}` in this system");
                tracing::warn!("{message}");
                blocking::write_message(stream, &FromSupervisor::Error { message })?;
                return Ok(());
            };
            blocking::write_message(stream, &FromSupervisor::Config(config.clone()))?;
            state.conns.insert(
                name.clone(),
                ModuleConn {
                    conn_id,
                    writer: stream.try_clone()?,
                    sent: config,
                },
            );
        }
        *module = Some(name.clone());
        let _ = self.events.send(ServerEvent::Connected {
            module: name.clone(),
            pid,
        });
        loop {
            let event = match blocking::read_message::<ToSupervisor>(stream)? {
                ToSupervisor::Ready => ServerEvent::Ready {
                    module: name.clone(),
                },
                ToSupervisor::Event { name: event } => ServerEvent::Event {
                    module: name.clone(),
                    name: event,
                },
                ToSupervisor::Pong | ToSupervisor::Hello { .. } => continue,
            };
            let _ = self.events.send(event);
        }
    }

    /// Puts a newly loaded system in force and sends each connected module its new
    /// configuration if it changed.
    pub fn apply(&self, loaded: Loaded) {
        let loaded = Arc::new(loaded);
        let mut state = self.lock();
        state.loaded = Arc::clone(&loaded);
        let mut updated = Vec::new();
        for (name, conn) in &mut state.conns {
            let Some(config) = loaded
                .system
                .module(name)
                .and_then(|instance| loaded.module_config(instance))
            else {
                continue;
            };
            if config != conn.sent {
                if blocking::write_message(
                    &mut conn.writer,
                    &FromSupervisor::Config(config.clone()),
                )
                .is_ok()
                {
                    let _ = conn.writer.flush();
                    updated.push(name.clone());
                }
                conn.sent = config;
            }
        }
        drop(state);
        if !updated.is_empty() {
            updated.sort();
            tracing::info!(modules = ?updated, "sent new configuration");
        }
        let _ = self.events.send(ServerEvent::Reloaded(loaded));
    }

    /// Watches `file` and reloads it on every change, until the process ends.
    pub fn watch(&self, file: &Path, module_path: Vec<PathBuf>) -> notify::Result<()> {
        let file = std::path::absolute(file)?;
        let folder = file
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("/"));
        let (tx, rx) = mpsc::channel();
        let mut watcher =
            notify::recommended_watcher(move |event: notify::Result<notify::Event>| {
                let _ = tx.send(event);
            })?;
        watcher.watch(&folder, RecursiveMode::NonRecursive)?;
        let server = self.clone();
        std::thread::spawn(move || {
            // The watcher lives as long as this thread.
            let _watcher = watcher;
            server.reload_loop(&file, &module_path, &rx);
        });
        Ok(())
    }

    fn reload_loop(
        &self,
        file: &Path,
        module_path: &[PathBuf],
        events: &Receiver<notify::Result<notify::Event>>,
    ) {
        let file_name = file.file_name();
        // Reading the file ourselves makes access events: only changes count.
        let concerns_file = |event: &notify::Result<notify::Event>| match event {
            Ok(event) => {
                !matches!(event.kind, notify::EventKind::Access(_))
                    && event.paths.iter().any(|path| path.file_name() == file_name)
            }
            Err(err) => {
                tracing::warn!("file watcher: {err}");
                false
            }
        };
        while let Ok(event) = events.recv() {
            if !concerns_file(&event) {
                continue;
            }
            // Let the editor finish writing: wait until no change has come for a moment.
            loop {
                match events.recv_timeout(SETTLE) {
                    Ok(event) if concerns_file(&event) => {}
                    Ok(_) => {}
                    Err(RecvTimeoutError::Timeout) => break,
                    Err(RecvTimeoutError::Disconnected) => return,
                }
            }
            if !file.exists() {
                tracing::warn!(file = %file.display(), "the system file is gone; the last good configuration stays in force");
                continue;
            }
            match load_system(file, module_path) {
                Ok(loaded) => {
                    if loaded.system == self.loaded().system {
                        continue;
                    }
                    tracing::info!(file = %file.display(), "configuration reloaded");
                    self.apply(loaded);
                }
                Err(diagnostics) => {
                    tracing::error!(
                        "the edited system file is invalid; the last good configuration stays in force:\n{diagnostics}"
                    );
                }
            }
        }
    }
}

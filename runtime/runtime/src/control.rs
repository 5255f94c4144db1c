//! The operator's hold on a run (adjustable autonomy): ask for the state of every module and of
//! the mission, start and stop modules by hand, and pause, resume, abort a mission or fire a
//! transition by hand. `armor run` serves it on a TCP port; `armor ctl` and the studio's run
//! view are its clients, through `armor_protocol::Client`; the requests and replies are
//! `armor_protocol`'s.
//!
//! `teleop` is relayed to the run's teleop module (see `crate::teleop_relay`) and answered
//! with the module's own answer; `files` returns what a client that attaches without the
//! system file needs to draw the run (`armor_protocol::RunFiles`).
//!
//! Room for the operator: an open client has a thread, and at most [`MAX_CLIENTS`] are open.
//! With a secret only key holders get that far; while the table is full, a new operator closes
//! the observer idle the longest (so observers' keys cannot shut the operator out), and
//! anyone else is refused (an operator is never closed to make room). Without a secret every
//! client is equal (the port is the local machine's), so a full table makes room as OpenSSH's
//! `MaxStartups` and a web server's keep-alive do: a new client closes the one that has been
//! waiting on its peer the longest (idle since its last reply, or not reading that reply),
//! which is first told why in a reply to its next request number. A client whose request the
//! run is answering is never closed. We keep a thread per open client rather than one event
//! loop for all of them: the table bounds the threads, each client's code stays a plain loop
//! of blocking reads and writes, and the gate already keeps strangers from ever reaching it.

use std::collections::HashMap;
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use armor_module_api::auth::{Admit, Listen, Role, Secret};
use armor_module_api::wire::WireError;
use armor_module_api::wire::blocking::{self, SecureStream, SecureWriter};
use armor_protocol::frame::read_bounded;
use armor_protocol::{FromRun, REPLY_TIMEOUT, Reply, Request, ToRun, allowed};

/// A request longer than this is not a request.
const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// A request from a client, with where to send the answer.
pub type Incoming = (Request, Sender<Reply>);

/// The most control connections open at once. Connections still in their handshake are the
/// gate's, bounded there.
const MAX_CLIENTS: usize = 64;
/// An open connection that sends nothing for this long is closed (the studio polls twice a
/// second; `armor ctl` sends at once).
const IDLE_TIMEOUT: Duration = Duration::from_secs(60);
/// A reply the client does not take for this long (the socket's buffers full, nothing moving)
/// closes the connection: an honest client reads its reply at once, and a slow link still
/// moves some bytes every few seconds.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// The word a closed client gets is tried for this long only: a client that does not read
/// must not keep a thread for it.
const FAREWELL_TIMEOUT: Duration = Duration::from_secs(1);

/// Serves the control interface on `addr`, handing each request to `requests`. With a
/// `secret`, the link is a Noise transport like the data links: through the run's gate
/// ([`crate::gate`]: no thread and not a byte for a stranger, a deadline on the whole
/// handshake), encrypted, and only for clients that prove the key of a role (operator or
/// observer, [`Secret::role_key`]); an observer's commands are refused.
pub fn serve(
    addr: SocketAddr,
    requests: Sender<Incoming>,
    secret: Option<Secret>,
) -> std::io::Result<SocketAddr> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    // Without a secret, the table makes room for a new client by closing the one idle the
    // longest; with one, it refuses the new client (see the module's doc).
    let make_room = secret.is_none();
    let listen = secret.map(|secret| Listen {
        admit: Admit::Control {
            operator: secret.role_key(Role::Operator),
            observer: secret.role_key(Role::Observer),
        },
        encrypt: true,
    });
    let clients = Arc::new(Clients::default());
    std::thread::spawn(move || {
        crate::gate::serve_requests(
            listener,
            listen,
            MAX_REQUEST_BYTES,
            move |stream, proven| {
                // Without a secret there is no role to prove: whoever reaches the (loopback)
                // port operates.
                let role = match proven.as_deref().map(Role::parse) {
                    None => Role::Operator,
                    Some(Some(role)) => role,
                    Some(None) => return,
                };
                let socket = match stream.get_ref().try_clone() {
                    Ok(socket) => socket,
                    Err(err) => {
                        tracing::warn!("cannot keep a control client: {err}");
                        return;
                    }
                };
                let Some(id) = clients.admit(socket, role, make_room) else {
                    tracing::warn!("{MAX_CLIENTS} control clients are connected: refused another");
                    return;
                };
                let requests = requests.clone();
                let clients = Arc::clone(&clients);
                std::thread::spawn(move || {
                    if let Err(err) = serve_client(stream, role, &requests, &clients, id) {
                        tracing::warn!("control client ({}): {err:#}", role.as_str());
                    }
                    clients.leave(id);
                });
            },
        );
    });
    Ok(local)
}

/// What an open client's thread is doing, for [`Clients::admit`] to choose whom to close.
#[derive(Clone, Copy, PartialEq)]
enum Doing {
    /// Waiting for the client's next request.
    Reading,
    /// The run is at work on a request: never closed.
    Answering,
    /// Writing a reply the client may not be reading.
    Writing,
}

struct Client {
    /// The connection's socket, to wake its thread and close it.
    socket: TcpStream,
    role: Role,
    doing: Doing,
    /// Since when the client has been idle: its last reply, or its connect.
    idle_since: Instant,
}

/// The open clients. One that is no longer in the table while its thread runs was closed to
/// make room.
#[derive(Default)]
struct Clients {
    table: Mutex<Table>,
}

#[derive(Default)]
struct Table {
    open: HashMap<u64, Client>,
    next_id: u64,
}

impl Clients {
    fn table(&self) -> std::sync::MutexGuard<'_, Table> {
        self.table.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Takes a new client in. When the table is full, closes first the client that has waited
    /// on its peer the longest among those it may replace: anyone with `make_room` (no
    /// secret), an observer for an operator. `None` when there is no room.
    fn admit(&self, socket: TcpStream, role: Role, make_room: bool) -> Option<u64> {
        let mut table = self.table();
        if table.open.len() >= MAX_CLIENTS {
            let replaceable = |client: &Client| {
                client.doing != Doing::Answering
                    && (make_room || (role == Role::Operator && client.role == Role::Observer))
            };
            let oldest = table
                .open
                .iter()
                .filter(|(_, client)| replaceable(client))
                .min_by_key(|(_, client)| client.idle_since)
                .map(|(&id, _)| id)?;
            if let Some(client) = table.open.remove(&oldest) {
                tracing::info!(
                    peer = ?client.socket.peer_addr().ok(),
                    idle_secs = client.idle_since.elapsed().as_secs_f64(),
                    "{MAX_CLIENTS} control clients are connected: closed the one idle the longest"
                );
                // A thread waiting for a request wakes to an end of input and says why it
                // closes; one blocked on a reply its client does not read stops at once.
                let how = match client.doing {
                    Doing::Reading => Shutdown::Read,
                    _ => Shutdown::Both,
                };
                let _ = client.socket.shutdown(how);
            }
        }
        table.next_id += 1;
        let id = table.next_id;
        table.open.insert(
            id,
            Client {
                socket,
                role,
                doing: Doing::Reading,
                idle_since: Instant::now(),
            },
        );
        Some(id)
    }

    /// Notes what client `id` now does; `false` when it was closed to make room.
    fn now(&self, id: u64, doing: Doing) -> bool {
        let mut table = self.table();
        let Some(client) = table.open.get_mut(&id) else {
            return false;
        };
        if doing == Doing::Reading {
            client.idle_since = Instant::now();
        }
        client.doing = doing;
        true
    }

    fn leave(&self, id: u64) {
        self.table().open.remove(&id);
    }
}

fn serve_client(
    stream: SecureStream,
    role: Role,
    requests: &Sender<Incoming>,
    clients: &Clients,
    id: u64,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    stream.get_ref().set_read_timeout(Some(IDLE_TIMEOUT))?;
    stream.get_ref().set_write_timeout(Some(WRITE_TIMEOUT))?;
    stream.get_ref().set_nodelay(true)?;
    let (mut reader, mut writer) = stream.split();
    let mut expected = 1;
    loop {
        let message: ToRun = match read_bounded(&mut reader, MAX_REQUEST_BYTES) {
            Ok(message) => message,
            Err(_) if !clients.now(id, Doing::Reading) => {
                return farewell(&mut writer, expected);
            }
            Err(WireError::Closed) => return Ok(()),
            Err(err) => return Err(err).context("bad request"),
        };
        if message.seq != expected {
            anyhow::bail!(
                "request numbered {} where {expected} was due: replayed, reordered or dropped on the way",
                message.seq
            );
        }
        expected += 1;
        if !clients.now(id, Doing::Answering) {
            return farewell(&mut writer, message.seq);
        }
        let reply = if allowed(role, &message.request) {
            let (tx, rx) = mpsc::channel();
            if requests.send((message.request, tx)).is_err() {
                return Ok(());
            }
            rx.recv_timeout(REPLY_TIMEOUT)
                .unwrap_or_else(|_| refusal("the run did not answer"))
        } else {
            refusal(
                "refused: an observer's key may read the run, not command it (give an operator's key)",
            )
        };
        // A client that is answering is never closed to make room: it still has its place.
        clients.now(id, Doing::Writing);
        let written = blocking::write_message(
            &mut writer,
            &FromRun {
                seq: message.seq,
                reply,
            },
        );
        if !clients.now(id, Doing::Reading) {
            return farewell(&mut writer, expected);
        }
        written?;
    }
}

fn refusal(message: &str) -> Reply {
    Reply {
        ok: false,
        message: message.to_owned(),
        status: None,
        files: None,
    }
}

/// Tells a client closed to make room why, as the reply to its request numbered `seq` (the one
/// it sent, or the next it will send), and closes its connection.
fn farewell(writer: &mut SecureWriter, seq: u64) -> anyhow::Result<()> {
    writer.get_ref().set_write_timeout(Some(FAREWELL_TIMEOUT))?;
    let reply = refusal(&format!(
        "closed: this connection was the one idle the longest when {MAX_CLIENTS} control \
         clients were connected and another came; connect again"
    ));
    // A client that reads nothing does not hear it; it is closed all the same.
    let _ = blocking::write_message(writer, &FromRun { seq, reply });
    let _ = writer.get_ref().shutdown(Shutdown::Both);
    Ok(())
}

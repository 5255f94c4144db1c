//! The operator's hold on a run (adjustable autonomy): ask for the state of every module and of
//! the mission, start and stop modules by hand, and pause, resume, abort a mission or fire a
//! transition by hand. `armor run` serves it on a TCP port; `armor ctl` and the studio's run
//! view are its clients, through `armor_protocol::Client`; the requests and replies are
//! `armor_protocol`'s.
//!
//! `teleop` is relayed to the run's teleop module (see `crate::teleop_relay`) and answered
//! with the module's own answer; `files` returns what a client that attaches without the
//! system file needs to draw the run (`armor_protocol::RunFiles`).

use std::net::{SocketAddr, TcpListener};
use std::sync::mpsc::{self, Sender};
use std::time::Duration;

use armor_module_api::auth::{Admit, Listen, Role, Secret};
use armor_module_api::wire::WireError;
use armor_module_api::wire::blocking::{self, SecureStream};
use armor_protocol::frame::read_bounded;
use armor_protocol::{FromRun, REPLY_TIMEOUT, Reply, Request, ToRun, allowed};

/// A request longer than this is not a request.
const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// A request from a client, with where to send the answer.
pub type Incoming = (Request, Sender<Reply>);

/// The most control connections open at once (authenticated, with a secret); more are closed
/// at once. Connections still in their handshake are the gate's, bounded there.
const MAX_CLIENTS: usize = 64;
/// An open connection that sends nothing for this long is closed (the studio polls twice a
/// second; `armor ctl` sends at once).
const IDLE_TIMEOUT: Duration = Duration::from_secs(60);

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
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    let listen = secret.map(|secret| Listen {
        admit: Admit::Control {
            operator: secret.role_key(Role::Operator),
            observer: secret.role_key(Role::Observer),
        },
        encrypt: true,
    });
    let open = Arc::new(AtomicUsize::new(0));
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
                if open.load(Ordering::Relaxed) >= MAX_CLIENTS {
                    tracing::warn!("{MAX_CLIENTS} control clients are connected: refused another");
                    return;
                }
                open.fetch_add(1, Ordering::Relaxed);
                let requests = requests.clone();
                let open = Arc::clone(&open);
                std::thread::spawn(move || {
                    if let Err(err) = serve_client(stream, role, &requests) {
                        tracing::warn!("control client ({}): {err:#}", role.as_str());
                    }
                    open.fetch_sub(1, Ordering::Relaxed);
                });
            },
        );
    });
    Ok(local)
}

fn serve_client(
    stream: SecureStream,
    role: Role,
    requests: &Sender<Incoming>,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    stream.get_ref().set_read_timeout(Some(IDLE_TIMEOUT))?;
    stream.get_ref().set_nodelay(true)?;
    let (mut reader, mut writer) = stream.split();
    let mut expected = 1;
    loop {
        let message: ToRun = match read_bounded(&mut reader, MAX_REQUEST_BYTES) {
            Ok(message) => message,
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
        let reply = if allowed(role, &message.request) {
            let (tx, rx) = mpsc::channel();
            if requests.send((message.request, tx)).is_err() {
                return Ok(());
            }
            rx.recv_timeout(REPLY_TIMEOUT).unwrap_or_else(|_| Reply {
                ok: false,
                message: "the run did not answer".to_owned(),
                status: None,
                files: None,
            })
        } else {
            Reply {
                ok: false,
                message: "refused: an observer's key may read the run, not command it (give an operator's key)".to_owned(),
                status: None,
                files: None,
            }
        };
        blocking::write_message(
            &mut writer,
            &FromRun {
                seq: message.seq,
                reply,
            },
        )?;
    }
}

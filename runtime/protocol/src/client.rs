//! A client of the control interface.

use std::net::{SocketAddr, TcpStream};

use armor_module_api::auth::{Dial, Role, RoleKey, Secret};
use armor_module_api::wire::blocking::{self, SecureReader, SecureStream, SecureWriter};
use armor_module_api::wire::{MAX_FRAME_BYTES, WireError};

use crate::frame::{closed, read_bounded};
use crate::{FromRun, REPLY_TIMEOUT, Reply, Request, ToRun};

/// Why a request to a run got no reply. Printed with its causes (`{err:#}`), it tells the user
/// what to do.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("cannot reach the run's control interface at {addr}")]
    Unreachable {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("the run refused the handshake: it holds another secret, or runs without one")]
    Refused,
    #[error("cannot open the control link at {addr} (is it a run's?)")]
    Handshake {
        addr: SocketAddr,
        #[source]
        source: WireError,
    },
    #[error(
        "the run closed the connection without a word: it requires the shared secret (armor ctl --secret FILE, or --key FILE)"
    )]
    SecretRequired,
    #[error("no reply from the run")]
    NoReply(#[source] WireError),
    #[error("the run answered request {answered} where {due} was due: the link was tampered with")]
    OutOfStep { answered: u64, due: u64 },
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Wire(#[from] WireError),
}

/// The key a control client proves, from a file: a role's key (`armor secret derive`), or the
/// run's secret itself, which acts as the operator.
pub fn key_from_file(
    path: &std::path::Path,
) -> Result<RoleKey, armor_module_api::auth::SecretError> {
    match RoleKey::load(path) {
        Ok(key) => Ok(key),
        Err(armor_module_api::auth::SecretError::BadRoleKey { .. }) => {
            Secret::load(path).map(|secret| RoleKey {
                role: Role::Operator,
                key: secret.role_key(Role::Operator),
            })
        }
        Err(err) => Err(err),
    }
}

/// Sends one request to a run's control interface and returns its reply; with a `secret`, first
/// proves it (and checks the run's proof).
pub fn request(
    addr: SocketAddr,
    request: &Request,
    secret: Option<&Secret>,
) -> Result<Reply, ClientError> {
    Client::connect(addr, secret)?.call(request)
}

/// A connection to a run's control interface, kept for many requests (authenticated once): the
/// studio's polls and the operator's driving commands, ten a second, need not each pay for a
/// connection and a handshake.
pub struct Client {
    reader: SecureReader,
    writer: SecureWriter,
    role: Option<Role>,
    seq: u64,
    /// The run's hello has not been read yet (a client without a key).
    hello_due: bool,
}

fn dial_role(dial: &Dial) -> Role {
    Role::parse(&dial.identity).unwrap_or(Role::Operator)
}

impl Client {
    /// Connects to the control interface at `addr`; with a `secret`, as the operator.
    pub fn connect(addr: SocketAddr, secret: Option<&Secret>) -> Result<Client, ClientError> {
        let key = secret.map(|secret| RoleKey {
            role: Role::Operator,
            key: secret.role_key(Role::Operator),
        });
        Client::connect_with(addr, key.as_ref())
    }

    /// Connects to the control interface at `addr`; with a role's `key`, proves it (and checks
    /// the run's proof) and encrypts the link.
    pub fn connect_with(addr: SocketAddr, key: Option<&RoleKey>) -> Result<Client, ClientError> {
        let stream = TcpStream::connect_timeout(&addr, REPLY_TIMEOUT)
            .map_err(|source| ClientError::Unreachable { addr, source })?;
        stream.set_read_timeout(Some(REPLY_TIMEOUT * 2))?;
        stream.set_nodelay(true)?;
        let dial = key.map(|key| Dial {
            key: key.key.clone(),
            identity: key.role.as_str().to_owned(),
            encrypt: true,
        });
        // Without a key the run's hello is read with the first reply: a run that requires a
        // key sends nothing and closes at once, which the first call reports.
        let Some(dial) = dial else {
            blocking::write_hello(&mut &stream)?;
            let (reader, writer) = SecureStream::plain(stream)?.split();
            return Ok(Client {
                reader,
                writer,
                role: None,
                seq: 0,
                hello_due: true,
            });
        };
        let stream = match blocking::dial(stream, Some(&dial)) {
            Ok(stream) => stream,
            Err(WireError::HandshakeRefused(_)) => return Err(ClientError::Refused),
            Err(source) => return Err(ClientError::Handshake { addr, source }),
        };
        let (reader, writer) = stream.split();
        Ok(Client {
            reader,
            writer,
            role: Some(dial_role(&dial)),
            seq: 0,
            hello_due: false,
        })
    }

    /// The role this client proved, `None` without a secret (then it may do anything).
    pub fn role(&self) -> Option<Role> {
        self.role
    }

    /// Sends one request and waits for its reply. After an error the connection is in an
    /// unknown state: connect again.
    pub fn call(&mut self, request: &Request) -> Result<Reply, ClientError> {
        self.seq += 1;
        blocking::write_message(
            &mut self.writer,
            &ToRun {
                seq: self.seq,
                request: request.clone(),
            },
        )?;
        let hello = if std::mem::take(&mut self.hello_due) {
            blocking::read_hello(&mut self.reader)
        } else {
            Ok(())
        };
        let answer =
            hello.and_then(|()| read_bounded::<FromRun>(&mut self.reader, MAX_FRAME_BYTES));
        let answer = match answer {
            Ok(answer) => answer,
            Err(err) if self.role.is_none() && self.seq == 1 && closed(&err) => {
                return Err(ClientError::SecretRequired);
            }
            Err(err) => return Err(ClientError::NoReply(err)),
        };
        if answer.seq != self.seq {
            return Err(ClientError::OutOfStep {
                answered: answer.seq,
                due: self.seq,
            });
        }
        Ok(answer.reply)
    }
}

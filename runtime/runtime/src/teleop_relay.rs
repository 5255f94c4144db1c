//! The operator's driving commands (`armor ctl teleop`, the studio's drive pad), relayed from
//! the control interface to the run's teleop module: the supervisor keeps one connection open to
//! the module's command port (the `teleop` endpoint the module says it listens at, section 4.2
//! of `docs/protocol.md`), follows the module when it comes back on another port, and answers
//! each request with the module's own answer (`ok`, `error: …`).
//!
//! The relay is a thread of its own, so that a teleop module that is slow to answer never holds
//! up the supervisor's loop; the control client waits for its reply as for any other.
//!
//! Which module is driven, and whether it can be, is decided by the supervisor's loop from its
//! process table and the config server's endpoints ([`target`]); this thread only talks.

use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::Duration;

use armor_module_api::auth::{Dial, Secret};
use armor_module_api::wire::blocking::{self, SecureStream};

use armor_protocol::{Reply, TELEOP_ENDPOINT, TELEOP_TYPE};

/// How long the module may take to accept a connection, and to answer a command (it answers
/// within a tick of its loop, 50 ms of run time).
const TIMEOUT: Duration = Duration::from_secs(2);
/// The longest answer line read from the module.
const MAX_ANSWER_BYTES: u64 = 1024;

/// One command for the module at `addr`, and where to send the reply.
pub struct Command {
    pub module: String,
    pub addr: SocketAddr,
    pub linear: f64,
    pub angular: f64,
    pub reply: Sender<Reply>,
}

/// A module of the run as the relay's choice needs it.
pub struct Candidate<'a> {
    pub name: &'a str,
    pub module_type: &'a str,
    /// Configured and at work.
    pub up: bool,
}

/// Why an operator's driving command finds no teleop module to go to, in the operator's words.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum NoTarget {
    #[error("this run has no teleop module `{0}`")]
    NoSuchModule(String),
    #[error("this run has no teleop module (type `teleop`)")]
    NoTeleop,
    #[error("this run has several teleop modules ({}): say which", .0.join(", "))]
    Several(Vec<String>),
    #[error("the teleop module `{0}` is not up (starting, restarting or failed)")]
    NotUp(String),
    #[error("the teleop module `{0}` has not said where it listens yet")]
    NoAddress(String),
    #[error("the teleop module `{module}` listens at `{address}`, which is not an address")]
    BadAddress { module: String, address: String },
}

/// The teleop module to drive and its command port: `wanted` by name, else the only module of
/// type `teleop`; why not when there is none, it is not up, or it has not said where it
/// listens.
pub fn target<'a>(
    modules: impl IntoIterator<Item = Candidate<'a>>,
    endpoints: &HashMap<String, BTreeMap<String, String>>,
    wanted: Option<&str>,
) -> Result<(String, SocketAddr), NoTarget> {
    let mut teleops: Vec<Candidate<'a>> = modules
        .into_iter()
        .filter(|module| module.module_type == TELEOP_TYPE)
        .collect();
    let chosen = match wanted {
        Some(wanted) => teleops
            .into_iter()
            .find(|module| module.name == wanted)
            .ok_or_else(|| NoTarget::NoSuchModule(wanted.to_owned()))?,
        None if teleops.len() > 1 => {
            return Err(NoTarget::Several(
                teleops
                    .iter()
                    .map(|module| module.name.to_owned())
                    .collect(),
            ));
        }
        None => teleops.pop().ok_or(NoTarget::NoTeleop)?,
    };
    if !chosen.up {
        return Err(NoTarget::NotUp(chosen.name.to_owned()));
    }
    let address = endpoints
        .get(chosen.name)
        .and_then(|endpoints| endpoints.get(TELEOP_ENDPOINT))
        .ok_or_else(|| NoTarget::NoAddress(chosen.name.to_owned()))?;
    let addr = address.parse().map_err(|_| NoTarget::BadAddress {
        module: chosen.name.to_owned(),
        address: address.clone(),
    })?;
    Ok((chosen.name.to_owned(), addr))
}

/// Starts the relay's thread; it ends when the sender is dropped. With the run's `secret`, the
/// relay proves the link key of each teleop module's key (identity
/// [`crate::host::SUPERVISOR_IDENTITY`]) and the link is encrypted, as the module requires.
pub fn start(secret: Option<Secret>) -> Sender<Command> {
    let (commands, receiver) = mpsc::channel();
    std::thread::spawn(move || relay(&receiver, secret.as_ref()));
    commands
}

/// The connection to the module's command port, and where it goes.
struct Link {
    addr: SocketAddr,
    conn: Conn,
}

enum Conn {
    /// Without a secret: lines in the clear.
    Lines {
        reader: BufReader<TcpStream>,
        writer: TcpStream,
    },
    /// With a secret: the wire protocol over Noise, a JSON string per frame.
    Secure(SecureStream),
}

impl Link {
    fn open(addr: SocketAddr, module: &str, secret: Option<&Secret>) -> std::io::Result<Link> {
        let stream = TcpStream::connect_timeout(&addr, TIMEOUT)?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(TIMEOUT))?;
        let conn = match secret {
            Some(secret) => {
                let dial = Dial {
                    key: secret
                        .module_key(module)
                        .link_key(crate::host::SUPERVISOR_IDENTITY),
                    identity: crate::host::SUPERVISOR_IDENTITY.to_owned(),
                    encrypt: true,
                };
                Conn::Secure(blocking::dial(stream, Some(&dial)).map_err(std::io::Error::other)?)
            }
            None => {
                let writer = stream.try_clone()?;
                Conn::Lines {
                    reader: BufReader::new(stream),
                    writer,
                }
            }
        };
        Ok(Link { addr, conn })
    }

    /// Sends one command line and reads the module's answer.
    fn send(&mut self, line: &str) -> std::io::Result<String> {
        let (reader, writer) = match &mut self.conn {
            Conn::Lines { reader, writer } => (reader, writer),
            Conn::Secure(stream) => {
                blocking::write_message(stream, &line.trim()).map_err(std::io::Error::other)?;
                let answer: String =
                    blocking::read_message(stream).map_err(std::io::Error::other)?;
                return Ok(answer.trim().to_owned());
            }
        };
        writer.write_all(line.as_bytes())?;
        let mut answer = String::new();
        if reader.take(MAX_ANSWER_BYTES).read_line(&mut answer)? == 0 {
            return Err(std::io::Error::other("the module closed the connection"));
        }
        Ok(answer.trim().to_owned())
    }
}

/// The module's command line for a request: `stop` for zero speeds.
fn command_line(linear: f64, angular: f64) -> String {
    if linear == 0.0 && angular == 0.0 {
        "stop\n".to_owned()
    } else {
        format!("v {linear} {angular}\n")
    }
}

fn relay(commands: &Receiver<Command>, secret: Option<&Secret>) {
    let mut link: Option<Link> = None;
    while let Ok(command) = commands.recv() {
        let line = command_line(command.linear, command.angular);
        // A module restarted on another port: follow it. A connection that fails is opened
        // again once, for a module restarted on the same port.
        if link.as_ref().is_some_and(|link| link.addr != command.addr) {
            link = None;
        }
        let mut answer = Err(std::io::Error::other("not sent"));
        for _ in 0..2 {
            if link.is_none() {
                match Link::open(command.addr, &command.module, secret) {
                    Ok(opened) => link = Some(opened),
                    Err(err) => {
                        answer = Err(err);
                        continue;
                    }
                }
            }
            let Some(open) = &mut link else { continue };
            answer = open.send(&line);
            if answer.is_ok() {
                break;
            }
            link = None;
        }
        let module = &command.module;
        let reply = match answer {
            Ok(answer) if answer == "ok" => Reply {
                ok: true,
                message: format!(
                    "teleop `{module}`: {}",
                    line.trim().replace("v ", "driving at ")
                ),
                status: None,
                files: None,
            },
            Ok(answer) => Reply {
                ok: false,
                message: format!("teleop `{module}` answered: {answer}"),
                status: None,
                files: None,
            },
            Err(err) => Reply {
                ok: false,
                message: format!(
                    "cannot reach the teleop module `{module}` at {}: {err}",
                    command.addr
                ),
                status: None,
                files: None,
            },
        };
        let _ = command.reply.send(reply);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::net::TcpListener;

    fn candidate<'a>(name: &'a str, module_type: &'a str, up: bool) -> Candidate<'a> {
        Candidate {
            name,
            module_type,
            up,
        }
    }

    fn endpoints(pairs: &[(&str, &str)]) -> HashMap<String, BTreeMap<String, String>> {
        pairs
            .iter()
            .map(|(module, addr)| {
                (
                    (*module).to_owned(),
                    BTreeMap::from([(TELEOP_ENDPOINT.to_owned(), (*addr).to_owned())]),
                )
            })
            .collect()
    }

    #[test]
    fn the_target_is_the_only_teleop_that_is_up_and_said_where_it_listens() {
        let known = endpoints(&[("pad", "127.0.0.1:4000")]);
        let chosen = target(
            [
                candidate("sim", "sim", true),
                candidate("pad", "teleop", true),
            ],
            &known,
            None,
        );
        assert_eq!(
            chosen,
            Ok(("pad".to_owned(), "127.0.0.1:4000".parse().unwrap()))
        );
        let cases: [(Vec<Candidate>, Option<&str>, &str); 5] = [
            (
                vec![candidate("sim", "sim", true)],
                None,
                "has no teleop module",
            ),
            (
                vec![candidate("pad", "teleop", false)],
                None,
                "`pad` is not up",
            ),
            (
                vec![candidate("other", "teleop", true)],
                None,
                "`other` has not said where it listens",
            ),
            (
                vec![
                    candidate("pad", "teleop", true),
                    candidate("other", "teleop", true),
                ],
                None,
                "several teleop modules (pad, other)",
            ),
            (
                vec![candidate("pad", "teleop", true)],
                Some("joystick"),
                "no teleop module `joystick`",
            ),
        ];
        for (modules, wanted, expected) in cases {
            let err = target(modules, &known, wanted)
                .expect_err(expected)
                .to_string();
            assert!(err.contains(expected), "{err} (expected {expected})");
        }
    }

    /// A stand-in for the teleop module's port that answers each line with `answer(line)`.
    fn fake_module(answer: fn(&str) -> String) -> SocketAddr {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let mut writer = stream.try_clone().unwrap();
                for line in BufReader::new(stream).lines() {
                    let Ok(line) = line else { break };
                    if writer
                        .write_all(format!("{}\n", answer(&line)).as_bytes())
                        .is_err()
                    {
                        break;
                    }
                }
            }
        });
        addr
    }

    fn drive(relay: &Sender<Command>, addr: SocketAddr, linear: f64) -> Reply {
        let (reply, replies) = mpsc::channel();
        relay
            .send(Command {
                module: "pad".to_owned(),
                addr,
                linear,
                angular: 0.0,
                reply,
            })
            .unwrap();
        replies.recv_timeout(Duration::from_secs(10)).unwrap()
    }

    #[test]
    fn relays_commands_and_answers_and_follows_a_new_port() {
        let relay = start(None);
        let first = fake_module(|line| {
            if line == "stop" || line.starts_with("v ") {
                "ok".to_owned()
            } else {
                format!("error: unknown command `{line}`")
            }
        });
        let reply = drive(&relay, first, 0.3);
        assert!(reply.ok, "{reply:?}");
        assert_eq!(reply.message, "teleop `pad`: driving at 0.3 0");
        assert!(drive(&relay, first, 0.0).ok);
        let refusing = fake_module(|_| "error: LINEAR `x` is not a finite number".to_owned());
        let reply = drive(&relay, refusing, 0.3);
        assert!(!reply.ok);
        assert!(
            reply.message.contains("answered: error: LINEAR"),
            "{reply:?}"
        );
        // Nothing listens there any more (a port just freed): said plainly.
        let gone = {
            let listener = TcpListener::bind("127.0.0.1:0").unwrap();
            listener.local_addr().unwrap()
        };
        let reply = drive(&relay, gone, 0.3);
        assert!(!reply.ok);
        assert!(reply.message.contains("cannot reach"), "{reply:?}");
        assert!(drive(&relay, first, 0.1).ok, "back to the first");
    }
}

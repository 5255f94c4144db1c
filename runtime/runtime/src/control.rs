//! The operator's hold on a running mission (adjustable autonomy): pause, resume, abort, fire a
//! transition by hand, and ask for the state. `armor run` serves it on a TCP port as JSON lines,
//! one request and one reply per line; `armor ctl` and the studio are its clients.
//!
//! ```text
//! → {"command":"fire","transition":"leave_wp1"}
//! ← {"ok":true,"message":"fired `leave_wp1`","status":{...}}
//! ```

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Sender};
use std::time::Duration;

use armor_model::net::Marking;
use serde::{Deserialize, Serialize};

pub const ENV_CONTROL: &str = "ARMOR_CONTROL";
/// A request line longer than this is not a request.
const MAX_LINE_BYTES: u64 = 64 * 1024;
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Request {
    Status,
    Pause,
    Resume,
    Abort,
    Fire { transition: String },
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Status {
    pub mission: String,
    pub run_secs: f64,
    pub paused: bool,
    pub marking: Marking,
    /// Transitions that may fire now or later, each with what it waits for.
    pub enabled: Vec<String>,
    pub active_modules: Vec<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    pub ok: bool,
    pub message: String,
    pub status: Option<Status>,
}

/// A request from a client, with where to send the answer.
pub type Incoming = (Request, Sender<Reply>);

/// Serves the control interface on `addr`, handing each request to `requests`.
pub fn serve(addr: SocketAddr, requests: Sender<Incoming>) -> std::io::Result<SocketAddr> {
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let requests = requests.clone();
            std::thread::spawn(move || {
                if let Err(err) = serve_client(stream, &requests) {
                    tracing::debug!("control client: {err}");
                }
            });
        }
    });
    Ok(local)
}

fn serve_client(stream: TcpStream, requests: &Sender<Incoming>) -> std::io::Result<()> {
    let mut writer = stream.try_clone()?;
    let mut reader = BufReader::new(stream);
    loop {
        let mut line = String::new();
        if (&mut reader).take(MAX_LINE_BYTES).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let reply = match serde_json::from_str::<Request>(&line) {
            Ok(request) => {
                let (tx, rx) = mpsc::channel();
                if requests.send((request, tx)).is_err() {
                    return Ok(());
                }
                rx.recv_timeout(REPLY_TIMEOUT).unwrap_or_else(|_| Reply {
                    ok: false,
                    message: "the run did not answer".to_owned(),
                    status: None,
                })
            }
            Err(err) => Reply {
                ok: false,
                message: format!(
                    "bad request: {err} (expected e.g. {{\"command\":\"pause\"}} or {{\"command\":\"fire\",\"transition\":\"NAME\"}})"
                ),
                status: None,
            },
        };
        let mut text = serde_json::to_string(&reply).map_err(std::io::Error::other)?;
        text.push('\n');
        writer.write_all(text.as_bytes())?;
    }
}

/// Sends one request to a run's control interface and returns its reply.
pub fn request(addr: SocketAddr, request: &Request) -> anyhow::Result<Reply> {
    use anyhow::Context as _;
    let stream = TcpStream::connect_timeout(&addr, REPLY_TIMEOUT)
        .with_context(|| format!("cannot reach the run's control interface at {addr}"))?;
    stream.set_read_timeout(Some(REPLY_TIMEOUT * 2))?;
    let mut writer = stream.try_clone()?;
    let mut text = serde_json::to_string(request)?;
    text.push('\n');
    writer.write_all(text.as_bytes())?;
    let mut line = String::new();
    BufReader::new(stream)
        .read_line(&mut line)
        .context("no reply from the run")?;
    serde_json::from_str(&line).with_context(|| format!("unreadable reply `{}`", line.trim()))
}

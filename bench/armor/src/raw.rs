//! The raw TCP references: a peer process (this binary in a hidden mode) and the bench's side.

use std::io::{ErrorKind, Read as _, Write as _};
use std::net::{TcpListener, TcpStream};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};

use crate::procs::{ChildGuard, self_command};

/// How long a reference peer has to connect.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// No read of the reference side waits longer than this (a dead peer fails the bench).
const IO_TIMEOUT: Duration = Duration::from_secs(60);
/// Read buffer of the raw sink.
const SINK_READ_BYTES: usize = 256 * 1024;

/// Hidden mode `--raw-echo ADDR SIZE`: sends back every SIZE-byte message until the bench
/// closes the connection.
pub fn echo_main(addr: &str, size: usize) -> anyhow::Result<ExitCode> {
    let mut stream = TcpStream::connect(addr).with_context(|| format!("cannot reach {addr}"))?;
    stream.set_nodelay(true)?;
    let mut message = vec![0; size];
    loop {
        match stream.read_exact(&mut message) {
            Ok(()) => stream.write_all(&message)?,
            Err(err) if err.kind() == ErrorKind::UnexpectedEof => return Ok(ExitCode::SUCCESS),
            Err(err) => return Err(err.into()),
        }
    }
}

/// Hidden mode `--raw-reply ADDR SIZE`: answers every byte received with SIZE bytes (a request
/// for the latest value) until the bench closes the connection.
pub fn reply_main(addr: &str, size: usize) -> anyhow::Result<ExitCode> {
    let mut stream = TcpStream::connect(addr).with_context(|| format!("cannot reach {addr}"))?;
    stream.set_nodelay(true)?;
    let latest = vec![9; size];
    let mut request = [0; 1];
    loop {
        match stream.read_exact(&mut request) {
            Ok(()) => stream.write_all(&latest)?,
            Err(err) if err.kind() == ErrorKind::UnexpectedEof => return Ok(ExitCode::SUCCESS),
            Err(err) => return Err(err.into()),
        }
    }
}

/// Hidden mode `--raw-sink ADDR BYTES`: reads BYTES bytes, then answers one byte.
pub fn sink_main(addr: &str, bytes: u64) -> anyhow::Result<ExitCode> {
    let mut stream = TcpStream::connect(addr).with_context(|| format!("cannot reach {addr}"))?;
    stream.set_nodelay(true)?;
    let mut buf = vec![0; SINK_READ_BYTES];
    let mut left = bytes;
    while left > 0 {
        let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
        match stream.read(&mut buf[..want]) {
            Ok(0) => bail!("the bench closed the connection with {left} bytes still to come"),
            Ok(got) => left -= got as u64,
            Err(err) if err.kind() == ErrorKind::Interrupted => {}
            Err(err) => return Err(err.into()),
        }
    }
    stream.write_all(&[1])?;
    Ok(ExitCode::SUCCESS)
}

/// A reference peer started and connected: the stream to it, and its guard.
pub struct Peer {
    pub stream: TcpStream,
    pub child: ChildGuard,
}

/// Starts this binary as `--MODE ADDR ARG` and accepts its connection.
pub fn start_peer(mode: &str, arg: &str) -> anyhow::Result<Peer> {
    start_peer_on("127.0.0.1", None, mode, arg)
}

/// [`start_peer`] listening on `listen_on`, the peer run inside the network namespace `netns`
/// when given (`ip netns exec`).
pub fn start_peer_on(
    listen_on: &str,
    netns: Option<&str>,
    mode: &str,
    arg: &str,
) -> anyhow::Result<Peer> {
    let listener =
        TcpListener::bind(format!("{listen_on}:0")).context("cannot listen for the peer")?;
    let addr = listener.local_addr()?.to_string();
    let mut command = match netns {
        None => self_command()?,
        Some(ns) => {
            let exe = std::env::current_exe().context("cannot locate this executable")?;
            let mut command = std::process::Command::new("ip");
            command.args(["netns", "exec", ns]).arg(exe);
            command
        }
    };
    command.arg(mode).arg(&addr).arg(arg);
    let mut child = ChildGuard::spawn(&format!("armor-bench {mode}"), command)?;
    listener.set_nonblocking(true)?;
    let deadline = Instant::now() + CONNECT_TIMEOUT;
    let stream = loop {
        match listener.accept() {
            Ok((stream, _)) => break stream,
            Err(err) if err.kind() == ErrorKind::WouldBlock => {
                child.check_alive()?;
                if Instant::now() >= deadline {
                    return Err(
                        child.failure(&format!("did not connect within {CONNECT_TIMEOUT:?}"))
                    );
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(err) => return Err(err).context("accept failed"),
        }
    };
    stream.set_nonblocking(false)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(IO_TIMEOUT))?;
    stream.set_write_timeout(Some(IO_TIMEOUT))?;
    Ok(Peer { stream, child })
}

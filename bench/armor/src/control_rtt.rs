//! `control_rtt_ms`: one request and its reply on a kept control link (what the studio's polls
//! and the operator's teleop commands pay), encrypted with a secret (the Noise transport, its
//! requests numbered) against the same link without a secret. Both control interfaces are
//! served in this process and answer from a thread, as the supervisor's loop does; requests
//! alternate between them so both see the same machine.

use std::net::SocketAddr;
use std::sync::mpsc;
use std::time::Instant;

use armor_bench_report::Report;
use armor_module_api::auth::Secret;
use armor_protocol::{Client, Reply, Request};
use armor_runtime::control;

use crate::Settings;

pub const NAME: &str = "control_rtt_ms";

/// A control interface whose requests a thread answers at once with a small reply.
fn serve(secret: Option<Secret>) -> anyhow::Result<SocketAddr> {
    let (tx, rx) = mpsc::channel::<control::Incoming>();
    let addr = control::serve(SocketAddr::from(([127, 0, 0, 1], 0)), tx, secret)?;
    std::thread::spawn(move || {
        for (_, reply) in rx {
            let _ = reply.send(Reply {
                ok: true,
                message: "status".to_owned(),
                status: Some(armor_protocol::Status::default()),
                files: None,
            });
        }
    });
    Ok(addr)
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let count = if settings.quick { 200 } else { 2000 };
    let secret = Secret::from_bytes(b"the bench's secret, 32 bytes ok");
    let mut encrypted = Client::connect(serve(Some(secret.clone()))?, Some(&secret))?;
    let mut plain = Client::connect(serve(None)?, None)?;
    let mut ours = Vec::with_capacity(count);
    let mut reference = Vec::with_capacity(count);
    for _ in 0..count {
        let start = Instant::now();
        encrypted.call(&Request::Status)?;
        ours.push(start.elapsed());
        let start = Instant::now();
        plain.call(&Request::Status)?;
        reference.push(start.elapsed());
    }
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "the same control link without a secret (plaintext)",
        )
        .with("goal", "ratio <= 1.2"))
}

//! `handshake_secret`: opening a connection to the agent and getting it ready for requests,
//! with the shared secret (hellos, then the Noise handshake: three messages and a
//! Diffie-Hellman on each side) against the same without a secret (the hellos only).

use std::net::TcpStream;
use std::time::Instant;

use anyhow::Context as _;
use armor_module_api::wire::blocking;

use crate::Settings;
use crate::harness::Security;
use armor_bench_report::Report;

pub const NAME: &str = "handshake_secret";

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let count = if settings.quick { 50 } else { 500 };
    let secured = Security::with_secret(false)?;
    let Security::Secret { secret, .. } = &secured else {
        unreachable!("with_secret makes a secret");
    };
    let secured_agent = secured.agent()?;
    let plain_agent = Security::Plain.agent()?;
    let dial = armor_module_api::auth::Dial {
        key: secret.module_key("bench"),
        identity: "bench".to_owned(),
        encrypt: false,
    };
    let mut ours = Vec::with_capacity(count);
    let mut reference = Vec::with_capacity(count);
    for _ in 0..count {
        let start = Instant::now();
        let stream = TcpStream::connect(secured_agent)?;
        blocking::dial(stream, Some(&dial)).context("the handshake with the agent")?;
        ours.push(start.elapsed());
        let start = Instant::now();
        let stream = TcpStream::connect(plain_agent)?;
        blocking::dial(stream, None).context("the hellos with the agent")?;
        reference.push(start.elapsed());
    }
    Ok(
        Report::distribution(NAME, "us", 1e6, &ours, &reference).with(
            "reference_is",
            "a connection with the hellos only (no secret)",
        ),
    )
}

//! What a stranger on the team network sees: the samples a zenoh peer without a key receives,
//! printed as their key expression, size and bytes (hex). The stranger's test reads it back to
//! show that nothing travels in clear.

use std::time::{Duration, Instant};

use zenoh::Wait as _;

use crate::net::z;

/// How many bytes of each sample are printed: the team's samples are smaller but for outputs.
const SHOWN_BYTES: usize = 65536;

/// `armor-team capture`: what anyone on the team network sees.
#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// zenoh endpoints to connect to; repeat.
    #[arg(long)]
    pub connect: Vec<String>,
    /// zenoh endpoints to listen at; repeat.
    #[arg(long)]
    pub listen: Vec<String>,
    #[arg(long, default_value = "armor/team/**")]
    pub key_expr: String,
    /// How long to capture.
    #[arg(long, default_value_t = 10.0)]
    pub for_secs: f64,
}

pub fn run(options: &Options) -> anyhow::Result<()> {
    let session = crate::net::open(&options.listen, &options.connect)?;
    let samples = z(session.declare_subscriber(&options.key_expr).wait())?;
    let deadline = Instant::now() + Duration::from_secs_f64(options.for_secs);
    let mut count = 0;
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        let Some(sample) = z(samples.recv_timeout(left))? else {
            break;
        };
        let bytes = sample.payload().to_bytes();
        count += 1;
        println!(
            "sample {} {} bytes {}",
            sample.key_expr(),
            bytes.len(),
            armor_module_api::auth::hex(&bytes[..bytes.len().min(SHOWN_BYTES)])
        );
    }
    println!("captured {count} samples");
    Ok(())
}

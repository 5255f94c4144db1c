//! What a stranger on the team network sees: the samples a zenoh peer without a key receives,
//! printed as their key expression, size and bytes (hex). The stranger's test reads it back to
//! show that nothing travels in clear.

use std::time::{Duration, Instant};

use zenoh::Wait as _;

use crate::net::z;

/// How many bytes of each sample are printed: the team's samples are smaller but for outputs.
const SHOWN_BYTES: usize = 65536;

pub fn run(
    listen: &[String],
    connect: &[String],
    key_expr: &str,
    for_secs: f64,
) -> anyhow::Result<()> {
    let session = crate::net::open(listen, connect)?;
    let samples = z(session.declare_subscriber(key_expr).wait())?;
    let deadline = Instant::now() + Duration::from_secs_f64(for_secs);
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

//! The zenoh session of a bridge or a station: a peer with its endpoints given, and no
//! scouting (neither multicast nor gossip), so that it talks only to the peers it was told of
//! and says nothing on the networks it was not.

use anyhow::Context as _;
use zenoh::Wait as _;

/// A zenoh result as an `anyhow` one (zenoh's errors are boxed trait objects).
pub fn z<T>(result: zenoh::Result<T>) -> anyhow::Result<T> {
    result.map_err(|err| anyhow::anyhow!("{err}"))
}

/// Opens a peer that listens at `listen` and connects to `connect` (zenoh endpoints such as
/// `tcp/10.0.0.2:7447`), retrying a peer that is not there yet.
pub fn open(listen: &[String], connect: &[String]) -> anyhow::Result<zenoh::Session> {
    let mut config = zenoh::Config::default();
    let endpoints = |list: &[String]| serde_json::to_string(list).unwrap_or_default();
    for (key, value) in [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("scouting/gossip/enabled", "false".to_owned()),
        ("listen/endpoints", endpoints(listen)),
        ("connect/endpoints", endpoints(connect)),
        // A peer that is not up yet (or was cut off) is tried again every second at most, so
        // that a station catches up soon after a radio comes back.
        (
            "connect/retry",
            r#"{"period_init_ms":250,"period_max_ms":1000,"period_increase_factor":2}"#.to_owned(),
        ),
    ] {
        z(config.insert_json5(key, &value)).with_context(|| format!("zenoh setting {key}"))?;
    }
    z(zenoh::open(config).wait()).context("cannot open the zenoh session")
}

//! `armor replay`: publishes a recording made by `armor-mod-recorder` (an MCAP file) again.
//!
//! Every channel is published under its original data name (the channel's topic) and data type
//! (the channel's `armor.data_type` metadata, else its schema name), through a node hosted in
//! this process. Messages go out at their recorded log times, counted from the first one and
//! divided by the time scale. Message encodings: `json` (the recorder's form of the built-in
//! types) is turned back into the type's postcard bytes; `postcard` and `raw` are sent as they
//! are; anything else is refused before anything is published. An unfinished recording (a
//! `.partial` file left by a crash) is played as far as it goes.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::types::{Counter, LaserScan, OccupancyGrid, Odometry, Pose2D, Text, Twist};
use armor_module_api::{Datum, Event, ModuleSpec, Node, RawOutput, Standalone};

use crate::mcap_read::{ChunkTooLarge, Record, Records};
use serde::Deserialize;
use serde::de::DeserializeOwned;

/// The channel metadata key the recorder writes the data type under.
pub const DATA_TYPE_KEY: &str = "armor.data_type";
/// The node's name, as the agent and subscribers' logs show it.
pub const NODE_NAME: &str = "replay";
/// After the last message, how long the node keeps writing what subscribers have not taken yet.
const LINGER: Duration = Duration::from_millis(500);

#[derive(Clone, Debug)]
pub struct Options {
    pub file: PathBuf,
    /// Play this many times faster than recorded.
    pub time_scale: f64,
    /// The agent's address (else `$ARMOR_AGENT`, else the default).
    pub agent: Option<String>,
    /// Play again from the start after the end, until killed.
    pub looping: bool,
    /// Before playing, wait at most this long for every channel to have a subscriber.
    pub wait_for_subscribers: Duration,
}

/// How a channel's messages become samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Conversion {
    /// JSON of a built-in type, back to postcard.
    FromJson,
    /// Sent as recorded.
    AsIs,
}

/// What a channel is published as.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Plan {
    data_name: String,
    data_type: String,
    conversion: Conversion,
}

/// A channel of a recording, as its record says it.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Channel {
    topic: String,
    message_encoding: String,
    metadata: BTreeMap<String, String>,
    /// The name of the channel's schema, if it has one.
    schema_name: Option<String>,
}

/// Reads a channel's data name, type and encoding, refusing what cannot be published.
fn plan(channel: &Channel) -> anyhow::Result<Plan> {
    let topic = &channel.topic;
    let data_type = channel
        .metadata
        .get(DATA_TYPE_KEY)
        .filter(|data_type| !data_type.is_empty())
        .or(channel.schema_name.as_ref().filter(|name| !name.is_empty()))
        .with_context(|| {
            format!(
                "channel `{topic}` names no data type (no `{DATA_TYPE_KEY}` metadata, no schema)"
            )
        })?
        .clone();
    let conversion = match channel.message_encoding.as_str() {
        "json" if json_type(&data_type) => Conversion::FromJson,
        "json" => bail!(
            "channel `{topic}`: JSON messages of type `{data_type}`, which has no known JSON form"
        ),
        "postcard" | "raw" => Conversion::AsIs,
        other => bail!(
            "channel `{topic}`: unknown message encoding `{other}` (armor replay reads json, postcard and raw)"
        ),
    };
    Ok(Plan {
        data_name: topic.clone(),
        data_type,
        conversion,
    })
}

fn json_type(data_type: &str) -> bool {
    matches!(
        data_type,
        "Counter"
            | "Text"
            | "Pose2D"
            | "Twist"
            | "Odometry"
            | "LaserScan"
            | "OccupancyGrid"
            | "Image"
    )
}

#[derive(Deserialize)]
struct CounterJson {
    value: u64,
}

#[derive(Deserialize)]
struct TextJson {
    text: String,
}

/// The postcard bytes of a built-in type's JSON form (as the recorder writes it).
fn from_json(data_type: &str, json: &[u8]) -> anyhow::Result<Vec<u8>> {
    fn encode<J: DeserializeOwned, T: Datum>(
        json: &[u8],
        to_value: impl FnOnce(J) -> T,
    ) -> anyhow::Result<Vec<u8>> {
        let value = to_value(serde_json::from_slice(json)?);
        let mut out = Vec::new();
        value.encode(&mut out)?;
        Ok(out)
    }
    let bytes = match data_type {
        "Counter" => encode(json, |json: CounterJson| Counter(json.value)),
        "Text" => encode(json, |json: TextJson| Text(json.text)),
        "Pose2D" => encode(json, |value: Pose2D| value),
        "Twist" => encode(json, |value: Twist| value),
        "Odometry" => encode(json, |value: Odometry| value),
        "LaserScan" => encode(json, |value: LaserScan| value),
        "OccupancyGrid" => encode(json, |value: OccupancyGrid| value),
        // Foxglove's RawImage or CompressedImage, as the recorder writes an image.
        "Image" => armor_model::foxglove::from_json(json)
            .map_err(anyhow::Error::msg)
            .and_then(|image| {
                let mut out = Vec::new();
                image.encode(&mut out)?;
                Ok(out)
            }),
        _ => bail!("no JSON form is known for type `{data_type}`"),
    };
    bytes.with_context(|| format!("a JSON message is not a {data_type}"))
}

/// One message of a recording, as its node sent it.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded {
    /// When the recorder logged it (Unix nanoseconds).
    pub log_time_ns: u64,
    pub data_name: String,
    pub data_type: String,
    /// The datum's encoding on the wire (postcard for the built-in types).
    pub payload: Vec<u8>,
}

impl Recorded {
    /// What it takes in memory, its own size included (as in a `Vec<Recorded>`).
    pub fn size_in_memory(&self) -> usize {
        std::mem::size_of::<Recorded>()
            .saturating_add(self.payload.len())
            .saturating_add(self.data_name.len())
            .saturating_add(self.data_type.len())
    }
}

/// Every message of a recording, in the order of the file; an unfinished one is read as far as
/// it goes.
pub fn read_recording(file: &Path) -> anyhow::Result<Vec<Recorded>> {
    read_recording_within(file, usize::MAX)
}

/// [`read_recording`], refusing a recording whose messages would take more than `max_bytes` in
/// memory (payloads, names and bookkeeping, see [`read_recording_bytes`]), or whose file is
/// larger than that.
pub fn read_recording_within(file: &Path, max_bytes: usize) -> anyhow::Result<Vec<Recorded>> {
    let name = file.display().to_string();
    let size = std::fs::metadata(file)
        .with_context(|| format!("cannot read {name}"))?
        .len();
    if usize::try_from(size).map_or(true, |size| size > max_bytes) {
        bail!("{name} is {size} bytes, more than the {max_bytes} it may take");
    }
    let bytes = std::fs::read(file).with_context(|| format!("cannot read {name}"))?;
    read_recording_bytes(&name, &bytes, max_bytes)
}

/// The messages of the recording `bytes` (read from `name`), refused once they take more than
/// `max_bytes` in memory: compressed chunks may hold far more than the file's size, so a small
/// file could otherwise fill the memory. Records are read by [`crate::mcap_read`], which checks
/// every length before it allocates. Every channel is planned when its record is read: one that
/// cannot be published is refused even if no message uses it.
pub fn read_recording_bytes(
    name: &str,
    bytes: &[u8],
    max_bytes: usize,
) -> anyhow::Result<Vec<Recorded>> {
    if !bytes.starts_with(mcap::MAGIC) {
        bail!("{name} is not an MCAP file");
    }
    let records =
        Records::new(bytes, max_bytes).with_context(|| format!("{name} is not an MCAP file"))?;
    let mut schema_names: HashMap<u16, String> = HashMap::new();
    let mut plans: HashMap<u16, Plan> = HashMap::new();
    let mut messages = Vec::new();
    let mut used_bytes = 0_usize;
    for record in records {
        let record = record.and_then(|record| match record {
            Record::Message { channel_id, .. } if !plans.contains_key(&channel_id) => {
                bail!("a message on channel {channel_id}, which no record defines")
            }
            record => Ok(record),
        });
        let record = match record {
            Ok(record) => record,
            // Too large is not damaged: nothing is shown rather than a part.
            Err(err) if err.is::<ChunkTooLarge>() => {
                return Err(err).context(format!("{name}: its messages take too much memory"));
            }
            Err(err) if !messages.is_empty() => {
                tracing::warn!("{name}: stopped at a damaged or unfinished part: {err:#}");
                return Ok(messages);
            }
            Err(err) => return Err(err).context(format!("{name} is not a valid MCAP file")),
        };
        match record {
            Record::Schema { id, name } => {
                schema_names.entry(id).or_insert(name);
            }
            Record::Channel(channel) => {
                if plans.contains_key(&channel.id) {
                    continue;
                }
                let schema_name = schema_names.get(&channel.schema_id).cloned();
                let id = channel.id;
                let channel = Channel {
                    topic: channel.topic,
                    message_encoding: channel.message_encoding,
                    metadata: channel.metadata,
                    schema_name,
                };
                let plan = plan(&channel).with_context(|| format!("cannot replay {name}"))?;
                plans.insert(id, plan);
            }
            Record::Message {
                channel_id,
                log_time_ns,
                data,
            } => {
                let Some(plan) = plans.get(&channel_id) else {
                    continue; // refused above
                };
                let payload = match plan.conversion {
                    Conversion::FromJson => from_json(&plan.data_type, &data)
                        .with_context(|| format!("channel `{}`", plan.data_name))?,
                    Conversion::AsIs => data,
                };
                let recorded = Recorded {
                    log_time_ns,
                    data_name: plan.data_name.clone(),
                    data_type: plan.data_type.clone(),
                    payload,
                };
                used_bytes = used_bytes.saturating_add(recorded.size_in_memory());
                if used_bytes > max_bytes {
                    bail!(
                        "{name}: its messages take more than {max_bytes} bytes once read (at message {})",
                        messages.len() + 1
                    );
                }
                messages.push(recorded);
            }
            // The summary that follows only repeats the schemas and channels.
            Record::DataEnd => return Ok(messages),
            Record::Other => {}
        }
    }
    tracing::warn!("{name} has no end (an unfinished recording?): read what it holds");
    Ok(messages)
}

/// Replays a recording until its end (or forever with `looping`).
pub fn run(options: &Options) -> anyhow::Result<()> {
    let scale = options.time_scale;
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--time-scale must be a positive number, not {scale}");
    }
    let name = options.file.display().to_string();
    let messages = read_recording(&options.file)?;
    let spec = ModuleSpec::new(NODE_NAME, "Publishes a recording again.");
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some(NODE_NAME.to_owned()),
            agent: options.agent.clone(),
            ..Standalone::default()
        },
    )?;
    let mut player = Player {
        node: &mut node,
        outputs: HashMap::new(),
    };
    for message in &messages {
        player.publish(&message.data_name, &message.data_type)?;
    }
    player.wait_for_subscribers(options.wait_for_subscribers)?;
    loop {
        let started = Instant::now();
        player.play_once(&messages, scale)?;
        tracing::info!(
            "replayed {} messages from {name} in {:.2} s",
            messages.len(),
            started.elapsed().as_secs_f64()
        );
        if !options.looping {
            break;
        }
        if messages.is_empty() {
            bail!("{name} holds no message to play in a loop");
        }
    }
    player.linger()
}

/// When a message logged at `log_time_ns` is due, the first having been logged at `first_ns`
/// and played at `started`; `None` beyond what a clock can say (a tiny time scale, or a
/// recording spanning centuries). A message logged before the first is due at once.
fn due_at(started: Instant, first_ns: u64, log_time_ns: u64, scale: f64) -> Option<Instant> {
    let offset_secs = log_time_ns.saturating_sub(first_ns) as f64 / 1e9 / scale;
    started.checked_add(Duration::try_from_secs_f64(offset_secs).ok()?)
}

struct Player<'a> {
    node: &'a mut Node,
    /// Data name → where its messages go.
    outputs: HashMap<String, RawOutput>,
}

impl Player<'_> {
    fn publish(&mut self, data_name: &str, data_type: &str) -> anyhow::Result<()> {
        if self.outputs.contains_key(data_name) {
            return Ok(());
        }
        let output = self
            .node
            .publish_raw(data_name, data_type)
            .with_context(|| format!("cannot publish `{data_name}`"))?;
        tracing::info!(data_name, data_type, "publishing");
        self.outputs.insert(data_name.to_owned(), output);
        Ok(())
    }

    fn wait_for_subscribers(&mut self, patience: Duration) -> anyhow::Result<()> {
        if patience.is_zero() {
            return Ok(());
        }
        let deadline = Instant::now() + patience;
        loop {
            let waiting: Vec<&str> = self
                .outputs
                .iter()
                .filter(|(_, output)| self.node.raw_subscriber_count(output) == 0)
                .map(|(data_name, _)| data_name.as_str())
                .collect();
            if waiting.is_empty() {
                return Ok(());
            }
            if Instant::now() >= deadline {
                tracing::warn!("no subscriber for {}; playing anyway", waiting.join(", "));
                return Ok(());
            }
            self.pause_until((Instant::now() + Duration::from_millis(20)).min(deadline))?;
        }
    }

    /// Keeps the node's connections turning until `until`.
    fn pause_until(&mut self, until: Instant) -> anyhow::Result<()> {
        loop {
            match self.node.next_event_until(until)? {
                Event::Timeout => return Ok(()),
                Event::Shutdown => bail!("asked to shut down"),
                _ => {}
            }
        }
    }

    /// Plays every message once, at its recorded time from the first.
    fn play_once(&mut self, messages: &[Recorded], scale: f64) -> anyhow::Result<()> {
        let started = Instant::now();
        let Some(first_ns) = messages.first().map(|message| message.log_time_ns) else {
            return Ok(());
        };
        for message in messages {
            let due = due_at(started, first_ns, message.log_time_ns, scale).with_context(|| {
                format!(
                    "a message logged {} ns after the first is due later than can be waited for at --time-scale {scale}",
                    message.log_time_ns.saturating_sub(first_ns)
                )
            })?;
            if due > Instant::now() {
                self.pause_until(due)?;
            }
            let output = &self.outputs[&message.data_name];
            self.node.send_raw(output, &message.payload)?;
        }
        Ok(())
    }

    /// Lets subscribers take what is still buffered before the process exits.
    fn linger(&mut self) -> anyhow::Result<()> {
        self.node.flush()?;
        self.pause_until(Instant::now() + LINGER)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use std::collections::BTreeMap;
    use std::io::Cursor;

    use super::*;

    fn encode<T: Datum>(value: &T) -> Vec<u8> {
        let mut out = Vec::new();
        value.encode(&mut out).unwrap();
        out
    }

    #[test]
    fn json_forms_turn_back_into_postcard() {
        assert_eq!(
            from_json("Counter", br#"{"value":300}"#).unwrap(),
            encode(&Counter(300))
        );
        assert_eq!(
            from_json("Text", br#"{"text":"hi"}"#).unwrap(),
            encode(&Text("hi".into()))
        );
        let odometry = Odometry {
            pose_in_odom: Pose2D {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: 0.5,
            },
            twist: Twist {
                linear_mps: 0.25,
                angular_radps: -0.1,
            },
        };
        let json = serde_json::to_vec(&serde_json::json!({
            "pose_in_odom": {"x_m": 1.0, "y_m": 2.0, "theta_rad": 0.5},
            "twist": {"linear_mps": 0.25, "angular_radps": -0.1},
        }))
        .unwrap();
        assert_eq!(from_json("Odometry", &json).unwrap(), encode(&odometry));
        let grid = br#"{"resolution_m":0.5,"width":2,"height":1,"origin_x_m":0,"origin_y_m":0,"cells":[-1,100]}"#;
        assert_eq!(
            from_json("OccupancyGrid", grid).unwrap(),
            encode(&OccupancyGrid {
                resolution_m: 0.5,
                width: 2,
                height: 1,
                cells: vec![-1, 100],
                ..OccupancyGrid::default()
            })
        );
        // An image as Foxglove's RawImage (what the recorder writes, and other tools too).
        let image = br#"{"timestamp":{"sec":1,"nsec":5},"frame_id":"cam","width":2,"height":1,"encoding":"mono8","step":2,"data":"CgA="}"#;
        assert_eq!(
            from_json("Image", image).unwrap(),
            encode(&armor_module_api::types::Image {
                width: 2,
                height: 1,
                encoding: armor_module_api::types::ImageEncoding::Mono8,
                stamp_ns: 1_000_000_005,
                frame_id: "cam".into(),
                data: vec![10, 0].into(),
            })
        );
        let err = from_json("Counter", br#"{"count":1}"#).unwrap_err();
        assert!(format!("{err:#}").contains("not a Counter"), "{err:#}");
        assert!(from_json("Imu", b"{}").is_err());
    }

    fn channel(topic: &str, encoding: &str, data_type: Option<&str>) -> Channel {
        Channel {
            topic: topic.into(),
            message_encoding: encoding.into(),
            metadata: data_type
                .map(|data_type| BTreeMap::from([(DATA_TYPE_KEY.into(), data_type.into())]))
                .unwrap_or_default(),
            schema_name: None,
        }
    }

    #[test]
    fn channels_are_planned_from_their_encoding_and_type() {
        let plan_of = |encoding, data_type| plan(&channel("a.b", encoding, data_type));
        assert_eq!(
            plan_of("json", Some("Counter")).unwrap().conversion,
            Conversion::FromJson
        );
        assert_eq!(
            plan_of("postcard", Some("Imu")).unwrap(),
            Plan {
                data_name: "a.b".into(),
                data_type: "Imu".into(),
                conversion: Conversion::AsIs
            }
        );
        assert_eq!(
            plan_of("raw", Some("Blob")).unwrap().conversion,
            Conversion::AsIs
        );
        let err = plan_of("cdr", Some("Imu")).unwrap_err().to_string();
        assert!(err.contains("unknown message encoding `cdr`"), "{err}");
        let err = plan_of("json", Some("Imu")).unwrap_err().to_string();
        assert!(err.contains("no known JSON form"), "{err}");
        let err = plan_of("postcard", None).unwrap_err().to_string();
        assert!(err.contains("names no data type"), "{err}");
    }

    /// An MCAP file with one channel of the given encoding and one message.
    fn mcap_with(encoding: &str) -> Vec<u8> {
        let mut writer = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
        let schema = writer.add_schema("Counter", "", &[]).unwrap();
        let metadata = BTreeMap::from([(DATA_TYPE_KEY.to_owned(), "Counter".to_owned())]);
        let channel = writer
            .add_channel(schema, "counter.count", encoding, &metadata)
            .unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 1,
            log_time: 5,
            publish_time: 5,
        };
        writer.write_to_known_channel(&header, &[1]).unwrap();
        writer.finish().unwrap();
        writer.into_inner().into_inner()
    }

    fn options(file: PathBuf) -> Options {
        Options {
            file,
            time_scale: 1.0,
            // Nothing listens there: every case below fails before connecting.
            agent: Some("127.0.0.1:9".into()),
            looping: false,
            wait_for_subscribers: Duration::ZERO,
        }
    }

    #[test]
    fn clear_errors_before_anything_is_published() {
        let dir = tempfile::tempdir().unwrap();
        let error = |file: PathBuf| format!("{:#}", run(&options(file)).unwrap_err());

        let missing = dir.path().join("missing.mcap");
        let err = error(missing);
        assert!(
            err.contains("cannot read") && err.contains("missing.mcap"),
            "{err}"
        );

        let text = dir.path().join("notes.mcap");
        std::fs::write(&text, "not a recording").unwrap();
        assert!(error(text).contains("is not an MCAP file"));

        let cdr = dir.path().join("cdr.mcap");
        std::fs::write(&cdr, mcap_with("cdr")).unwrap();
        let err = error(cdr);
        assert!(err.contains("unknown message encoding `cdr`"), "{err}");

        let mut scale = options(dir.path().join("x"));
        scale.time_scale = 0.0;
        assert!(
            run(&scale)
                .unwrap_err()
                .to_string()
                .contains("--time-scale")
        );
    }

    #[test]
    fn every_channel_is_planned_and_a_cut_file_is_read_as_far_as_it_goes() {
        let bytes = mcap_with("postcard");
        let messages = read_recording_bytes("f", &bytes, usize::MAX).unwrap();
        assert_eq!(messages.len(), 1);
        assert_eq!(messages[0].data_name, "counter.count");
        assert_eq!(messages[0].data_type, "Counter");
        assert_eq!(messages[0].log_time_ns, 5);
        // A channel no message uses is planned all the same.
        let mut writer = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
        writer
            .add_channel(0, "camera.image", "cdr", &BTreeMap::new())
            .unwrap();
        writer.finish().unwrap();
        let unused = writer.into_inner().into_inner();
        let err = format!(
            "{:#}",
            read_recording_bytes("f", &unused, usize::MAX).unwrap_err()
        );
        assert!(
            err.contains("channel `camera.image` names no data type"),
            "{err}"
        );
        // Cut after its message, it gives that message; cut in its header, a clear error.
        let half = &bytes[..bytes.len() / 2];
        assert_eq!(
            read_recording_bytes("f", half, usize::MAX).unwrap(),
            messages
        );
        let err = format!(
            "{:#}",
            read_recording_bytes("f", &bytes[..20], usize::MAX).unwrap_err()
        );
        assert!(err.contains("f is not a valid MCAP file"), "{err}");
    }

    /// A record as MCAP frames it: opcode, length (u64), body.
    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut out = vec![opcode];
        out.extend((body.len() as u64).to_le_bytes());
        out.extend(body);
        out
    }

    fn string(text: &str) -> Vec<u8> {
        let mut out = (text.len() as u32).to_le_bytes().to_vec();
        out.extend(text.as_bytes());
        out
    }

    /// A channel record: id 1, no schema, the data type in its metadata.
    fn channel_record(topic: &[u8]) -> Vec<u8> {
        let mut body = vec![1, 0, 0, 0];
        body.extend(topic);
        body.extend(string("postcard"));
        let entry = [string(DATA_TYPE_KEY), string("Counter")].concat();
        body.extend((entry.len() as u32).to_le_bytes());
        body.extend(entry);
        record(mcap::records::op::CHANNEL, &body)
    }

    fn message_record(log_time_ns: u64) -> Vec<u8> {
        let mut body = vec![1, 0, 7, 0, 0, 0];
        body.extend(log_time_ns.to_le_bytes());
        body.extend(log_time_ns.to_le_bytes());
        body.extend(encode(&Counter(3)));
        record(mcap::records::op::MESSAGE, &body)
    }

    #[test]
    fn a_string_longer_than_its_record_is_refused_before_it_is_allocated() {
        // The mcap crate's parser reserved the 4 GiB this topic claims before finding three
        // bytes; read_record checks the length against the record first.
        let mut hostile_topic = u32::MAX.to_le_bytes().to_vec();
        hostile_topic.extend(b"abc");
        let header = record(
            mcap::records::op::HEADER,
            &[string(""), string("hand")].concat(),
        );
        let good = [
            mcap::MAGIC.to_vec(),
            header.clone(),
            channel_record(&string("counter.count")),
            message_record(5),
        ]
        .concat();
        let messages = read_recording_bytes("f", &good, usize::MAX).unwrap();
        assert_eq!(messages.len(), 1);
        assert_eq!(messages[0].payload, encode(&Counter(3)));

        let hostile = [mcap::MAGIC.to_vec(), header, channel_record(&hostile_topic)].concat();
        let err = format!(
            "{:#}",
            read_recording_bytes("f", &hostile, usize::MAX).unwrap_err()
        );
        assert!(
            err.contains("not a valid MCAP file: a damaged record (opcode 0x04"),
            "{err}"
        );
        // After messages, a damaged record ends the reading; what was read is kept.
        let late = [good.clone(), channel_record(&hostile_topic)].concat();
        assert_eq!(
            read_recording_bytes("f", &late, usize::MAX).unwrap(),
            messages
        );
        // So does a message on a channel nothing defined.
        let stray = [mcap::MAGIC.to_vec(), message_record(5)].concat();
        let err = format!(
            "{:#}",
            read_recording_bytes("f", &stray, usize::MAX).unwrap_err()
        );
        assert!(err.contains("channel 1, which no record defines"), "{err}");
    }

    #[test]
    fn a_recording_larger_than_its_budget_is_refused() {
        // Two messages, not in a chunk.
        let bytes = [
            mcap::MAGIC.to_vec(),
            channel_record(&string("counter.count")),
            message_record(5),
            message_record(6),
        ]
        .concat();
        let two = read_recording_bytes("f", &bytes, usize::MAX).unwrap();
        assert_eq!(two.len(), 2);
        let needed = two[0].size_in_memory() + two[1].size_in_memory();
        assert_eq!(read_recording_bytes("f", &bytes, needed).unwrap(), two);
        let err = read_recording_bytes("f", &bytes, needed - 1).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "f: its messages take more than {} bytes once read (at message 2)",
                needed - 1
            )
        );
        // A chunk that would decompress to more than the budget is not decompressed.
        let chunked = mcap_with("postcard");
        let err = read_recording_bytes("f", &chunked, 50).unwrap_err();
        assert!(
            format!("{err:#}").starts_with("f: its messages take too much memory: a chunk of"),
            "{err:#}"
        );
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("small.mcap");
        std::fs::write(&file, &bytes).unwrap();
        assert_eq!(
            read_recording_within(&file, bytes.len().max(needed)).unwrap(),
            two
        );
        let err = read_recording_within(&file, bytes.len() - 1).unwrap_err();
        assert!(err.to_string().contains("more than the"), "{err}");
    }

    #[test]
    fn hostile_log_times_give_an_error_not_a_panic() {
        let now = Instant::now();
        assert_eq!(
            due_at(now, 1_000, 1_500_000_000 + 1_000, 2.0),
            Some(now + Duration::from_millis(750))
        );
        assert_eq!(due_at(now, 1_000, 0, 1.0), Some(now), "before the first");
        // Duration::from_secs_f64 panicked on these.
        assert_eq!(due_at(now, 0, u64::MAX, 1e-300), None);
        assert_eq!(due_at(now, 0, u64::MAX, 1e-12), None);
        assert!(due_at(now, 0, u64::MAX, 1.0).is_some(), "584 years");
    }
}

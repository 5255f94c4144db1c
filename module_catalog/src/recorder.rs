//! `recorder`: records every sample of named data streams into an MCAP file while active.
//!
//! The file has one channel per data name (topic = data name), each sample a message whose log
//! and publish times are its run-clock stamp. Samples of the built-in types that postcard encodes
//! (`Counter`, `Text`, `Pose2D`, `Twist`, `Odometry`, `LaserScan`, `OccupancyGrid`) are stored
//! as JSON objects with a JSON Schema, so that common viewers (Foxglove, the `mcap` CLI) show
//! them; a sample JSON cannot carry exactly (a NaN or infinite number) goes to a second channel
//! of the same topic, stored as postcard. `Image` samples are stored as JSON in Foxglove's own
//! schemas ([`armor_model::foxglove`]): `foxglove.RawImage` for `rgb8` and `mono8`,
//! `foxglove.CompressedImage` for JPEG, which Foxglove shows in its image panel. Any other type is stored as it travelled: message
//! encoding `postcard`, schema named after the type with no schema data, except `Blob`, whose
//! bytes are not postcard (encoding `raw`). Every channel's metadata names its data type under
//! [`DATA_TYPE_KEY`]; `armor replay` publishes the file again.
//!
//! The file is written as `FILE.partial`, flushed to disk every second (a crash loses at most
//! the last second, and leaves a truncated but recoverable MCAP under that name), and renamed
//! into place when recording stops: when the module is stopped, shuts down, or gets SIGTERM or
//! SIGINT (see [`body_until`]). Recording resumes on the next start in a new file: `NAME-2.EXT`,
//! then `NAME-3.EXT`, ... A file that exists already is never written over: the next free name
//! is taken, with a warning. A relative `file` is written into the run's folder
//! (`armor_module_api::output_path`).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_model::foxglove;
use armor_module_api::types::{
    CodecError, Counter, Image, LaserScan, OccupancyGrid, Odometry, Pose2D, Text, Twist,
};
use armor_module_api::{
    BodyResult, Datum, Event, ModuleSpec, Node, ParamSpec, ParamType, RawInput, RawSample,
};
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::json;

use crate::BodyError;

pub const TYPE: &str = "recorder";
/// Channel metadata key naming the ArMoR data type of a channel's messages.
pub const DATA_TYPE_KEY: &str = "armor.data_type";
/// How often the file is flushed to disk while recording.
pub const FLUSH_PERIOD: Duration = Duration::from_secs(1);
/// The longest the module waits before looking at the termination flag again.
const TICK: Duration = Duration::from_millis(100);

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Records every sample of the named data streams, with its stamp and type, into an MCAP file while active.",
    )
        .category(armor_module_api::Category::Recording)
    .version(env!("CARGO_PKG_VERSION"))
    .param(ParamSpec::new(
        "record",
        ParamType::String,
        "the data names to record, comma-separated (e.g. `sim.odometry,sim.scan,sim.pose_truth`)",
    ))
    .param(ParamSpec::new(
        "file",
        ParamType::String,
        "the file to write (a relative name goes into the run's folder): written as FILE.partial and renamed into place when recording stops; after a stop, the next start records into NAME-2.EXT, NAME-3.EXT, ...; an existing file is never written over, the next free name is taken (tunable live: a new file is used from the next start, as a mission sets it per place)",
    ))
    .param(
        ParamSpec::new(
            "format",
            ParamType::String,
            "file format: `mcap` (JSON messages for the built-in types, postcard bytes for others)",
        ).choices(&["mcap"])
        .default("mcap"),
    )
    .param(
        ParamSpec::new(
            "compression",
            ParamType::String,
            "compression of the file's chunks: `zstd`, `lz4` or `none`",
        ).choices(&["zstd", "lz4", "none"])
        .default("zstd"),
    )
    .param(
        ParamSpec::new(
            "report_secs",
            ParamType::Float,
            "log how many messages were recorded every this many seconds (0: only when a file is saved)",
        ).min(0.0)
        .unit("s")
        .default("5"),
    )
}

/// The module body, for a test bench or a caller that handles no signals.
pub fn body(node: &mut Node) -> BodyResult {
    body_until(node, &AtomicBool::new(false))
}

/// The module body, which also ends (saving the file) once `terminate` is set: the binary sets
/// it on SIGTERM and SIGINT, which would otherwise kill the process with the file unfinished.
pub fn body_until(node: &mut Node, terminate: &AtomicBool) -> BodyResult {
    let mut settings = Settings::from_node(node)?;
    let mut inputs: Vec<(RawInput, String)> = Vec::new();
    for data_name in &settings.record {
        inputs.push((node.subscribe_raw(data_name, true)?, data_name.clone()));
    }
    tracing::info!(
        "recording {} into {} while active",
        settings.record.join(", "),
        settings.file.display()
    );
    let mut segments = 0;
    let mut recording = None;
    if node.is_active() {
        recording = Some(Recording::create(
            &next_segment(&settings.file, &mut segments),
            settings.compression,
        )?);
    }
    let mut next_flush = Instant::now() + FLUSH_PERIOD;
    let mut report_period = settings.report_period;
    let mut next_report = report_period.map(|period| Instant::now() + period);
    let mut reported = 0;
    loop {
        if terminate.load(Ordering::Relaxed) {
            tracing::info!("terminated by a signal");
            break;
        }
        let wake = (Instant::now() + TICK).min(next_flush);
        match node.next_event_until(wake)? {
            Event::Input(port) => {
                let Some((input, data_name)) = inputs.iter().find(|(input, _)| input.id() == port)
                else {
                    continue;
                };
                while let Some(sample) = node.take_raw(input) {
                    // Inactive: the samples are read (so the providers never wait) and dropped.
                    if let Some(recording) = &mut recording {
                        recording.write(data_name, &sample)?;
                    }
                }
            }
            Event::Start if recording.is_none() => {
                reported = 0;
                recording = Some(Recording::create(
                    &next_segment(&settings.file, &mut segments),
                    settings.compression,
                )?);
            }
            Event::Stop => {
                if let Some(recording) = recording.take() {
                    recording.finish()?;
                }
            }
            Event::ParamsChanged(names) => {
                // A mission sets `file` per place: the next start records into the new file
                // (its first segment), while a recording under way goes on in its own.
                if names
                    .iter()
                    .any(|name| name == "file" || name == "compression")
                {
                    match Settings::from_node(node) {
                        Ok(new) => {
                            if new.file != settings.file {
                                segments = 0;
                            }
                            settings.file = new.file;
                            settings.compression = new.compression;
                            tracing::info!(
                                "from the next start, recording into {}",
                                settings.file.display()
                            );
                        }
                        Err(err) => tracing::error!("{err}; keeping the previous file"),
                    }
                }
                for name in names
                    .iter()
                    .filter(|name| !["report_secs", "file", "compression"].contains(&name.as_str()))
                {
                    tracing::warn!("a new `{name}` takes effect when the module is restarted");
                }
                if names.iter().any(|name| name == "report_secs") {
                    match Settings::report_period(node) {
                        Ok(period) => {
                            report_period = period;
                            next_report = period.map(|period| Instant::now() + period);
                        }
                        Err(err) => tracing::error!("{err}; keeping the previous `report_secs`"),
                    }
                }
            }
            Event::Shutdown => break,
            _ => {}
        }
        let now = Instant::now();
        if now >= next_flush {
            if let Some(recording) = &mut recording {
                recording.flush()?;
            }
            next_flush = now + FLUSH_PERIOD;
        }
        if let (Some(at), Some(recording)) = (next_report, &recording)
            && now >= at
        {
            if recording.total != reported {
                tracing::info!("{}", recording.progress());
                reported = recording.total;
            }
            next_report = report_period.map(|period| now + period);
        }
    }
    if let Some(recording) = recording.take() {
        recording.finish()?;
    }
    Ok(())
}

/// The module's parameters, checked.
#[derive(Clone, Debug)]
struct Settings {
    record: Vec<String>,
    file: PathBuf,
    compression: Option<mcap::Compression>,
    report_period: Option<Duration>,
}

impl Settings {
    fn from_node(node: &Node) -> Result<Self, BodyError> {
        let required = |name: &str| -> Result<String, BodyError> {
            node.param::<String>(name)
                .ok()
                .filter(|value| !value.trim().is_empty())
                .ok_or_else(|| format!("parameter `{name}` is required").into())
        };
        let record = parse_record(&required("record")?)?;
        let file = armor_module_api::output_path(Path::new(required("file")?.trim()));
        let format: String = node.param("format")?;
        if format.trim() != "mcap" {
            return Err(format!("parameter `format` must be `mcap`, not `{format}`").into());
        }
        let compression: String = node.param("compression")?;
        let compression = match compression.trim() {
            "zstd" => Some(mcap::Compression::Zstd),
            "lz4" => Some(mcap::Compression::Lz4),
            "none" => None,
            other => {
                return Err(format!(
                    "parameter `compression` must be `zstd`, `lz4` or `none`, not `{other}`"
                )
                .into());
            }
        };
        Ok(Self {
            record,
            file,
            compression,
            report_period: Self::report_period(node)?,
        })
    }

    fn report_period(node: &Node) -> Result<Option<Duration>, BodyError> {
        let secs = node.param::<f64>("report_secs")?;
        Ok((secs > 0.0).then(|| Duration::from_secs_f64(secs)))
    }
}

/// The data names of the `record` parameter, in order, each once.
fn parse_record(value: &str) -> Result<Vec<String>, BodyError> {
    data_names("record", value)
}

/// The data names of the comma-separated list in parameter `param`, in order, each once (the
/// recorder's `record`, the Foxglove bridge's `topics`).
pub(crate) fn data_names(param: &str, value: &str) -> Result<Vec<String>, BodyError> {
    let mut names: Vec<String> = Vec::new();
    for name in value
        .split(',')
        .map(str::trim)
        .filter(|name| !name.is_empty())
    {
        if name.chars().any(char::is_whitespace) {
            return Err(format!("parameter `{param}`: `{name}` is not a data name").into());
        }
        if !names.iter().any(|known| known == name) {
            names.push(name.to_owned());
        }
    }
    if names.is_empty() {
        return Err(format!(
            "parameter `{param}` names no data (expected e.g. `sim.odometry,sim.scan`)"
        )
        .into());
    }
    Ok(names)
}

/// Where the `segment`th recording of a run goes: `file` itself, then `NAME-2.EXT`, ...
pub fn segment_path(file: &Path, segment: u32) -> PathBuf {
    if segment <= 1 {
        return file.to_path_buf();
    }
    let stem = file
        .file_stem()
        .map(|stem| stem.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match file.extension() {
        Some(ext) => format!("{stem}-{segment}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{segment}"),
    };
    file.with_file_name(name)
}

/// The file of the next recording after the `segments`th: the first free one of `file`,
/// `NAME-2.EXT`, …, so that a file left by an earlier run (or a crashed one's partial file) is
/// never written over.
fn next_segment(file: &Path, segments: &mut u32) -> PathBuf {
    loop {
        *segments += 1;
        let path = segment_path(file, *segments);
        if !path.exists() && !partial_path(&path).exists() {
            return path;
        }
        tracing::warn!("{} exists: not writing over it", path.display());
    }
}

/// The name a recording has until it is complete.
pub fn partial_path(file: &Path) -> PathBuf {
    let mut name = file.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// How the messages of a data type are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// A JSON object per message, with a JSON Schema (built-in types).
    Json,
    /// The postcard bytes as they travelled (types this recorder does not know).
    Postcard,
    /// The bytes as they travelled, for `Blob`, which is not postcard.
    Raw,
}

impl Encoding {
    /// The channel's message encoding in the MCAP file.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Json => "json",
            Encoding::Postcard => "postcard",
            Encoding::Raw => "raw",
        }
    }
}

/// How samples of `data_type` are stored (but see [`to_json`]: a sample JSON cannot carry
/// exactly is stored as postcard).
pub fn encoding_for(data_type: &str) -> Encoding {
    match data_type {
        "Blob" => Encoding::Raw,
        _ if JSON_TYPES.contains(&data_type) => Encoding::Json,
        _ => Encoding::Postcard,
    }
}

/// The types stored as JSON: the built-in types that postcard encodes.
pub const JSON_TYPES: [&str; 8] = [
    "Counter",
    "Text",
    "Pose2D",
    "Twist",
    "Odometry",
    "LaserScan",
    "OccupancyGrid",
    "Image",
];

#[derive(Serialize, serde::Deserialize, PartialEq)]
struct CounterJson {
    value: u64,
}

#[derive(Serialize, serde::Deserialize, PartialEq)]
struct TextJson {
    text: String,
}

/// The JSON object of a sample of a built-in type: `Ok(None)` for a type stored otherwise, or a
/// value JSON cannot carry exactly (NaN, infinities); an error if the payload does not decode.
pub fn to_json(data_type: &str, payload: &[u8]) -> Result<Option<Vec<u8>>, CodecError> {
    match data_type {
        "Counter" => exact_json(payload, |value: Counter| CounterJson { value: value.0 }),
        "Text" => exact_json(payload, |value: Text| TextJson { text: value.0 }),
        "Pose2D" => exact_json(payload, |value: Pose2D| value),
        "Twist" => exact_json(payload, |value: Twist| value),
        "Odometry" => exact_json(payload, |value: Odometry| value),
        "LaserScan" => exact_json(payload, |value: LaserScan| value),
        "OccupancyGrid" => exact_json(payload, |value: OccupancyGrid| value),
        "Image" => Ok(Some(foxglove::to_json(&Image::decode(payload)?))),
        _ => Ok(None),
    }
}

/// The name of the schema of a sample stored as JSON: the type's, but for an image the
/// Foxglove schema of its encoding.
fn json_schema_name(data_type: &str, payload: &[u8]) -> String {
    match data_type {
        "Image" => Image::decode(payload)
            .map(|image| foxglove::schema_name(image.encoding).to_owned())
            .unwrap_or_default(),
        _ => data_type.to_owned(),
    }
}

/// Decodes a `T`, turns it into its JSON form `J`, and keeps the JSON only if reading it back
/// gives the same value.
fn exact_json<T: Datum, J: Serialize + DeserializeOwned + PartialEq>(
    payload: &[u8],
    to_json: impl FnOnce(T) -> J,
) -> Result<Option<Vec<u8>>, CodecError> {
    let value = to_json(T::decode(payload)?);
    let Ok(bytes) = serde_json::to_vec(&value) else {
        return Ok(None);
    };
    let exact = serde_json::from_slice::<J>(&bytes).is_ok_and(|back| back == value);
    Ok(exact.then_some(bytes))
}

/// The JSON Schema of a built-in type's JSON form (named as [`json_schema_name`] names it),
/// `None` for other types.
pub fn json_schema(data_type: &str) -> Option<serde_json::Value> {
    if let Some(schema) = foxglove::json_schema(data_type) {
        return Some(schema);
    }
    let number = |doc: &str| json!({"type": "number", "description": doc});
    let pose = json!({
        "type": "object",
        "properties": {
            "x_m": number("x, in metres"),
            "y_m": number("y, in metres"),
            "theta_rad": number("heading, counter-clockwise from the x axis, in radians"),
        },
        "required": ["x_m", "y_m", "theta_rad"],
    });
    let twist = json!({
        "type": "object",
        "properties": {
            "linear_mps": number("forward speed, in m/s"),
            "angular_radps": number("turn rate, counter-clockwise, in rad/s"),
        },
        "required": ["linear_mps", "angular_radps"],
    });
    let body = match data_type {
        "Counter" => json!({
            "type": "object",
            "properties": {"value": {"type": "integer", "minimum": 0}},
            "required": ["value"],
        }),
        "Text" => json!({
            "type": "object",
            "properties": {"text": {"type": "string"}},
            "required": ["text"],
        }),
        "Pose2D" => pose.clone(),
        "Twist" => twist.clone(),
        "Odometry" => json!({
            "type": "object",
            "properties": {"pose_in_odom": pose, "twist": twist},
            "required": ["pose_in_odom", "twist"],
        }),
        "LaserScan" => json!({
            "type": "object",
            "properties": {
                "angle_min_rad": number("angle of the first beam, in radians"),
                "angle_increment_rad": number("angle between two beams, in radians"),
                "range_max_m": number("a range of this or more means no echo"),
                "ranges_m": {"type": "array", "items": {"type": "number"}},
            },
            "required": ["angle_min_rad", "angle_increment_rad", "range_max_m", "ranges_m"],
        }),
        "OccupancyGrid" => json!({
            "type": "object",
            "properties": {
                "resolution_m": number("side of a cell, in metres"),
                "width": {"type": "integer", "minimum": 0},
                "height": {"type": "integer", "minimum": 0},
                "origin_x_m": number("x of the lower-left corner of cell (0, 0)"),
                "origin_y_m": number("y of the lower-left corner of cell (0, 0)"),
                "cells": {
                    "type": "array",
                    "description": "row by row: -1 unknown, 0 free ... 100 occupied",
                    "items": {"type": "integer", "minimum": -1, "maximum": 100},
                },
            },
            "required": ["resolution_m", "width", "height", "origin_x_m", "origin_y_m", "cells"],
        }),
        _ => return None,
    };
    let mut schema = json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": data_type,
    });
    if let (Some(schema), serde_json::Value::Object(body)) = (schema.as_object_mut(), body) {
        schema.extend(body);
    }
    Some(schema)
}

/// A file whose flush reaches the disk: the writer flushes once a second, so that a crash of
/// the machine, not only of the process, loses at most the last second.
struct DurableFile(File);

impl Write for DurableFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.sync_data()
    }
}

impl Seek for DurableFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.0.seek(pos)
    }
}

/// One MCAP file being written: created under its partial name, renamed by [`Recording::finish`].
pub struct Recording {
    file: PathBuf,
    partial: PathBuf,
    writer: mcap::Writer<BufWriter<DurableFile>>,
    /// (data name, data type, encoding, schema name, channel id), in the order they were added.
    channels: Vec<(String, String, Encoding, String, u16)>,
    counts: BTreeMap<String, u64>,
    total: u64,
    /// Written since the last flush.
    dirty: bool,
}

impl Recording {
    /// Starts a recording that will be `file` once finished, its chunks compressed with
    /// `compression` (none if `None`).
    pub fn create(file: &Path, compression: Option<mcap::Compression>) -> anyhow::Result<Self> {
        let partial = partial_path(file);
        let handle = File::create(&partial)
            .with_context(|| format!("cannot create {}", partial.display()))?;
        let options = mcap::WriteOptions::new()
            .compression(compression)
            .library(format!("armor-mod-recorder {}", env!("CARGO_PKG_VERSION")))
            // Chunks are small (one per second at most): compress them on this thread.
            .compression_threads(0);
        let writer = options
            .create(BufWriter::new(DurableFile(handle)))
            .with_context(|| format!("cannot write {}", partial.display()))?;
        tracing::info!("recording into {}", partial.display());
        Ok(Self {
            file: file.to_path_buf(),
            partial,
            writer,
            channels: Vec::new(),
            counts: BTreeMap::new(),
            total: 0,
            dirty: false,
        })
    }

    /// How many messages were recorded so far.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Adds a sample of `data_name` as a message at its stamp.
    pub fn write(&mut self, data_name: &str, sample: &RawSample) -> anyhow::Result<()> {
        let mut encoding = encoding_for(&sample.data_type);
        let json = match encoding {
            Encoding::Json => match to_json(&sample.data_type, &sample.payload) {
                Ok(json) => json,
                Err(err) => {
                    tracing::warn!(data_name, "{err}: stored as it came");
                    None
                }
            },
            _ => None,
        };
        if encoding == Encoding::Json && json.is_none() {
            encoding = Encoding::Postcard;
        }
        let schema_name = match encoding {
            Encoding::Json => json_schema_name(&sample.data_type, &sample.payload),
            _ => sample.data_type.clone(),
        };
        let channel_id = self.channel(data_name, &sample.data_type, encoding, &schema_name)?;
        let header = mcap::records::MessageHeader {
            channel_id,
            // MCAP sequences are 32 bits: they wrap.
            sequence: sample.seq as u32,
            log_time: sample.stamp_ns,
            publish_time: sample.stamp_ns,
        };
        let data = json.as_deref().unwrap_or(&sample.payload);
        self.writer
            .write_to_known_channel(&header, data)
            .with_context(|| format!("cannot write {}", self.partial.display()))?;
        match self.counts.get_mut(data_name) {
            Some(count) => *count += 1,
            None => {
                self.counts.insert(data_name.to_owned(), 1);
            }
        }
        self.total += 1;
        self.dirty = true;
        Ok(())
    }

    /// The channel of a data name, type, encoding and schema, added on first use.
    fn channel(
        &mut self,
        data_name: &str,
        data_type: &str,
        encoding: Encoding,
        schema_name: &str,
    ) -> anyhow::Result<u16> {
        if let Some(&(.., id)) = self
            .channels
            .iter()
            .find(|(name, type_name, how, schema, _)| {
                name == data_name
                    && type_name == data_type
                    && *how == encoding
                    && schema == schema_name
            })
        {
            return Ok(id);
        }
        let schema_id = match (encoding, json_schema(schema_name)) {
            _ if data_type.is_empty() => 0,
            (Encoding::Json, Some(schema)) => {
                let schema = serde_json::to_vec(&schema)?;
                self.writer.add_schema(schema_name, "jsonschema", &schema)?
            }
            // No schema language describes these bytes: the schema only names the type.
            _ => self.writer.add_schema(data_type, "", &[])?,
        };
        let metadata = BTreeMap::from([(DATA_TYPE_KEY.to_owned(), data_type.to_owned())]);
        let id = self
            .writer
            .add_channel(schema_id, data_name, encoding.name(), &metadata)?;
        tracing::info!(
            "recording `{data_name}` ({}) as {}",
            if data_type.is_empty() {
                "type unknown"
            } else {
                data_type
            },
            encoding.name()
        );
        self.channels.push((
            data_name.to_owned(),
            data_type.to_owned(),
            encoding,
            schema_name.to_owned(),
            id,
        ));
        Ok(id)
    }

    /// Writes what was recorded so far to the disk (a no-op if nothing new).
    pub fn flush(&mut self) -> anyhow::Result<()> {
        if self.dirty {
            self.writer
                .flush()
                .with_context(|| format!("cannot write {}", self.partial.display()))?;
            self.dirty = false;
        }
        Ok(())
    }

    /// `recorded N messages: name count, ...`
    pub fn progress(&self) -> String {
        let counts: Vec<String> = self
            .counts
            .iter()
            .map(|(name, count)| format!("{name} {count}"))
            .collect();
        let counts = if counts.is_empty() {
            String::new()
        } else {
            format!(": {}", counts.join(", "))
        };
        format!("recorded {} messages{counts}", self.total)
    }

    /// Completes the file (summary and index) and renames it into place; returns its path.
    pub fn finish(self) -> anyhow::Result<PathBuf> {
        let progress = self.progress();
        let Self {
            file: path,
            partial,
            mut writer,
            ..
        } = self;
        let context = || format!("cannot complete {}", partial.display());
        writer.finish().with_context(context)?;
        let DurableFile(file) = writer
            .into_inner()
            .into_inner()
            .map_err(|err| anyhow::Error::new(err.into_error()).context(context()))?;
        file.sync_all().with_context(context)?;
        drop(file);
        std::fs::rename(&partial, &path).with_context(|| {
            format!("cannot rename {} to {}", partial.display(), path.display())
        })?;
        let folder = match path.parent() {
            Some(folder) if !folder.as_os_str().is_empty() => folder,
            _ => Path::new("."),
        };
        if let Ok(folder) = File::open(folder) {
            // Makes the rename itself durable, where the platform can.
            let _ = folder.sync_all();
        }
        tracing::info!("saved {}: {progress}", path.display());
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use armor_module_api::types::Blob;

    fn sample<T: Datum>(seq: u64, stamp_ns: u64, value: &T) -> RawSample {
        let mut payload = Vec::new();
        value.encode(&mut payload).expect("encode");
        RawSample {
            seq,
            stamp_ns,
            link: 1,
            data_type: T::TYPE.to_owned(),
            payload,
        }
    }

    /// Every message of a file: (topic, encoding, schema name, schema encoding, data type
    /// metadata, log time, data).
    type Row = (String, String, String, String, String, u64, Vec<u8>);

    fn read_back(file: &Path) -> Vec<Row> {
        let bytes = std::fs::read(file).expect("read");
        assert!(
            mcap::Summary::read(&bytes).expect("summary").is_some(),
            "a finished file has its summary"
        );
        mcap::MessageStream::new(&bytes)
            .expect("mcap")
            .map(|message| {
                let message = message.expect("message");
                let channel = &message.channel;
                let (schema, schema_encoding) = channel
                    .schema
                    .as_ref()
                    .map(|schema| (schema.name.clone(), schema.encoding.clone()))
                    .unwrap_or_default();
                (
                    channel.topic.clone(),
                    channel.message_encoding.clone(),
                    schema,
                    schema_encoding,
                    channel.metadata[DATA_TYPE_KEY].clone(),
                    message.log_time,
                    message.data.into_owned(),
                )
            })
            .collect()
    }

    #[test]
    fn built_in_types_are_json_blob_raw_others_postcard() {
        for json_type in JSON_TYPES {
            assert_eq!(encoding_for(json_type), Encoding::Json, "{json_type}");
            // An image's schema is Foxglove's for its encoding.
            let schema_names = match json_type {
                "Image" => vec![foxglove::RAW_IMAGE, foxglove::COMPRESSED_IMAGE],
                _ => vec![json_type],
            };
            for name in schema_names {
                let schema = json_schema(name).expect("schema");
                assert_eq!(schema["title"], name);
                assert_eq!(schema["type"], "object");
            }
        }
        assert_eq!(encoding_for("Blob"), Encoding::Raw);
        assert_eq!(encoding_for("Imu"), Encoding::Postcard);
        assert_eq!(encoding_for(""), Encoding::Postcard);
    }

    #[test]
    fn json_forms_are_objects_named_as_in_the_protocol() {
        let json = |data_type: &str, payload: &[u8]| -> serde_json::Value {
            let bytes = to_json(data_type, payload).expect("decodes").expect("json");
            serde_json::from_slice(&bytes).expect("valid json")
        };
        let counter = sample(1, 0, &Counter(300));
        assert_eq!(json("Counter", &counter.payload), json!({"value": 300}));
        let text = sample(1, 0, &Text("héllo".into()));
        assert_eq!(json("Text", &text.payload), json!({"text": "héllo"}));
        let odometry = Odometry {
            pose_in_odom: Pose2D {
                x_m: 1.5,
                y_m: -2.0,
                theta_rad: 0.1,
            },
            twist: Twist {
                linear_mps: 0.3,
                angular_radps: 0.0,
            },
        };
        let odometry = sample(1, 0, &odometry);
        assert_eq!(
            json("Odometry", &odometry.payload)["pose_in_odom"]["theta_rad"],
            0.1
        );
        assert_eq!(to_json("Imu", &[1, 2]).expect("no decoding"), None);
        assert!(to_json("Counter", &[]).is_err(), "a truncated payload");
    }

    #[test]
    fn every_finite_pose_is_stored_as_json() {
        // Doubles of every magnitude: serde_json reads each back to the same bits (with its
        // `float_roundtrip`, which the workspace turns on), so none falls back to postcard.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            state
        };
        for _ in 0..5_000 {
            let unit = (next() >> 11) as f64 / (1u64 << 53) as f64;
            let pose = Pose2D {
                x_m: unit * 100.0 - 50.0,
                // Any finite positive double below 2.
                y_m: f64::from_bits(next() >> 2),
                theta_rad: (unit - 0.5) * std::f64::consts::TAU,
            };
            let payload = sample(1, 0, &pose).payload;
            assert!(
                to_json("Pose2D", &payload).expect("decodes").is_some(),
                "{pose:?} is not stored as JSON"
            );
        }
    }

    #[test]
    fn a_value_json_cannot_carry_exactly_is_not_json() {
        let scan = LaserScan {
            angle_min_rad: -1.0,
            angle_increment_rad: 0.01,
            range_max_m: 8.0,
            ranges_m: vec![1.25, f32::INFINITY],
        };
        let scan = sample(1, 0, &scan);
        assert_eq!(to_json("LaserScan", &scan.payload).expect("decodes"), None);
        let pose = sample(
            1,
            0,
            &Pose2D {
                x_m: f64::NAN,
                ..Pose2D::default()
            },
        );
        assert_eq!(to_json("Pose2D", &pose.payload).expect("decodes"), None);
    }

    #[test]
    fn images_are_stored_in_foxglove_schemas_by_encoding() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("cam.mcap");
        let mut recording = Recording::create(&file, None).expect("create");
        let mut image = Image {
            width: 2,
            height: 1,
            encoding: armor_module_api::types::ImageEncoding::Rgb8,
            stamp_ns: 2_000_000_001,
            frame_id: "camera".into(),
            data: vec![1, 2, 3, 4, 5, 6].into(),
        };
        recording
            .write("cam.image", &sample(1, 10, &image))
            .expect("write");
        image.encoding = armor_module_api::types::ImageEncoding::Jpeg;
        image.data = vec![0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 0, 1, 0, 2, 3].into();
        recording
            .write("cam.image", &sample(2, 20, &image))
            .expect("write");
        recording.finish().expect("finish");
        let rows = read_back(&file);
        let kinds: Vec<_> = rows
            .iter()
            .map(|row| (&*row.0, &*row.1, &*row.2, &*row.3, &*row.4))
            .collect();
        assert_eq!(
            kinds,
            [
                (
                    "cam.image",
                    "json",
                    "foxglove.RawImage",
                    "jsonschema",
                    "Image"
                ),
                (
                    "cam.image",
                    "json",
                    "foxglove.CompressedImage",
                    "jsonschema",
                    "Image"
                ),
            ]
        );
        let raw: serde_json::Value = serde_json::from_slice(&rows[0].6).expect("json");
        assert_eq!(raw["data"], "AQIDBAUG");
        assert_eq!(raw["timestamp"], json!({"sec": 2, "nsec": 1}));
        let compressed: serde_json::Value = serde_json::from_slice(&rows[1].6).expect("json");
        assert_eq!(compressed["format"], "jpeg");
    }

    #[test]
    fn the_file_has_a_channel_per_data_name_and_is_renamed_when_finished() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let mut recording =
            Recording::create(&file, Some(mcap::Compression::Zstd)).expect("create");
        assert!(partial_path(&file).exists());
        assert!(!file.exists(), "not in place before it is complete");
        recording
            .write("counter.count", &sample(1, 1_000, &Counter(1)))
            .expect("write");
        recording
            .write("counter.count", &sample(2, 2_000, &Counter(2)))
            .expect("write");
        let imu = RawSample {
            seq: 1,
            stamp_ns: 1_500,
            link: 1,
            data_type: "Imu".into(),
            payload: vec![1, 2, 3],
        };
        recording.write("imu.data", &imu).expect("write");
        recording
            .write("cam.jpeg", &sample(1, 1_700, &Blob(vec![0xFF, 0xD8])))
            .expect("write");
        let infinite = LaserScan {
            ranges_m: vec![f32::INFINITY],
            ..LaserScan::default()
        };
        let infinite = sample(1, 1_800, &infinite);
        recording.write("sim.scan", &infinite).expect("write");
        recording.flush().expect("flush");
        assert_eq!(recording.total(), 5);
        assert_eq!(
            recording.progress(),
            "recorded 5 messages: cam.jpeg 1, counter.count 2, imu.data 1, sim.scan 1"
        );
        assert_eq!(recording.finish().expect("finish"), file);
        assert!(!partial_path(&file).exists());

        let rows = read_back(&file);
        let row = |topic: &str, index: usize| {
            rows.iter()
                .filter(|row| row.0 == topic)
                .nth(index)
                .cloned()
                .expect("row")
        };
        let first = row("counter.count", 0);
        assert_eq!(
            (&*first.1, &*first.2, &*first.3, &*first.4, first.5),
            ("json", "Counter", "jsonschema", "Counter", 1_000)
        );
        assert_eq!(first.6, br#"{"value":1}"#);
        assert_eq!(row("counter.count", 1).6, br#"{"value":2}"#);
        let imu = row("imu.data", 0);
        assert_eq!(
            (&*imu.1, &*imu.2, &*imu.3, &*imu.4, imu.5, imu.6),
            ("postcard", "Imu", "", "Imu", 1_500, vec![1, 2, 3])
        );
        let blob = row("cam.jpeg", 0);
        assert_eq!(
            (&*blob.1, &*blob.4, blob.6),
            ("raw", "Blob", vec![0xFF, 0xD8])
        );
        let scan = row("sim.scan", 0);
        assert_eq!(
            (&*scan.1, &*scan.4, scan.6),
            ("postcard", "LaserScan", infinite.payload)
        );
    }

    #[test]
    fn a_flushed_recording_can_be_read_before_it_is_finished() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let mut recording = Recording::create(&file, None).expect("create");
        for value in 1..=3 {
            recording
                .write("counter.count", &sample(value, value * 10, &Counter(value)))
                .expect("write");
        }
        recording.flush().expect("flush");
        // What a crash now would leave: the partial file, without summary or end magic.
        let bytes = std::fs::read(partial_path(&file)).expect("read");
        let options = mcap::read::Options::IgnoreEndMagic.into();
        let messages: Vec<u64> = mcap::MessageStream::new_with_options(&bytes, options)
            .expect("mcap")
            .map_while(Result::ok)
            .map(|message| message.log_time)
            .collect();
        assert_eq!(messages, [10, 20, 30]);
        drop(recording);
    }

    #[test]
    fn segment_and_partial_names() {
        let file = Path::new("/data/run.mcap");
        assert_eq!(segment_path(file, 1), file);
        assert_eq!(segment_path(file, 3), Path::new("/data/run-3.mcap"));
        assert_eq!(segment_path(Path::new("log"), 2), Path::new("log-2"));
        assert_eq!(partial_path(file), Path::new("/data/run.mcap.partial"));
    }

    #[test]
    fn record_lists_are_checked_and_deduplicated() {
        assert_eq!(
            parse_record(" sim.odometry, sim.scan,,sim.odometry ").expect("ok"),
            ["sim.odometry", "sim.scan"]
        );
        assert!(parse_record(" , ").is_err());
        assert!(parse_record("a b").is_err());
    }

    fn bench(file: &Path, params: &[(&str, &str)]) -> TestBench {
        let file = file.to_str().expect("utf-8 path");
        let mut all = vec![("record", "counter.count,other.text"), ("file", file)];
        all.extend_from_slice(params);
        TestBench::new(&spec(), &all).expect("bench")
    }

    fn push(value: u64) -> Step {
        Step::push("counter.count", &Counter(value)).expect("step")
    }

    fn recorded_payloads(file: &Path) -> Vec<Vec<u8>> {
        read_back(file).into_iter().map(|row| row.6).collect()
    }

    #[test]
    fn records_only_while_active_and_saves_each_active_stretch() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let mut bench = bench(&file, &[("compression", "lz4")]);
        bench.script([
            push(1),
            push(2),
            Step::Timeouts(1),
            Step::Active(false),
            push(3),
            Step::Active(true),
            push(4),
        ]);
        body(bench.node()).expect("body");
        // On a bench the type is unknown (no agent): the bytes are kept as they came.
        assert_eq!(recorded_payloads(&file), [vec![1], vec![2]]);
        assert_eq!(recorded_payloads(&dir.path().join("run-2.mcap")), [vec![4]]);
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .map(|entry| entry.expect("entry").file_name())
            .collect();
        assert_eq!(left.len(), 2, "no partial file left: {left:?}");
    }

    #[test]
    fn a_new_file_is_used_from_the_next_start() {
        let dir = tempfile::tempdir().expect("dir");
        let first = dir.path().join("run.mcap");
        let second = dir.path().join("leg.mcap");
        let mut bench = bench(&first, &[]);
        bench.script([
            push(1),
            Step::Active(false),
            Step::param("file", second.to_str().expect("utf-8")),
            push(2),
            Step::Active(true),
            push(3),
        ]);
        body(bench.node()).expect("body");
        assert_eq!(recorded_payloads(&first), [vec![1]]);
        // The new file's first segment, not `leg-2.mcap`.
        assert_eq!(recorded_payloads(&second), [vec![3]]);
    }

    #[test]
    fn a_file_left_by_an_earlier_run_is_never_written_over() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        std::fs::write(&file, b"an earlier run").expect("write");
        std::fs::write(partial_path(&dir.path().join("run-2.mcap")), b"a crash").expect("write");
        let mut bench = bench(&file, &[]);
        bench.script([push(1), Step::Active(false), Step::Active(true), push(2)]);
        body(bench.node()).expect("body");
        assert_eq!(std::fs::read(&file).expect("read"), b"an earlier run");
        assert_eq!(recorded_payloads(&dir.path().join("run-3.mcap")), [vec![1]]);
        assert_eq!(recorded_payloads(&dir.path().join("run-4.mcap")), [vec![2]]);
    }

    #[test]
    fn a_recorder_started_inactive_writes_nothing_until_started() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let mut bench = bench(&file, &[]);
        // Inactive from the start (the Stop event this queues finds nothing to save).
        bench.set_active(false);
        bench.script([push(1), Step::Timeouts(1)]);
        body(bench.node()).expect("body");
        assert!(std::fs::read_dir(dir.path()).expect("dir").next().is_none());
    }

    #[test]
    fn a_termination_request_saves_the_file() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let mut bench = bench(&file, &[]);
        bench.script([push(1), Step::Timeouts(5)]);
        let terminate = AtomicBool::new(false);
        let node = bench.node();
        // The flag is set before the body starts: it saves an empty file at once.
        terminate.store(true, Ordering::Relaxed);
        body_until(node, &terminate).expect("body");
        assert!(file.exists());
        assert!(recorded_payloads(&file).is_empty());
    }

    #[test]
    fn refuses_missing_or_bad_parameters() {
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("run.mcap");
        let cases: [(&[(&str, &str)], &str); 5] = [
            (&[("file", "x.mcap")], "`record` is required"),
            (&[("record", "a.b")], "`file` is required"),
            (
                &[("record", "a.b"), ("file", "x"), ("format", "bag")],
                "`format`",
            ),
            (
                &[("record", "a.b"), ("file", "x"), ("compression", "gzip")],
                "`compression`",
            ),
            (
                &[("record", "a.b"), ("file", "x"), ("report_secs", "-1")],
                "`report_secs`",
            ),
        ];
        for (params, expected) in cases {
            let mut bench = TestBench::new(&spec(), params).expect("bench");
            let err = body(bench.node()).expect_err("must refuse");
            assert!(err.to_string().contains(expected), "{err}");
        }
        let mut bench = bench(&dir.path().join("missing/run.mcap"), &[]);
        bench.script([push(1)]);
        let err = body(bench.node()).expect_err("no folder");
        assert!(err.to_string().contains("cannot create"), "{err}");
        assert!(!file.exists());
    }
}

//! `foxglove`: the run's live data in Foxglove, over Foxglove's WebSocket protocol.
//!
//! The module subscribes to the data names in `topics` as the studio's live views do (best
//! effort, at most `max_rate_hz` samples a second of each, whatever its type), and serves them
//! with the official `foxglove` crate's WebSocket server, one channel per data name (the
//! channel's topic is the data name), in Foxglove's own schemas (protobuf), which its 3D, Image
//! and Raw Messages panels show:
//!
//! | ArMoR type | Foxglove schema | frame |
//! | --- | --- | --- |
//! | `Pose2D` | `foxglove.PoseInFrame` | `map` |
//! | `Odometry` | `foxglove.Odometry` (pose and velocity) | `map` |
//! | `PoseEstimate` | `foxglove.Odometry` (pose and its covariance; state and fit as metadata) | `map` |
//! | `LaserScan` | `foxglove.LaserScan` (no echo: infinite) | `base_link` |
//! | `OccupancyGrid` | `foxglove.Grid` (one `int8` field, `occupancy`: -1 unknown, 0 to 100) | `map` |
//! | `Image` | `foxglove.CompressedImage` (JPEG) or `foxglove.RawImage` (`rgb8`, `mono8`) | the camera's |
//! | `Markers` | `foxglove.SceneUpdate` (an entity per frame, living one second of run time) | `map`, `base_link` |
//! | `Text` named `….path` | `foxglove.PosesInFrame` (the follower's `X,Y X,Y …`) | `map` |
//! | any other built-in type | JSON with a JSON Schema, as the recorder stores it | |
//!
//! With `robot_pose` naming one of the poses, each of its samples also goes out as a
//! `foxglove.FrameTransform` from `map` to `base_link` on the topic `/tf`, so that the scan and
//! the robot's markers are drawn where the robot is. Messages are stamped with the sample's run
//! time.
//!
//! Foxglove's protocol has no authentication: whoever reaches the port reads every topic. So
//! the module listens on loopback only (`listen`, by default Foxglove's own 127.0.0.1:8765) and
//! refuses any other address, with or without the run's secret; from another computer, reach it
//! through an SSH tunnel (`docs/foxglove.md`). It logs `foxglove listening on ws://ADDR` and
//! tells the supervisor that address (its `foxglove` endpoint, shown by `armor ctl status`).

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use armor_module_api::types::{
    Frame, Image, ImageEncoding, LaserScan, Marker, Markers, OccupancyGrid, Odometry, Pose2D,
    PoseEstimate, Shape, Text,
};
use armor_module_api::{
    BodyResult, Datum, Event, ModuleSpec, Node, ParamSpec, ParamType, RawInput,
};
use foxglove::schemas::{
    ArrowPrimitive, Color, CompressedImage, FrameTransform, Grid, KeyValuePair, LinePrimitive,
    PackedElementField, Point3, Pose, PoseInFrame, PosesInFrame, Quaternion, RawImage, SceneEntity,
    SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp, Vector2, Vector3, line_primitive,
    packed_element_field,
};
use foxglove::{Channel, Context, RawChannel, Schema, WebSocketServer};

use crate::BodyError;

pub const TYPE: &str = "foxglove";
/// The endpoint the module says it listens at (`docs/protocol.md`, section 4.2).
pub const ENDPOINT: &str = "foxglove";
/// The frame of the world (the map's) in Foxglove.
pub const MAP_FRAME: &str = "map";
/// The robot's frame in Foxglove.
pub const ROBOT_FRAME: &str = "base_link";
/// The topic of the robot's transforms, with `robot_pose`.
pub const TRANSFORMS_TOPIC: &str = "/tf";
/// How long a module's markers stay in Foxglove's scene without a new sample (run time): a
/// module that stops drawing (the observer, done) leaves nothing behind.
const MARKER_LIFETIME_SECS: i32 = 1;
/// A point marker's diameter, in metres (ArMoR gives sizes in screen points, Foxglove's spheres
/// are in metres).
const POINT_DIAMETER_M: f64 = 0.1;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Serves the run's live data to Foxglove over its WebSocket protocol, on loopback only: \
         each data name in `topics` as a channel in Foxglove's schemas (poses, the estimate \
         with its covariance, scans, maps, images, markers, paths).",
    )
    .category(armor_module_api::Category::Recording)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .param(ParamSpec::new(
        "topics",
        ParamType::String,
        "the data names to serve, comma-separated (e.g. `sim.pose_truth,localiser.estimate,\
         sim.scan,camera.image,follower.markers,follower.path`); read at start only",
    ))
    .param(
        ParamSpec::new(
            "listen",
            ParamType::String,
            "where Foxglove connects: a loopback address and port (port 0: any free port, logged \
             as `foxglove listening on ws://ADDR`); any other address is refused, since \
             Foxglove's protocol has no authentication; read at start only",
        )
        .default("127.0.0.1:8765"),
    )
    .param(
        ParamSpec::new(
            "robot_pose",
            ParamType::String,
            "a data name among `topics` whose pose places the robot (`base_link`) on the map, \
             sent as transforms on `/tf` (empty: none); read at start only",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "max_rate_hz",
            ParamType::Float,
            "at most this many samples a second of each data name (greater than 0); read at \
             start only",
        )
        .above(0.0)
        .unit("Hz")
        .default("30"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let settings = Settings::read(node)?;
    let context = Context::new();
    let server = WebSocketServer::new()
        .name(format!("ArMoR {}", node.name()))
        .context(&context)
        .bind(settings.listen.ip().to_string(), settings.listen.port())
        .start_blocking()
        .map_err(|err| format!("cannot listen on `{}`: {err}", settings.listen))?;
    let addr = SocketAddr::new(settings.listen.ip(), server.port());
    tracing::info!("foxglove listening on ws://{addr}");
    node.set_endpoint(ENDPOINT, &addr.to_string());
    let mut inputs: Vec<(RawInput, String)> = Vec::new();
    for name in &settings.topics {
        inputs.push((
            node.subscribe_raw_at_most(name, settings.max_rate_hz)?,
            name.clone(),
        ));
    }
    let mut bridge = Bridge::new(context, settings.robot_pose);
    loop {
        match node.next_event(Some(Duration::from_millis(200)))? {
            Event::Input(port) => {
                let Some((input, name)) = inputs.iter().find(|(input, _)| input.id() == port)
                else {
                    continue;
                };
                while let Some(sample) = node.take_raw(input) {
                    bridge.publish(name, &sample.data_type, sample.stamp_ns, &sample.payload);
                }
            }
            Event::ParamsChanged(names) => {
                for name in names {
                    tracing::warn!("a new `{name}` takes effect when the module is restarted");
                }
            }
            Event::Shutdown => break,
            _ => {}
        }
    }
    // Its clients are told the server is going; the process ends right after.
    server.stop().detach_all();
    Ok(())
}

/// The module's parameters, checked.
#[derive(Clone, Debug, PartialEq)]
struct Settings {
    topics: Vec<String>,
    listen: SocketAddr,
    robot_pose: Option<String>,
    max_rate_hz: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        let topics = crate::recorder::data_names("topics", &node.param::<String>("topics")?)?;
        let listen = loopback(node.param::<String>("listen")?.trim())?;
        let robot_pose = node.param::<String>("robot_pose")?.trim().to_owned();
        let robot_pose = if robot_pose.is_empty() {
            None
        } else if topics.contains(&robot_pose) {
            Some(robot_pose)
        } else {
            return Err(format!(
                "`robot_pose` = `{robot_pose}` is not among `topics` ({})",
                topics.join(", ")
            )
            .into());
        };
        Ok(Self {
            topics,
            listen,
            robot_pose,
            max_rate_hz: node.param::<f64>("max_rate_hz")?,
        })
    }
}

/// `listen` as a loopback address: Foxglove's clients cannot authenticate, so nothing else.
fn loopback(listen: &str) -> Result<SocketAddr, BodyError> {
    let addr: SocketAddr = listen.parse().map_err(|_| {
        format!("`listen` = `{listen}` is not an address and port such as 127.0.0.1:8765")
    })?;
    if !addr.ip().is_loopback() {
        return Err(format!(
            "`listen` = `{listen}` is not a loopback address: Foxglove's WebSocket protocol has \
             no authentication, so the bridge listens on 127.0.0.1 or ::1 only (from another \
             computer, forward the port over SSH: `ssh -L 8765:127.0.0.1:8765 ROBOT`)"
        )
        .into());
    }
    Ok(addr)
}

/// One topic's channel, in the schema its data type is served in.
enum Publisher {
    Pose(Channel<PoseInFrame>),
    Odometry(Channel<foxglove::schemas::Odometry>),
    Estimate(Channel<foxglove::schemas::Odometry>),
    Scan(Channel<foxglove::schemas::LaserScan>),
    Grid(Channel<Grid>),
    Image {
        compressed: Option<Channel<CompressedImage>>,
        raw: Option<Channel<RawImage>>,
    },
    Markers(Channel<SceneUpdate>),
    Path(Channel<PosesInFrame>),
    /// With the data type, which says how to write it as JSON.
    Json(Arc<RawChannel>, String),
    /// A type with no Foxglove form (said once, when its first sample came).
    Nothing,
}

/// The channels, opened as each topic's first sample tells its type.
struct Bridge {
    context: Arc<Context>,
    publishers: BTreeMap<String, Publisher>,
    robot_pose: Option<String>,
    transforms: Channel<FrameTransform>,
}

impl Bridge {
    fn new(context: Arc<Context>, robot_pose: Option<String>) -> Self {
        let transforms = context
            .channel_builder(TRANSFORMS_TOPIC)
            .build::<FrameTransform>();
        Self {
            context,
            publishers: BTreeMap::new(),
            robot_pose,
            transforms,
        }
    }

    fn open(&self, name: &str, data_type: &str, payload: &[u8]) -> Publisher {
        let builder = || self.context.channel_builder(name);
        let is_path = name.rsplit('.').next() == Some("path");
        match data_type {
            "Pose2D" => Publisher::Pose(builder().build()),
            "Odometry" => Publisher::Odometry(builder().build()),
            "PoseEstimate" => Publisher::Estimate(builder().build()),
            "LaserScan" => Publisher::Scan(builder().build()),
            "OccupancyGrid" => Publisher::Grid(builder().build()),
            "Image" => Publisher::Image {
                compressed: None,
                raw: None,
            },
            "Markers" => Publisher::Markers(builder().build()),
            "Text" if is_path => Publisher::Path(builder().build()),
            _ => match crate::recorder::json_schema(data_type) {
                Some(schema) if crate::recorder::to_json(data_type, payload).is_ok() => {
                    let schema =
                        Schema::new(data_type, "jsonschema", schema.to_string().into_bytes());
                    match builder()
                        .message_encoding("json")
                        .schema(schema)
                        .build_raw()
                    {
                        Ok(channel) => Publisher::Json(channel, data_type.to_owned()),
                        Err(err) => {
                            tracing::error!("`{name}`: cannot open its channel: {err}");
                            Publisher::Nothing
                        }
                    }
                }
                _ => {
                    tracing::warn!("`{name}`: no Foxglove form for the type `{data_type}`");
                    Publisher::Nothing
                }
            },
        }
    }

    /// Serves one sample of `name`; one that cannot be decoded is logged and skipped.
    fn publish(&mut self, name: &str, data_type: &str, stamp_ns: u64, payload: &[u8]) {
        if !self.publishers.contains_key(name) {
            let publisher = self.open(name, data_type, payload);
            self.publishers.insert(name.to_owned(), publisher);
        }
        let Some(publisher) = self.publishers.get_mut(name) else {
            return;
        };
        let stamp = timestamp(stamp_ns);
        let robot = match publish(publisher, &self.context, name, stamp, payload) {
            Ok(robot) => robot,
            Err(err) => {
                tracing::warn!("`{name}`: a sample not served: {err}");
                return;
            }
        };
        if let Some(robot) = robot
            && self.robot_pose.as_deref() == Some(name)
        {
            self.transforms
                .log_with_time(&robot_transform(robot, stamp), stamp_ns);
        }
    }
}

/// Serves `payload` on `publisher`; the pose in it, when it has one.
fn publish(
    publisher: &mut Publisher,
    context: &Arc<Context>,
    name: &str,
    stamp: Timestamp,
    payload: &[u8],
) -> Result<Option<Pose2D>, BodyError> {
    let time = stamp.total_nanos();
    match publisher {
        Publisher::Pose(channel) => {
            let pose = Pose2D::decode(payload)?;
            channel.log_with_time(&pose_in_frame(pose, stamp), time);
            return Ok(Some(pose));
        }
        Publisher::Odometry(channel) => {
            let odometry = Odometry::decode(payload)?;
            channel.log_with_time(&odometry_message(&odometry, stamp), time);
            return Ok(Some(odometry.pose_in_odom));
        }
        Publisher::Estimate(channel) => {
            let estimate = PoseEstimate::decode(payload)?;
            channel.log_with_time(&estimate_message(&estimate, stamp), time);
            return Ok(Some(estimate.pose_in_map));
        }
        Publisher::Scan(channel) => {
            channel.log_with_time(&scan_message(&LaserScan::decode(payload)?, stamp), time);
        }
        Publisher::Grid(channel) => {
            channel.log_with_time(&grid_message(&OccupancyGrid::decode(payload)?, stamp), time);
        }
        Publisher::Image { compressed, raw } => {
            let image = Image::decode(payload)?;
            let stamp = timestamp(image.stamp_ns);
            match image.encoding {
                ImageEncoding::Jpeg => compressed
                    .get_or_insert_with(|| context.channel_builder(name).build())
                    .log_with_time(&compressed_image(&image, stamp), time),
                ImageEncoding::Rgb8 | ImageEncoding::Mono8 => raw
                    .get_or_insert_with(|| context.channel_builder(name).build())
                    .log_with_time(&raw_image(&image, stamp)?, time),
            }
        }
        Publisher::Markers(channel) => {
            channel.log_with_time(&scene_update(name, &Markers::decode(payload)?, stamp), time);
        }
        Publisher::Path(channel) => {
            channel.log_with_time(&path_message(&Text::decode(payload)?.0, stamp)?, time);
        }
        Publisher::Json(channel, data_type) => {
            if let Some(json) = crate::recorder::to_json(data_type, payload)? {
                channel.log_with_meta(&json, foxglove::PartialMetadata::with_log_time(time));
            }
        }
        Publisher::Nothing => {}
    }
    Ok(None)
}

/// A run-time stamp in nanoseconds as Foxglove's.
pub fn timestamp(stamp_ns: u64) -> Timestamp {
    let secs = u32::try_from(stamp_ns / 1_000_000_000).unwrap_or(u32::MAX);
    // Below a billion, so it fits.
    let nanos = (stamp_ns % 1_000_000_000) as u32;
    Timestamp::new(secs, nanos)
}

/// A rotation about the vertical axis by `heading_rad`.
fn yaw(heading_rad: f64) -> Quaternion {
    let half = heading_rad / 2.0;
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: half.sin(),
        w: half.cos(),
    }
}

/// A pose in the plane, at height 0.
fn pose(x_m: f64, y_m: f64, heading_rad: f64) -> Pose {
    Pose {
        position: Some(Vector3 {
            x: x_m,
            y: y_m,
            z: 0.0,
        }),
        orientation: Some(yaw(heading_rad)),
    }
}

pub fn pose_in_frame(value: Pose2D, stamp: Timestamp) -> PoseInFrame {
    PoseInFrame {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_owned(),
        pose: Some(pose(value.x_m, value.y_m, value.theta_rad)),
    }
}

pub fn odometry_message(value: &Odometry, stamp: Timestamp) -> foxglove::schemas::Odometry {
    let at = value.pose_in_odom;
    foxglove::schemas::Odometry {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_owned(),
        body_frame_id: ROBOT_FRAME.to_owned(),
        pose: Some(pose(at.x_m, at.y_m, at.theta_rad)),
        linear_velocity: Some(Vector3 {
            x: value.twist.linear_mps,
            y: 0.0,
            z: 0.0,
        }),
        angular_velocity: Some(Vector3 {
            x: 0.0,
            y: 0.0,
            z: value.twist.angular_radps,
        }),
        pose_covariance: Vec::new(),
        velocity_covariance: Vec::new(),
        metadata: Vec::new(),
    }
}

/// The estimate as Foxglove's odometry: its pose, and its (x, y, heading) covariance placed in
/// the 6×6 matrix of (x, y, z, roll, pitch, yaw), the rest zero (unknown).
pub fn estimate_message(value: &PoseEstimate, stamp: Timestamp) -> foxglove::schemas::Odometry {
    let at = value.pose_in_map;
    let mut covariance = vec![0.0; 36];
    let index = [0, 1, 5];
    for (row, six_row) in index.iter().enumerate() {
        for (col, six_col) in index.iter().enumerate() {
            covariance[six_row * 6 + six_col] = value.covariance[row * 3 + col];
        }
    }
    let entry = |key: &str, value: String| KeyValuePair {
        key: key.to_owned(),
        value,
    };
    foxglove::schemas::Odometry {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_owned(),
        body_frame_id: ROBOT_FRAME.to_owned(),
        pose: Some(pose(at.x_m, at.y_m, at.theta_rad)),
        linear_velocity: None,
        angular_velocity: None,
        pose_covariance: covariance,
        velocity_covariance: Vec::new(),
        metadata: vec![
            entry("state", value.state.as_str().to_owned()),
            entry("fit", value.fit.to_string()),
        ],
    }
}

/// The scan in the robot's frame; a beam without an echo reads as infinitely far.
pub fn scan_message(value: &LaserScan, stamp: Timestamp) -> foxglove::schemas::LaserScan {
    let beams = value.ranges_m.len();
    let end_angle =
        value.angle_min_rad + value.angle_increment_rad * beams.saturating_sub(1) as f64;
    foxglove::schemas::LaserScan {
        timestamp: Some(stamp),
        frame_id: ROBOT_FRAME.to_owned(),
        pose: Some(pose(0.0, 0.0, 0.0)),
        start_angle: value.angle_min_rad,
        end_angle,
        ranges: value
            .ranges_m
            .iter()
            .map(|&range| {
                let range = f64::from(range);
                if range >= value.range_max_m {
                    f64::INFINITY
                } else {
                    range
                }
            })
            .collect(),
        intensities: Vec::new(),
    }
}

/// The grid as one `int8` field per cell, rows from the origin up, as ours.
pub fn grid_message(value: &OccupancyGrid, stamp: Timestamp) -> Grid {
    Grid {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_owned(),
        pose: Some(pose(value.origin_x_m, value.origin_y_m, 0.0)),
        column_count: value.width,
        cell_size: Some(Vector2 {
            x: value.resolution_m,
            y: value.resolution_m,
        }),
        row_stride: value.width,
        cell_stride: 1,
        fields: vec![PackedElementField {
            name: "occupancy".to_owned(),
            offset: 0,
            r#type: packed_element_field::NumericType::Int8 as i32,
        }],
        data: value
            .cells
            .iter()
            .map(|&cell| cell.to_ne_bytes()[0])
            .collect(),
    }
}

pub fn compressed_image(value: &Image, stamp: Timestamp) -> CompressedImage {
    CompressedImage {
        timestamp: Some(stamp),
        frame_id: value.frame_id.clone(),
        data: value.data.to_vec().into(),
        format: "jpeg".to_owned(),
    }
}

pub fn raw_image(value: &Image, stamp: Timestamp) -> Result<RawImage, BodyError> {
    let bytes_per_pixel = value.encoding.bytes_per_pixel().unwrap_or(1);
    let step = u32::try_from(bytes_per_pixel)
        .ok()
        .and_then(|bytes| bytes.checked_mul(value.width))
        .ok_or("an image too wide to serve")?;
    Ok(RawImage {
        timestamp: Some(stamp),
        frame_id: value.frame_id.clone(),
        width: value.width,
        height: value.height,
        encoding: value.encoding.name().to_owned(),
        step,
        data: value.data.to_vec().into(),
    })
}

fn color(rgba: [u8; 4]) -> Color {
    let channel = |value: u8| f64::from(value) / 255.0;
    Color {
        r: channel(rgba[0]),
        g: channel(rgba[1]),
        b: channel(rgba[2]),
        a: channel(rgba[3]),
    }
}

fn point(at: &armor_module_api::types::MarkerPoint) -> Point3 {
    Point3 {
        x: f64::from(at.x_m),
        y: f64::from(at.y_m),
        z: 0.0,
    }
}

/// A module's markers as a scene update: one entity for those in the world's frame and one for
/// those in the robot's (ids `NAME/map` and `NAME/base_link`), each replacing the previous
/// sample's and gone after a second of run time without a new one.
pub fn scene_update(name: &str, value: &Markers, stamp: Timestamp) -> SceneUpdate {
    let entity = |frame_id: &str| SceneEntity {
        timestamp: Some(stamp),
        frame_id: frame_id.to_owned(),
        id: format!("{name}/{frame_id}"),
        lifetime: Some(foxglove::schemas::Duration::new(MARKER_LIFETIME_SECS, 0)),
        frame_locked: true,
        ..SceneEntity::default()
    };
    let mut world = entity(MAP_FRAME);
    let mut robot = entity(ROBOT_FRAME);
    for marker in &value.markers {
        let entity = match marker.frame {
            Frame::World => &mut world,
            Frame::Robot => &mut robot,
        };
        add_marker(entity, marker);
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![world, robot],
    }
}

fn add_marker(entity: &mut SceneEntity, marker: &Marker) {
    let rgba = color(marker.rgba);
    let line = |kind: line_primitive::Type, points: Vec<Point3>| LinePrimitive {
        r#type: kind as i32,
        pose: Some(pose(0.0, 0.0, 0.0)),
        thickness: f64::from(marker.size_px.max(1.0)),
        scale_invariant: true,
        points,
        color: Some(rgba),
        ..LinePrimitive::default()
    };
    match marker.shape {
        Shape::Points => entity
            .spheres
            .extend(marker.points.iter().map(|at| SpherePrimitive {
                pose: Some(pose(f64::from(at.x_m), f64::from(at.y_m), 0.0)),
                size: Some(Vector3 {
                    x: POINT_DIAMETER_M,
                    y: POINT_DIAMETER_M,
                    z: POINT_DIAMETER_M,
                }),
                color: Some(rgba),
            })),
        Shape::Polyline => entity.lines.push(line(
            line_primitive::Type::LineStrip,
            marker.points.iter().map(point).collect(),
        )),
        Shape::Polygon => entity.lines.push(line(
            line_primitive::Type::LineLoop,
            marker.points.iter().map(point).collect(),
        )),
        Shape::Arrows => entity
            .arrows
            .extend(marker.points.chunks_exact(2).map(|pair| {
                let (from, to) = (point(&pair[0]), point(&pair[1]));
                let length = (to.x - from.x).hypot(to.y - from.y);
                ArrowPrimitive {
                    pose: Some(pose(from.x, from.y, (to.y - from.y).atan2(to.x - from.x))),
                    shaft_length: length * 0.75,
                    shaft_diameter: 0.03,
                    head_length: length * 0.25,
                    head_diameter: 0.08,
                    color: Some(rgba),
                }
            })),
        Shape::Text => {
            if let Some(at) = marker.points.first() {
                entity.texts.push(TextPrimitive {
                    pose: Some(pose(f64::from(at.x_m), f64::from(at.y_m), 0.0)),
                    billboard: true,
                    font_size: 14.0,
                    scale_invariant: true,
                    color: Some(rgba),
                    text: marker.text.clone(),
                });
            }
        }
    }
}

/// The follower's path (`X,Y X,Y …`, metres) as poses, each heading to the next.
pub fn path_message(text: &str, stamp: Timestamp) -> Result<PosesInFrame, BodyError> {
    let mut points = Vec::new();
    for word in text.split_whitespace() {
        let parsed = word.split_once(',').and_then(|(x, y)| {
            let (x, y) = (x.parse::<f64>().ok()?, y.parse::<f64>().ok()?);
            (x.is_finite() && y.is_finite()).then_some((x, y))
        });
        points.push(parsed.ok_or_else(|| format!("`{word}` is not a point `X,Y` of a path"))?);
    }
    let poses = points
        .iter()
        .enumerate()
        .map(|(at, &(x, y))| {
            let heading = match (
                points.get(at + 1),
                at.checked_sub(1).map(|before| points[before]),
            ) {
                (Some(&(next_x, next_y)), _) => (next_y - y).atan2(next_x - x),
                (None, Some((before_x, before_y))) => (y - before_y).atan2(x - before_x),
                (None, None) => 0.0,
            };
            pose(x, y, heading)
        })
        .collect();
    Ok(PosesInFrame {
        timestamp: Some(stamp),
        frame_id: MAP_FRAME.to_owned(),
        poses,
    })
}

/// Where the robot is on the map, as the transform from `map` to `base_link`.
pub fn robot_transform(robot: Pose2D, stamp: Timestamp) -> FrameTransform {
    FrameTransform {
        timestamp: Some(stamp),
        parent_frame_id: MAP_FRAME.to_owned(),
        child_frame_id: ROBOT_FRAME.to_owned(),
        translation: Some(Vector3 {
            x: robot.x_m,
            y: robot.y_m,
            z: 0.0,
        }),
        rotation: Some(yaw(robot.theta_rad)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use armor_module_api::types::{LocalisationState, MarkerPoint};

    fn stamp() -> Timestamp {
        timestamp(12_500_000_000)
    }

    #[test]
    fn stamps_are_split_into_seconds_and_nanoseconds() {
        assert_eq!(stamp(), Timestamp::new(12, 500_000_000));
        assert_eq!(timestamp(u64::MAX).sec(), u32::MAX);
    }

    #[test]
    fn a_pose_is_placed_in_the_map_turned_about_the_vertical() {
        let message = pose_in_frame(
            Pose2D {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: std::f64::consts::FRAC_PI_2,
            },
            stamp(),
        );
        assert_eq!(message.frame_id, "map");
        let pose = message.pose.unwrap_or_default();
        let position = pose.position.unwrap_or_default();
        assert_eq!((position.x, position.y), (1.0, 2.0));
        let rotation = pose.orientation.unwrap_or_default();
        assert!((rotation.z - 0.5f64.sqrt()).abs() < 1e-12, "{rotation:?}");
        assert!((rotation.w - 0.5f64.sqrt()).abs() < 1e-12, "{rotation:?}");
    }

    #[test]
    fn the_estimates_covariance_goes_to_x_y_and_yaw() {
        let estimate = PoseEstimate {
            pose_in_map: Pose2D::default(),
            covariance: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
            fit: 0.75,
            state: LocalisationState::Localised,
            proven: true,
        };
        let message = estimate_message(&estimate, stamp());
        let c = &message.pose_covariance;
        assert_eq!(c.len(), 36);
        assert_eq!((c[0], c[1], c[5]), (1.0, 2.0, 3.0));
        assert_eq!((c[6], c[7], c[11]), (4.0, 5.0, 6.0));
        assert_eq!((c[30], c[31], c[35]), (7.0, 8.0, 9.0));
        assert_eq!(c.iter().filter(|value| **value != 0.0).count(), 9);
        assert_eq!(message.metadata[0].value, "localised");
    }

    #[test]
    fn a_beam_without_echo_is_infinite_and_the_angles_span_the_beams() {
        let scan = LaserScan {
            angle_min_rad: -1.0,
            angle_increment_rad: 0.5,
            range_max_m: 10.0,
            ranges_m: vec![1.0, 10.0, 2.5, 30.0, 0.5],
        };
        let message = scan_message(&scan, stamp());
        assert_eq!(message.frame_id, "base_link");
        assert_eq!((message.start_angle, message.end_angle), (-1.0, 1.0));
        assert_eq!(
            message.ranges,
            [1.0, f64::INFINITY, 2.5, f64::INFINITY, 0.5]
        );
    }

    #[test]
    fn a_grid_keeps_its_cells_rows_and_origin() {
        let grid = OccupancyGrid {
            resolution_m: 0.5,
            width: 3,
            height: 2,
            origin_x_m: -1.0,
            origin_y_m: 4.0,
            cells: vec![-1, 0, 100, 50, 0, -1],
        };
        let message = grid_message(&grid, stamp());
        assert_eq!(
            (
                message.column_count,
                message.row_stride,
                message.cell_stride
            ),
            (3, 3, 1)
        );
        assert_eq!(message.data.as_ref(), [255, 0, 100, 50, 0, 255]);
        let origin = message
            .pose
            .unwrap_or_default()
            .position
            .unwrap_or_default();
        assert_eq!((origin.x, origin.y), (-1.0, 4.0));
    }

    #[test]
    fn markers_go_to_an_entity_per_frame_with_their_shapes() {
        let at = |x_m, y_m| MarkerPoint { x_m, y_m };
        let marker = |shape, frame, points: Vec<MarkerPoint>| Marker {
            shape,
            frame,
            rgba: [255, 0, 0, 255],
            size_px: 2.0,
            points,
            text: "goal".to_owned(),
        };
        let markers = Markers {
            markers: vec![
                marker(
                    Shape::Polyline,
                    Frame::World,
                    vec![at(0.0, 0.0), at(1.0, 0.0)],
                ),
                marker(Shape::Text, Frame::World, vec![at(1.0, 1.0)]),
                marker(
                    Shape::Arrows,
                    Frame::Robot,
                    vec![at(0.0, 0.0), at(0.0, 2.0)],
                ),
                marker(
                    Shape::Points,
                    Frame::Robot,
                    vec![at(1.0, 0.0), at(2.0, 0.0)],
                ),
                marker(
                    Shape::Polygon,
                    Frame::World,
                    vec![at(0.0, 0.0), at(1.0, 0.0), at(0.0, 1.0)],
                ),
            ],
        };
        let update = scene_update("follower.markers", &markers, stamp());
        let [world, robot] = &update.entities[..] else {
            panic!("{update:?}");
        };
        assert_eq!(
            (world.id.as_str(), world.frame_id.as_str()),
            ("follower.markers/map", "map")
        );
        assert_eq!(robot.frame_id, "base_link");
        assert_eq!(world.lines.len(), 2);
        assert_eq!(world.texts[0].text, "goal");
        assert_eq!(robot.spheres.len(), 2);
        let arrow = &robot.arrows[0];
        assert!((arrow.shaft_length + arrow.head_length - 2.0).abs() < 1e-9);
    }

    #[test]
    fn a_path_is_read_into_poses_and_garbage_is_refused() {
        let path = path_message("0,0 3,0 3,4", stamp()).unwrap_or_default();
        assert_eq!(path.poses.len(), 3);
        let heading = |pose: &Pose| {
            let rotation = pose.orientation.unwrap_or_default();
            2.0 * rotation.z.atan2(rotation.w)
        };
        assert!(heading(&path.poses[0]).abs() < 1e-12);
        assert!((heading(&path.poses[2]) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        for garbage in ["1,2 3", "a,b", "1,NaN"] {
            let err = path_message(garbage, stamp())
                .err()
                .map(|err| err.to_string());
            assert!(
                err.is_some_and(|err| err.contains("is not a point")),
                "{garbage}"
            );
        }
    }

    #[test]
    fn refuses_to_listen_beyond_loopback_and_bad_settings() {
        for (params, expected) in [
            (
                vec![("topics", "sim.scan"), ("listen", "0.0.0.0:8765")],
                "is not a loopback address",
            ),
            (
                vec![("topics", "sim.scan"), ("listen", "10.0.0.2:0")],
                "no authentication",
            ),
            (
                vec![("topics", "sim.scan"), ("listen", "localhost")],
                "is not an address and port",
            ),
            (vec![("topics", " , ")], "names no data"),
            (
                vec![("topics", "sim.scan"), ("robot_pose", "sim.pose_truth")],
                "is not among `topics`",
            ),
        ] {
            let mut bench = TestBench::new(&spec(), &params).unwrap_or_else(|err| panic!("{err}"));
            let err = body(bench.node()).err().map(|err| err.to_string());
            assert!(
                err.as_deref().is_some_and(|err| err.contains(expected)),
                "{params:?}: {err:?}"
            );
        }
    }

    #[test]
    fn listens_on_loopback_and_tells_the_supervisor_where() {
        let mut bench = TestBench::new(
            &spec(),
            &[("topics", "sim.scan,sim.scan"), ("listen", "127.0.0.1:0")],
        )
        .unwrap_or_else(|err| panic!("{err}"));
        bench.script([Step::Timeouts(1)]);
        let result = body(bench.node());
        assert!(result.is_ok(), "{result:?}");
        let endpoints = bench.endpoints();
        let port = endpoints
            .first()
            .and_then(|endpoint| endpoint.strip_prefix("foxglove 127.0.0.1:"))
            .and_then(|port| port.parse::<u16>().ok());
        assert!(port.is_some_and(|port| port > 0), "{endpoints:?}");
    }
}

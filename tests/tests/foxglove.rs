//! Live data in Foxglove (issue 37): a simulated run with the `foxglove` module serves its
//! poses, the localiser's estimate with its covariance, the scan, the mapper's grid, the
//! camera, the follower's markers and path, and the robot's transform, over Foxglove's
//! WebSocket protocol on loopback. The test is a protocol client written from the protocol's
//! specification (subprotocol `foxglove.sdk.v1`, which the `foxglove` crate's server speaks:
//! `foxglove.websocket.v1` renamed; JSON `serverInfo` and `advertise`, `subscribe`, binary
//! `messageData` frames): it subscribes to every channel and decodes each message in the schema
//! its channel advertises.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use armor_tests::{PATIENCE, ctl_status, run_with_control, wait_until, workspace_root};
use foxglove::Decode;
use foxglove::schemas::{
    CompressedImage, FrameTransform, Grid, LaserScan, Odometry, PoseInFrame, PosesInFrame,
    SceneUpdate,
};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// Every topic the run serves, with the schema it must be advertised in.
const TOPICS: [(&str, &str); 8] = [
    ("sim.pose_truth", "foxglove.PoseInFrame"),
    ("localiser.estimate", "foxglove.Odometry"),
    ("sim.scan", "foxglove.LaserScan"),
    ("mapper.map", "foxglove.Grid"),
    ("camera.image", "foxglove.CompressedImage"),
    ("follower.markers", "foxglove.SceneUpdate"),
    ("follower.path", "foxglove.PosesInFrame"),
    ("/tf", "foxglove.FrameTransform"),
];

/// The bundled robot system of the yard (`missions/robot/system.xml`), its files given by
/// their full paths, its follower given a path as a compiled plan gives it (it then publishes
/// the path it follows), with a mapper and the bridge added.
fn system(dir: &Path) -> PathBuf {
    let world = workspace_root().join("assets/worlds/yard.world");
    let topics: Vec<&str> = TOPICS
        .iter()
        .map(|(topic, _)| *topic)
        .filter(|topic| !topic.starts_with('/'))
        .collect();
    let added = format!(
        r#"  <module name="mapper" type="mapper"/>
  <module name="fox" type="foxglove">
    <param name="topics" value="{}"/>
    <param name="listen" value="127.0.0.1:0"/>
    <param name="robot_pose" value="sim.pose_truth"/>
  </module>
  <link from="sim.odometry" to="mapper.odometry"/>
  <link from="sim.scan" to="mapper.scan"/>
</system>"#,
        topics.join(",")
    );
    let mut text =
        std::fs::read_to_string(workspace_root().join("missions/robot/system.xml")).unwrap();
    for (from, to) in [
        (
            r#"value="yard.world""#.to_owned(),
            format!(r#"value="{}""#, world.display()),
        ),
        (
            r#"value="truth.mcap""#.to_owned(),
            format!(r#"value="{}""#, dir.join("truth.mcap").display()),
        ),
        (
            r#"<param name="goal_y_m" value="4"/>"#.to_owned(),
            r#"<param name="goal_y_m" value="4"/><param name="path" value="4,4 16,4"/>"#.to_owned(),
        ),
        ("</system>".to_owned(), added),
    ] {
        assert!(text.contains(&from), "system.xml has no `{from}`");
        text = text.replace(&from, &to);
    }
    let file = dir.join("foxglove.xml");
    std::fs::write(&file, text).unwrap();
    file
}

/// A channel the server advertised.
#[derive(Debug)]
struct Channel {
    topic: String,
    encoding: String,
    schema_name: String,
}

/// A client of Foxglove's WebSocket protocol, as Foxglove Studio connects.
struct Client {
    socket: WebSocket<TcpStream>,
    channels: BTreeMap<u64, Channel>,
    /// Subscription id → channel id.
    subscriptions: BTreeMap<u32, u64>,
}

impl Client {
    fn connect(addr: &str) -> Client {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(PATIENCE)).unwrap();
        let mut request = format!("ws://{addr}").into_client_request().unwrap();
        request
            .headers_mut()
            .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
        let (socket, response) = tungstenite::client(request, stream).unwrap();
        assert_eq!(
            response.headers()["Sec-WebSocket-Protocol"],
            "foxglove.sdk.v1"
        );
        // Short reads from here on, so that new channels are subscribed to between messages.
        socket
            .get_ref()
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        Client {
            socket,
            channels: BTreeMap::new(),
            subscriptions: BTreeMap::new(),
        }
    }

    /// The next message within a short wait: a JSON one is taken in (`advertise`), a binary
    /// one returned as (channel, payload).
    fn next(&mut self) -> Option<(u64, Vec<u8>)> {
        let message = match self.socket.read() {
            Ok(message) => message,
            Err(tungstenite::Error::Io(err))
                if matches!(
                    err.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return None;
            }
            Err(err) => panic!("the bridge's socket failed: {err}"),
        };
        match message {
            Message::Text(text) => {
                let json: serde_json::Value = serde_json::from_str(&text).unwrap();
                // The crate's server sends an advertisement before it records the channel as
                // advertised to this client (foxglove 0.30.3, `advertise_channels`): a client
                // that subscribes at once may be told the channel is unknown. It is there a
                // moment later, so subscribe again.
                if json["op"] == "status"
                    && let Some(channel) = json["message"]
                        .as_str()
                        .and_then(|message| message.strip_prefix("Unknown channel ID: "))
                        .and_then(|id| id.parse::<u64>().ok())
                {
                    self.subscriptions.retain(|_, known| *known != channel);
                }
                if json["op"] == "advertise" {
                    for channel in json["channels"].as_array().unwrap() {
                        self.channels.insert(
                            channel["id"].as_u64().unwrap(),
                            Channel {
                                topic: channel["topic"].as_str().unwrap().to_owned(),
                                encoding: channel["encoding"].as_str().unwrap().to_owned(),
                                schema_name: channel["schemaName"].as_str().unwrap().to_owned(),
                            },
                        );
                    }
                }
                None
            }
            Message::Binary(data) => {
                // messageData: opcode 1, subscription id (u32), log time (u64), payload.
                assert!(data.len() >= 13, "a binary message of {} bytes", data.len());
                assert_eq!(data[0], 1, "opcode");
                let subscription = u32::from_le_bytes(data[1..5].try_into().unwrap());
                let channel = self.subscriptions[&subscription];
                Some((channel, data[13..].to_vec()))
            }
            _ => None,
        }
    }

    fn subscribe(&mut self, channel: u64) {
        let id = self.subscriptions.keys().max().map_or(1, |last| last + 1);
        self.subscriptions.insert(id, channel);
        let request = serde_json::json!({
            "op": "subscribe",
            "subscriptions": [{"id": id, "channelId": channel}],
        });
        self.socket
            .send(Message::text(request.to_string()))
            .unwrap();
    }
}

/// What one message says, decoded in its schema, in words for the assertions.
fn decode(schema: &str, payload: &[u8]) -> String {
    match schema {
        "foxglove.PoseInFrame" => {
            let pose = PoseInFrame::decode(payload).unwrap();
            let position = pose.pose.unwrap().position.unwrap();
            assert_eq!(pose.frame_id, "map");
            assert!(position.x.is_finite() && position.y.is_finite());
            format!("pose at ({:.2}, {:.2})", position.x, position.y)
        }
        "foxglove.Odometry" => {
            let estimate = Odometry::decode(payload).unwrap();
            assert_eq!(estimate.pose_covariance.len(), 36);
            let (x, y) = (estimate.pose_covariance[0], estimate.pose_covariance[7]);
            assert!(x > 0.0 && y > 0.0, "variances {x}, {y}");
            format!("estimate with variances {x:.4}, {y:.4}")
        }
        "foxglove.LaserScan" => {
            let scan = LaserScan::decode(payload).unwrap();
            assert_eq!(scan.frame_id, "base_link");
            assert!(scan.ranges.iter().any(|range| range.is_finite()));
            format!("scan of {} beams", scan.ranges.len())
        }
        "foxglove.Grid" => {
            let grid = Grid::decode(payload).unwrap();
            assert!(grid.column_count > 0);
            assert_eq!(grid.data.len() % grid.column_count as usize, 0);
            assert!(grid.data.iter().any(|cell| *cell as i8 > 50), "no wall");
            format!("grid of {} columns", grid.column_count)
        }
        "foxglove.CompressedImage" => {
            let image = CompressedImage::decode(payload).unwrap();
            assert_eq!(image.format, "jpeg");
            assert_eq!(image.data[..2], [0xFF, 0xD8], "a JPEG file");
            format!("jpeg of {} bytes", image.data.len())
        }
        "foxglove.SceneUpdate" => {
            let update = SceneUpdate::decode(payload).unwrap();
            let primitives: usize = update
                .entities
                .iter()
                .map(|entity| entity.lines.len() + entity.spheres.len() + entity.texts.len())
                .sum();
            assert!(primitives > 0, "{update:?}");
            format!("scene of {primitives} primitives")
        }
        "foxglove.PosesInFrame" => {
            let path = PosesInFrame::decode(payload).unwrap();
            assert!(path.poses.len() >= 2, "{path:?}");
            format!("path of {} poses", path.poses.len())
        }
        "foxglove.FrameTransform" => {
            let transform = FrameTransform::decode(payload).unwrap();
            assert_eq!(
                (
                    transform.parent_frame_id.as_str(),
                    transform.child_frame_id.as_str()
                ),
                ("map", "base_link")
            );
            "transform map → base_link".to_owned()
        }
        other => panic!("an unexpected schema {other}"),
    }
}

#[test]
fn a_foxglove_client_subscribes_to_and_decodes_every_channel_of_a_live_run() {
    let dir = tempfile::tempdir().unwrap();
    let (run, control) = run_with_control(&system(dir.path()));
    let mut endpoint = None;
    wait_until("the bridge's endpoint in the status", PATIENCE, || {
        let status = ctl_status(&control);
        endpoint = status["modules"].as_array().and_then(|modules| {
            modules
                .iter()
                .find(|module| module["name"] == "fox" && module["state"] == "running")
                .and_then(|module| module["endpoints"]["foxglove"].as_str())
                .map(str::to_owned)
        });
        endpoint.is_some()
    });
    let endpoint = endpoint.unwrap();
    assert!(endpoint.starts_with("127.0.0.1:"), "{endpoint}");

    let mut client = Client::connect(&endpoint);
    let mut decoded: BTreeMap<String, String> = BTreeMap::new();
    let mut received: BTreeMap<String, usize> = BTreeMap::new();
    let deadline = Instant::now() + PATIENCE * 2;
    while decoded.len() < TOPICS.len() {
        if Instant::now() > deadline {
            let bridge: Vec<String> = run
                .lines()
                .into_iter()
                .filter(|line| line.starts_with("[fox]") || line.starts_with("[localiser]"))
                .collect();
            panic!(
                "decoded only {decoded:#?} (messages: {received:?}); advertised {:#?}; the \
                 bridge and the localiser said {bridge:#?}",
                client.channels
            );
        }
        // Channels are advertised as their first sample comes: subscribe to each new one.
        let new: Vec<u64> = client
            .channels
            .keys()
            .filter(|id| !client.subscriptions.values().any(|known| known == *id))
            .copied()
            .collect();
        for channel in new {
            client.subscribe(channel);
        }
        let Some((channel, payload)) = client.next() else {
            continue;
        };
        let channel = &client.channels[&channel];
        let Some((_, schema)) = TOPICS.iter().find(|(topic, _)| *topic == channel.topic) else {
            panic!("a channel not asked for: {channel:?}");
        };
        assert_eq!(channel.schema_name, *schema, "{channel:?}");
        assert_eq!(channel.encoding, "protobuf", "{channel:?}");
        let what = decode(schema, &payload);
        *received.entry(channel.topic.clone()).or_default() += 1;
        decoded.entry(channel.topic.clone()).or_insert(what);
    }
    eprintln!("decoded: {decoded:#?}\nmessages: {received:?}");
    drop(run);
}

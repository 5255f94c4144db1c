//! Data types carried on ports. A type's name is what links are checked against; its encoding is
//! postcard (a documented, compact serde format) unless the type says otherwise, as [`Blob`] does.

use serde::{Deserialize, Serialize};

mod image;
pub use image::{Image, ImageEncoding, Pixels};

#[derive(Debug, thiserror::Error)]
#[error("cannot {action} {data_type}: {reason}")]
pub struct CodecError {
    pub action: &'static str,
    pub data_type: &'static str,
    pub reason: String,
}

/// A value that can travel on a port.
pub trait Datum: Sized {
    /// The data type name declared on ports, e.g. `Counter`.
    const TYPE: &'static str;
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError>;
    fn decode(bytes: &[u8]) -> Result<Self, CodecError>;
    /// Decodes from a buffer the value may keep (no copy for byte payloads).
    fn decode_owned(bytes: Vec<u8>) -> Result<Self, CodecError> {
        Self::decode(&bytes)
    }
    /// For a type whose encoding ends in bytes it holds as they are (a `Blob`'s, an `Image`'s
    /// pixels): appends the encoding before them to `head` and returns them, so that a large
    /// value is sent from its own memory, not copied into a frame first.
    fn split_encoding(&self, _head: &mut Vec<u8>) -> Option<&[u8]> {
        None
    }
}

/// Implements [`Datum`] with postcard for serde types.
#[macro_export]
macro_rules! postcard_datum {
    ($ty:ty, $name:literal) => {
        impl $crate::types::Datum for $ty {
            const TYPE: &'static str = $name;
            fn encode(&self, out: &mut Vec<u8>) -> Result<(), $crate::types::CodecError> {
                $crate::types::postcard_encode(self, out, $name)
            }
            fn decode(bytes: &[u8]) -> Result<Self, $crate::types::CodecError> {
                $crate::types::postcard_decode(bytes, $name)
            }
        }
    };
}

pub fn postcard_encode<T: Serialize>(
    value: &T,
    out: &mut Vec<u8>,
    data_type: &'static str,
) -> Result<(), CodecError> {
    let extended = postcard::to_extend(value, std::mem::take(out));
    match extended {
        Ok(bytes) => {
            *out = bytes;
            Ok(())
        }
        Err(err) => Err(CodecError {
            action: "encode",
            data_type,
            reason: err.to_string(),
        }),
    }
}

pub fn postcard_decode<T: for<'de> Deserialize<'de>>(
    bytes: &[u8],
    data_type: &'static str,
) -> Result<T, CodecError> {
    postcard::from_bytes(bytes).map_err(|err| CodecError {
        action: "decode",
        data_type,
        reason: err.to_string(),
    })
}

/// A sequence number, as published by the `counter` module.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counter(pub u64);
postcard_datum!(Counter, "Counter");

/// A battery's state: what is left of its charge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Battery {
    /// From 1 (full) to 0 (empty).
    pub charge: f64,
}
postcard_datum!(Battery, "Battery");

/// A line of text.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Text(pub String);
postcard_datum!(Text, "Text");

/// Opaque bytes, sent as they are (no encoding step, so large payloads cost one copy).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blob(pub Vec<u8>);

impl Datum for Blob {
    const TYPE: &'static str = "Blob";
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        out.extend_from_slice(&self.0);
        Ok(())
    }
    fn decode(bytes: &[u8]) -> Result<Self, CodecError> {
        Ok(Blob(bytes.to_vec()))
    }
    fn decode_owned(bytes: Vec<u8>) -> Result<Self, CodecError> {
        Ok(Blob(bytes))
    }
    fn split_encoding(&self, _head: &mut Vec<u8>) -> Option<&[u8]> {
        Some(&self.0)
    }
}

/// A pose in the plane. Which frame it is in (world, odometry, map) is said by the port's name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose2D {
    pub x_m: f64,
    pub y_m: f64,
    /// Heading, counter-clockwise from the x axis.
    pub theta_rad: f64,
}
postcard_datum!(Pose2D, "Pose2D");

/// A velocity command or measurement of a differential-drive robot, in the robot's frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    pub linear_mps: f64,
    pub angular_radps: f64,
}
postcard_datum!(Twist, "Twist");

/// Dead-reckoned pose and velocity (drifts with distance and rotation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    pub pose_in_odom: Pose2D,
    pub twist: Twist,
}
postcard_datum!(Odometry, "Odometry");

/// How much a localiser trusts its estimate (the thresholds are the localiser's, stated in its
/// description).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum LocalisationState {
    Localised,
    #[default]
    Uncertain,
    Lost,
}

impl LocalisationState {
    pub fn as_str(self) -> &'static str {
        match self {
            LocalisationState::Localised => "localised",
            LocalisationState::Uncertain => "uncertain",
            LocalisationState::Lost => "lost",
        }
    }
}

/// A pose estimated on a map, with its uncertainty: the covariance of (x, y, heading), row by
/// row (m², m·rad, rad²), how well the latest scan fits the map there (0 to 1: the mean of the
/// likelihood field at the beams' ends), the localiser's state, and whether the estimate is
/// proven: a localiser that searched the map, or suspects the robot was carried, says `false`
/// until the estimate held while the robot drove or turned on it (`docs/localisation.md`);
/// a follower does not drive on an estimate that is not proven.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseEstimate {
    pub pose_in_map: Pose2D,
    pub covariance: [f64; 9],
    pub fit: f64,
    pub state: LocalisationState,
    /// Absent from estimates written before it existed (recordings, JSON): such an estimate
    /// reads as proven, since everything then drove on every estimate.
    #[serde(default = "proven_when_absent")]
    pub proven: bool,
}

fn proven_when_absent() -> bool {
    true
}

/// A [`PoseEstimate`] as it was encoded before `proven` (its fields, in order, without it).
#[derive(Deserialize)]
struct PoseEstimateBeforeProven {
    pose_in_map: Pose2D,
    covariance: [f64; 9],
    fit: f64,
    state: LocalisationState,
}

impl Datum for PoseEstimate {
    const TYPE: &'static str = "PoseEstimate";
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        postcard_encode(self, out, Self::TYPE)
    }
    /// Today's encoding, or one written before `proven` (an old recording): that one ends
    /// after `state`, exactly, and reads as proven. postcard is not self-describing, so the
    /// old layout is tried only when today's runs out of bytes, and must use every byte.
    fn decode(bytes: &[u8]) -> Result<Self, CodecError> {
        let current = postcard_decode::<Self>(bytes, Self::TYPE);
        if current.is_ok() {
            return current;
        }
        match postcard::take_from_bytes::<PoseEstimateBeforeProven>(bytes) {
            Ok((old, [])) => Ok(Self {
                pose_in_map: old.pose_in_map,
                covariance: old.covariance,
                fit: old.fit,
                state: old.state,
                proven: true,
            }),
            _ => current,
        }
    }
}

impl PoseEstimate {
    /// The covariance of independent errors: `sigma_m` in x and in y, `sigma_rad` in heading.
    pub fn diagonal_covariance(sigma_m: f64, sigma_rad: f64) -> [f64; 9] {
        let (position, heading) = (sigma_m * sigma_m, sigma_rad * sigma_rad);
        [
            position, 0.0, 0.0, //
            0.0, position, 0.0, //
            0.0, 0.0, heading,
        ]
    }

    /// The standard deviation of the position along its most uncertain axis (the square root
    /// of the largest eigenvalue of the covariance's position block).
    pub fn position_sigma_m(&self) -> f64 {
        let c = &self.covariance;
        let (a, b, d) = (c[0], c[1], c[4]);
        let half_trace = (a + d) / 2.0;
        let spread = (((a - d) / 2.0).powi(2) + b * b).sqrt();
        let largest = half_trace + spread;
        if largest.is_finite() {
            largest.max(0.0).sqrt()
        } else {
            f64::INFINITY
        }
    }
}

/// One sweep of a planar laser scanner. Beam `i` points at `angle_min_rad + i ×
/// angle_increment_rad` in the robot's frame; a range of `range_max_m` or more means no echo.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    pub range_max_m: f64,
    pub ranges_m: Vec<f32>,
}
postcard_datum!(LaserScan, "LaserScan");

/// An occupancy grid: cell `(col, row)` is `cells[row × width + col]`, covering the square of
/// side `resolution_m` whose lower-left corner is at `origin + (col, row) × resolution_m`.
/// Values: -1 unknown, 0 free … 100 occupied.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    pub resolution_m: f64,
    pub width: u32,
    pub height: u32,
    pub origin_x_m: f64,
    pub origin_y_m: f64,
    pub cells: Vec<i8>,
}
postcard_datum!(OccupancyGrid, "OccupancyGrid");

/// One report of the run's health stream (`armor.health`, see [`crate::protocol::HEALTH`]):
/// what happened to a module, when, and why.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Health {
    /// The module it is about.
    pub module: String,
    /// `failed` (its process ended or its connection closed), `stalled` (it answered no ping
    /// for a lease), `restarting`, `recovered` (configured and at work again), `gave_up` (no
    /// more restarts), `switched` (one of its inputs moved to another source).
    pub kind: String,
    /// In words: `was killed by signal 9`, `follower.odometry: mapper.pose → sim.odometry`.
    pub reason: String,
    /// Run time of the report, in nanoseconds.
    pub at_ns: u64,
}
postcard_datum!(Health, "Health");
/// What a module draws of its own view on the Run view's map: points, polylines, polygons,
/// arrows and text, each in the world frame or the robot's, with its colour. By convention a
/// module publishes them on an output named `markers`; the map draws each module's in a layer
/// of its own.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Markers {
    pub markers: Vec<Marker>,
}
postcard_datum!(Markers, "Markers");

/// One drawing: its `points` read as [`Shape`] says, in `frame`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    pub shape: Shape,
    pub frame: Frame,
    /// Red, green, blue, opacity.
    pub rgba: [u8; 4],
    /// Line width, or a point's diameter, in screen points.
    pub size_px: f32,
    pub points: Vec<MarkerPoint>,
    /// What a [`Shape::Text`] says (drawn at its first point); a label for the others.
    pub text: String,
}

/// A point of a marker, in metres in its frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerPoint {
    pub x_m: f32,
    pub y_m: f32,
}

/// How a marker's points are drawn (encoded as its index: 0 points … 4 text).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Shape {
    /// Each point a dot.
    #[default]
    Points,
    /// The points joined in order.
    Polyline,
    /// The points joined and closed, filled faintly.
    Polygon,
    /// Each pair of points an arrow from the first to the second.
    Arrows,
    /// `text` at the first point.
    Text,
}

/// The frame a marker's points are in (encoded as its index: 0 world, 1 robot).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Frame {
    /// The world (the map's) frame.
    #[default]
    World,
    /// The robot's: x ahead, y to its left, drawn from the robot's pose.
    Robot,
}

impl Marker {
    /// A marker of `shape` in `frame` through `points` (x, y in metres).
    pub fn new(
        shape: Shape,
        frame: Frame,
        rgba: [u8; 4],
        points: impl IntoIterator<Item = (f64, f64)>,
    ) -> Self {
        Self {
            shape,
            frame,
            rgba,
            size_px: 2.0,
            points: points
                .into_iter()
                .map(|(x, y)| MarkerPoint {
                    x_m: x as f32,
                    y_m: y as f32,
                })
                .collect(),
            text: String::new(),
        }
    }

    pub fn with_text(mut self, text: &str) -> Self {
        self.text = text.to_owned();
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn postcard_types_round_trip_and_reject_truncation() {
        let mut out = Vec::new();
        Text("héllo".into()).encode(&mut out).expect("encode");
        assert_eq!(Text::decode(&out).expect("decode"), Text("héllo".into()));
        assert!(Text::decode(&out[..3]).is_err());
        let mut out = vec![9];
        Counter(300).encode(&mut out).expect("encode");
        assert_eq!(
            out,
            [9, 0xAC, 0x02],
            "appends a varint after what was there"
        );
    }

    #[test]
    fn a_hostile_length_fails_without_allocating_what_it_claims() {
        // A sequence of u64::MAX elements (varint), then nothing: serde preallocates at most
        // what the bytes left can hold (postcard's size hint), so decoding fails at the end of
        // the input instead of asking for 2^64 elements, which would abort with a capacity
        // overflow.
        let huge_len = [0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01];
        let mut grid = Vec::new();
        grid.extend(0.5_f64.to_le_bytes()); // resolution
        grid.extend([0xFF, 0xFF, 0xFF, 0xFF, 0x0F]); // width: u32::MAX
        grid.extend([0xFF, 0xFF, 0xFF, 0xFF, 0x0F]); // height: u32::MAX
        grid.extend([0; 16]); // origin
        grid.extend(huge_len);
        let err = OccupancyGrid::decode(&grid).expect_err("too short");
        assert!(err.to_string().contains("OccupancyGrid"), "{err}");
        let mut scan = vec![0; 24]; // angles and maximum range
        scan.extend(huge_len);
        scan.extend([0; 64]);
        assert!(LaserScan::decode(&scan).is_err());
        assert!(Text::decode(&huge_len).is_err());
    }

    /// A recording made before `proven` existed still reads: postcard ends after `state` and
    /// JSON has no `proven`; either reads as proven, as every estimate was then taken.
    #[test]
    fn a_pose_estimate_written_before_proven_reads_as_proven() {
        let estimate = PoseEstimate {
            pose_in_map: Pose2D {
                x_m: 1.5,
                y_m: -2.0,
                theta_rad: 0.25,
            },
            covariance: PoseEstimate::diagonal_covariance(0.1, 0.05),
            fit: 0.8,
            state: LocalisationState::Lost,
            proven: false,
        };
        let mut out = Vec::new();
        estimate.encode(&mut out).expect("encode");
        assert_eq!(PoseEstimate::decode(&out).expect("decode"), estimate);
        assert_eq!(out.last(), Some(&0), "proven: false, one byte, last");
        let old = &out[..out.len() - 1];
        assert_eq!(
            PoseEstimate::decode(old).expect("the old layout"),
            PoseEstimate {
                proven: true,
                ..estimate
            }
        );
        // Shorter still is broken, in either layout, and said so.
        let err = PoseEstimate::decode(&old[..old.len() - 1]).expect_err("truncated");
        assert!(err.to_string().contains("PoseEstimate"), "{err}");
        let json = r#"{"pose_in_map":{"x_m":1.5,"y_m":-2.0,"theta_rad":0.25},
            "covariance":[0.01,0,0,0,0.01,0,0,0,0.0025],"fit":0.8,"state":"Lost"}"#;
        let read: PoseEstimate = serde_json::from_str(json).expect("old JSON");
        assert!(read.proven);
    }

    #[test]
    fn markers_encode_as_docs_protocol_md_says() {
        let markers = Markers {
            markers: vec![
                Marker::new(
                    Shape::Arrows,
                    Frame::Robot,
                    [255, 0, 0, 128],
                    [(0.0, 0.0), (1.5, -0.5)],
                )
                .with_text("f"),
            ],
        };
        let mut out = Vec::new();
        markers.encode(&mut out).expect("encode");
        let mut expected = vec![1, 3, 1, 255, 0, 0, 128];
        expected.extend(2.0f32.to_le_bytes());
        expected.push(2);
        for value in [0.0f32, 0.0, 1.5, -0.5] {
            expected.extend(value.to_le_bytes());
        }
        expected.extend([1, b'f']);
        assert_eq!(out, expected);
        assert_eq!(Markers::decode(&out).expect("decode"), markers);
        assert!(Markers::decode(&out[..out.len() - 1]).is_err());
    }
}

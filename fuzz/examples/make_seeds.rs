//! Writes the seeds of the targets that read binary data (`data_types`, `studio_data`,
//! `recording`) into seeds/: `cargo run --example make_seeds` from fuzz/. The recordings are
//! written as the recorder writes them (channel metadata `armor.data_type`, postcard or JSON
//! messages), compressed or not, with CRCs or without (so that mutations get past the checksums),
//! cut short, and with hostile contents (a grid claiming 2^64 cells, times out of order at both
//! ends of the range).

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use armor_module_api::Datum;
use armor_module_api::types::{
    Blob, Counter, Image, ImageEncoding, LaserScan, OccupancyGrid, Odometry, Pose2D, Text, Twist,
};

fn encode<T: Datum>(value: &T) -> Vec<u8> {
    let mut out = Vec::new();
    value.encode(&mut out).expect("encodes");
    out
}

fn write(folder: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(folder).expect("seed folder");
    std::fs::write(folder.join(name), bytes).expect("seed written");
}

fn pose(x_m: f64) -> Pose2D {
    Pose2D {
        x_m,
        y_m: 2.0,
        theta_rad: 0.5,
    }
}

fn scan() -> LaserScan {
    LaserScan {
        angle_min_rad: -1.5,
        angle_increment_rad: 0.5,
        range_max_m: 8.0,
        ranges_m: vec![1.0, 2.5, f32::NAN, 8.0, 0.5, -1.0, f32::INFINITY],
    }
}

fn grid() -> OccupancyGrid {
    OccupancyGrid {
        resolution_m: 0.25,
        width: 4,
        height: 3,
        origin_x_m: -0.5,
        origin_y_m: -0.5,
        cells: vec![-1, 0, 0, 100, 50, -1, 100, 0, 0, 0, 127, -128],
    }
}

/// 2^64 − 2^33 + 1 cells claimed, four sent.
fn huge_grid() -> OccupancyGrid {
    OccupancyGrid {
        width: u32::MAX,
        height: u32::MAX,
        cells: vec![0; 4],
        ..grid()
    }
}

/// The data type name and payload of each type, a valid value.
fn samples() -> Vec<(u8, Vec<u8>)> {
    vec![
        (0, encode(&Counter(300))),
        (1, encode(&Text("héllo".into()))),
        (2, encode(&Blob(vec![0, 1, 2, 255]))),
        (3, encode(&pose(1.0))),
        (
            4,
            encode(&Twist {
                linear_mps: 0.4,
                angular_radps: -0.8,
            }),
        ),
        (
            5,
            encode(&Odometry {
                pose_in_odom: pose(0.9),
                ..Odometry::default()
            }),
        ),
        (6, encode(&scan())),
        (7, encode(&grid())),
    ]
}

fn data_types(folder: &Path) {
    let names = [
        "counter",
        "text",
        "blob",
        "pose2d",
        "twist",
        "odometry",
        "laserscan",
        "grid",
    ];
    for (which, payload) in samples() {
        let mut seed = vec![which];
        seed.extend(payload);
        write(folder, names[usize::from(which)], &seed);
    }
    let mut huge = vec![7];
    huge.extend(encode(&huge_grid()));
    write(folder, "grid-huge", &huge);
    // A sequence announcing u64::MAX elements.
    let mut long_scan = vec![6];
    long_scan.extend([0; 24]);
    long_scan.extend([0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01]);
    write(folder, "laserscan-long", &long_scan);
    // An image (2 × 1 mono8: the example of docs/protocol.md), and one announcing u64::MAX bytes
    // of pixels.
    let mut image = vec![8];
    image.extend(encode(&Image {
        width: 2,
        height: 1,
        encoding: ImageEncoding::Mono8,
        stamp_ns: 1_500_000_000,
        frame_id: "cam".into(),
        data: vec![10, 20].into(),
    }));
    write(folder, "image", &image);
    let mut long_image = image[..image.len() - 3].to_vec();
    long_image.extend([0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01, 10, 20]);
    write(folder, "image-long", &long_image);
}

fn studio_data(folder: &Path) {
    let seed = |which: u8, side: u8, payload: &[u8]| {
        let mut seed = vec![which, side];
        seed.extend(payload);
        seed
    };
    write(folder, "pose", &seed(0, 0, &encode(&pose(1.0))));
    let mut scan_at = encode(&pose(-3.0));
    scan_at.extend(encode(&scan()));
    write(folder, "scan", &seed(1, 0, &scan_at));
    write(folder, "grid", &seed(2, 13, &encode(&grid())));
    write(folder, "grid-shrunk", &seed(2, 1, &encode(&grid())));
    write(folder, "grid-huge", &seed(2, 13, &encode(&huge_grid())));
    let mut inconsistent = grid();
    inconsistent.cells.truncate(5);
    write(
        folder,
        "grid-inconsistent",
        &seed(2, 13, &encode(&inconsistent)),
    );
    let mut times = Vec::new();
    for time in [30_u64, 10, u64::MAX, 0] {
        times.extend(time.to_le_bytes());
    }
    times.extend(12.5_f64.to_le_bytes());
    write(folder, "timeline", &seed(3, 0, &times));
    write(folder, "path", &seed(4, 0, b"0,0 1.5,2 -3,4e2 x"));
}

struct Channel {
    data_name: &'static str,
    data_type: &'static str,
    encoding: &'static str,
}

/// A recording of `messages` (channel index, log time, payload).
fn recording(
    options: mcap::WriteOptions,
    channels: &[Channel],
    messages: &[(usize, u64, Vec<u8>)],
) -> Vec<u8> {
    let mut writer = options
        .create(Cursor::new(Vec::new()))
        .expect("a writer in memory");
    let ids: Vec<u16> = channels
        .iter()
        .map(|channel| {
            let schema = writer
                .add_schema(channel.data_type, "", &[])
                .expect("schema");
            let metadata =
                BTreeMap::from([("armor.data_type".to_owned(), channel.data_type.to_owned())]);
            writer
                .add_channel(schema, channel.data_name, channel.encoding, &metadata)
                .expect("channel")
        })
        .collect();
    for (sequence, (channel, log_time, payload)) in messages.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: ids[*channel],
            sequence: sequence as u32,
            log_time: *log_time,
            publish_time: *log_time,
        };
        writer
            .write_to_known_channel(&header, payload)
            .expect("message");
    }
    writer.finish().expect("finished");
    writer.into_inner().into_inner()
}

fn recordings(folder: &Path) {
    let postcard = |data_name, data_type| Channel {
        data_name,
        data_type,
        encoding: "postcard",
    };
    let channels = [
        postcard("sim.pose_truth", "Pose2D"),
        postcard("sim.odometry", "Odometry"),
        postcard("sim.scan", "LaserScan"),
        postcard("mapper.grid", "OccupancyGrid"),
        Channel {
            data_name: "sim.pose_json",
            data_type: "Pose2D",
            encoding: "json",
        },
        Channel {
            data_name: "camera.raw",
            data_type: "Blob",
            encoding: "raw",
        },
    ];
    let start = 1_700_000_000_000_000_000_u64;
    let messages = vec![
        (0, start, encode(&pose(0.0))),
        (
            1,
            start + 1_000_000,
            encode(&Odometry {
                pose_in_odom: pose(0.1),
                ..Odometry::default()
            }),
        ),
        (2, start + 2_000_000, encode(&scan())),
        (3, start + 3_000_000, encode(&grid())),
        (
            4,
            start + 4_000_000,
            br#"{"x_m":1.5,"y_m":-2,"theta_rad":0.25}"#.to_vec(),
        ),
        (5, start + 5_000_000, vec![9, 8, 7]),
        (0, start + 100_000_000, encode(&pose(0.5))),
    ];
    let plain = || mcap::WriteOptions::new().compression(None);
    write(
        folder,
        "postcard.mcap",
        &recording(plain(), &channels, &messages),
    );
    let no_crc = plain()
        .calculate_chunk_crcs(false)
        .calculate_data_section_crc(false)
        .calculate_summary_section_crc(false);
    let unchecked = recording(no_crc, &channels, &messages);
    write(folder, "no-crc.mcap", &unchecked);
    // Cut in the middle: no summary, read as far as it goes.
    write(
        folder,
        "partial.mcap",
        &unchecked[..unchecked.len() * 2 / 3],
    );
    write(
        folder,
        "unchunked.mcap",
        &recording(plain().use_chunks(false), &channels, &messages),
    );
    write(
        folder,
        "zstd.mcap",
        &recording(
            mcap::WriteOptions::new().compression(Some(mcap::Compression::Zstd)),
            &channels,
            &messages,
        ),
    );
    write(
        folder,
        "lz4.mcap",
        &recording(
            mcap::WriteOptions::new()
                .compression(Some(mcap::Compression::Lz4))
                .calculate_chunk_crcs(false),
            &channels,
            &messages,
        ),
    );
    // Times at both ends of the range, out of order, and a grid claiming 2^64 cells.
    let hostile = vec![
        (0, u64::MAX, encode(&pose(1.0))),
        (3, 1, encode(&huge_grid())),
        (0, 0, encode(&pose(f64::NAN))),
        (2, u64::MAX, vec![0xFF; 12]),
    ];
    write(
        folder,
        "hostile.mcap",
        &recording(
            plain()
                .calculate_chunk_crcs(false)
                .calculate_data_section_crc(false)
                .calculate_summary_section_crc(false),
            &channels,
            &hostile,
        ),
    );
}

fn main() {
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
    data_types(&seeds.join("data_types"));
    studio_data(&seeds.join("studio_data"));
    recordings(&seeds.join("recording"));
}

//! The simulated camera as a process: its images cross a real link unchanged (the picture the
//! renderer draws here, byte for byte, for a 640×480 `rgb8` frame sent from the module's own
//! buffer), and a recorder writes them into MCAP in Foxglove's image schemas, which the official
//! `mcap` Python package reads back with the schemas named. A Python program written from
//! docs/protocol.md alone (tests/python/image_publisher.py) publishes images that arrive
//! decoded as it meant them.
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::{Duration, Instant};

use armor_model::world::World;
use armor_module_api::types::{Image, ImageEncoding};
use armor_module_api::{Event, ModuleSpec};
use armor_module_catalog::camera::render::Camera;
use armor_tests::mcap::recorded;
use armor_tests::{PATIENCE, Proc, bin, start_agent, test_node, workspace_root};

/// `armor-mod-camera-sim` standalone on the agent at `agent`, in the workspace's folder (where it
/// finds `assets/worlds/yard.world`), with these parameters.
fn camera(name: &str, agent: &str, params: &[&str]) -> Proc {
    let mut command = Command::new(bin("armor-mod-camera-sim"));
    command.current_dir(workspace_root()).args([
        "--name",
        name,
        "--agent",
        agent,
        "--param",
        "world=yard",
    ]);
    for param in params {
        command.args(["--param", param]);
    }
    Proc::start(&mut command)
}

#[test]
fn a_camera_frame_crosses_a_link_unchanged() {
    let (_agent, agent) = start_agent();
    let _camera = camera(
        "cam",
        &agent.to_string(),
        &[
            "encoding=rgb8",
            "width=640",
            "height=480",
            "fov_deg=70",
            "rate_hz=5",
        ],
    );
    let mut viewer = test_node(
        ModuleSpec::new("viewer", "looks").input::<Image>("image", "the camera's"),
        agent,
        &[("image", "cam.image")],
    );
    let input = viewer.input::<Image>("image").unwrap();
    let deadline = Instant::now() + PATIENCE;
    let sample = loop {
        assert!(Instant::now() < deadline, "no image within {PATIENCE:?}");
        if let Event::Input(_) = viewer.next_event(Some(Duration::from_millis(100))).unwrap()
            && let Some(sample) = viewer.take(&input).unwrap()
        {
            break sample;
        }
    };
    let image = sample.value;
    assert_eq!(
        (image.width, image.height, image.encoding, &*image.frame_id),
        (640, 480, ImageEncoding::Rgb8, "camera")
    );
    // With no pose linked, the camera looks from the world's start pose: the same picture
    // drawn here must be what came through, every one of the 921,600 bytes.
    let text = std::fs::read_to_string(workspace_root().join("assets/worlds/yard.world")).unwrap();
    let world = World::parse(&text, "yard.world").unwrap();
    let mut expected = Vec::new();
    Camera {
        width: 640,
        height: 480,
        fov_rad: 70_f64.to_radians(),
        ..Camera::default()
    }
    .render(&world, world.start(), &mut expected);
    assert_eq!(image.data.len(), 921_600);
    assert!(image.data == expected, "the pixels changed on the way");
    assert!(
        image.stamp_ns <= sample.stamp_ns,
        "taken ({}) before it was sent ({})",
        image.stamp_ns,
        sample.stamp_ns
    );
}

#[test]
fn a_seeded_random_picture_crosses_a_link_unchanged() {
    // Pixels no renderer would draw (seed 25): every byte value, in no order.
    let (_agent, agent) = start_agent();
    let mut provider = test_node(
        ModuleSpec::new("source", "sends").output::<Image>("image", "noise"),
        agent,
        &[],
    );
    let output = provider.output::<Image>("image").unwrap();
    let mut viewer = test_node(
        ModuleSpec::new("viewer", "looks").input::<Image>("image", "every one"),
        agent,
        &[("image", "source.image")],
    );
    let input = viewer.reliable_input::<Image>("image").unwrap();
    let mut state = 25_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let sent: Vec<Image> = [
        (640, 480, ImageEncoding::Rgb8),
        (33, 7, ImageEncoding::Mono8),
    ]
    .into_iter()
    .map(|(width, height, encoding)| {
        let len = (width * height) as usize * encoding.bytes_per_pixel().unwrap();
        Image {
            width,
            height,
            encoding,
            stamp_ns: next() >> 8,
            frame_id: format!("noise-{width}"),
            data: (0..len).map(|_| next() as u8).collect(),
        }
    })
    .collect();
    let deadline = Instant::now() + PATIENCE;
    while provider.subscriber_count(&output) == 0 {
        assert!(Instant::now() < deadline, "the viewer never subscribed");
        provider
            .next_event(Some(Duration::from_millis(10)))
            .unwrap();
        viewer.next_event(Some(Duration::from_millis(10))).unwrap();
    }
    for image in &sent {
        provider.send(&output, image).unwrap();
    }
    provider.flush().unwrap();
    let mut received = Vec::new();
    while received.len() < sent.len() {
        assert!(Instant::now() < deadline, "got {} images", received.len());
        provider.next_event(Some(Duration::from_millis(1))).unwrap();
        viewer.next_event(Some(Duration::from_millis(10))).unwrap();
        while let Some(sample) = viewer.take(&input).unwrap() {
            received.push(sample.value);
        }
    }
    assert!(received == sent, "the images changed on the way");
}

#[test]
fn recorded_images_are_read_by_the_mcap_python_package_in_foxglove_schemas() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("camera.mcap");
    let (_agent, agent) = start_agent();
    let agent = agent.to_string();
    let _jpeg = camera("front", &agent, &["encoding=jpeg", "rate_hz=20"]);
    let _grey = camera(
        "rear",
        &agent,
        &["encoding=mono8", "width=64", "height=48", "rate_hz=20"],
    );
    let mut recorder = Proc::start(Command::new(bin("armor-mod-recorder")).args([
        "--agent",
        &agent,
        "--param",
        "record=front.image,rear.image",
        "--param",
        &format!("file={}", file.display()),
        "--param",
        "report_secs=0.2",
    ]));
    recorder.wait_for("saying 20 images were recorded", PATIENCE, |line| {
        recorded(line).is_some_and(|count| count >= 20)
    });
    recorder.signal(libc::SIGTERM);
    let status = recorder.wait_exit(PATIENCE);
    assert!(status.success(), "{status}: {:#?}", recorder.lines());

    let output = armor_tests::tools::python3(&["mcap"])
        .arg(workspace_root().join("tests/python/mcap_images.py"))
        .arg(&file)
        .output()
        .unwrap_or_else(|err| panic!("cannot run python3: {err}"));
    assert!(
        output.status.success(),
        "the mcap package could not read {}: {}",
        file.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    let topics: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let [front, rear] = topics.as_array().unwrap().as_slice() else {
        panic!("two image channels: {topics:#}");
    };
    for (entry, schema) in [
        (front, "foxglove.CompressedImage"),
        (rear, "foxglove.RawImage"),
    ] {
        assert_eq!(entry["schema"], schema, "{entry:#}");
        assert_eq!(entry["schema_title"], schema);
        assert_eq!(entry["schema_encoding"], "jsonschema");
        assert_eq!(entry["message_encoding"], "json");
        assert_eq!(entry["metadata"]["armor.data_type"], "Image");
        assert!(entry["count"].as_u64().unwrap() >= 2, "{entry:#}");
        assert_eq!(entry["first"]["frame_id"], "camera");
        assert!(entry["first"]["timestamp"]["nsec"].as_u64().unwrap() < 1_000_000_000);
    }
    assert_eq!(front["topic"], "front.image");
    assert_eq!(front["first"]["format"], "jpeg");
    assert_eq!(
        front["first"]["data_head"], "ffd8ffe0",
        "a JPEG (JFIF) file: {front:#}"
    );
    assert_eq!(rear["first"]["encoding"], "mono8");
    assert_eq!(
        (
            &rear["first"]["width"],
            &rear["first"]["height"],
            &rear["first"]["step"]
        ),
        (
            &serde_json::json!(64),
            &serde_json::json!(48),
            &serde_json::json!(64)
        )
    );
    assert_eq!(rear["first"]["data_len"], 64 * 48);
}

#[test]
fn images_published_by_a_python_module_written_from_the_protocol_arrive_decoded() {
    let (_agent, agent) = start_agent();
    let publisher = Proc::start(
        armor_tests::tools::python3(&[])
            .arg(workspace_root().join("tests/python/image_publisher.py"))
            .arg(agent.to_string())
            .arg("pycam"),
    );
    publisher.wait_for("saying it registered", PATIENCE, |line| {
        line == "registered pycam.image"
    });
    let mut viewer = test_node(
        ModuleSpec::new("viewer", "looks").input::<Image>("image", "every one"),
        agent,
        &[("image", "pycam.image")],
    );
    let input = viewer.reliable_input::<Image>("image").unwrap();
    let deadline = Instant::now() + PATIENCE;
    let mut received = Vec::new();
    while received.len() < 2 {
        assert!(
            Instant::now() < deadline,
            "got {} images; the publisher said:\n{}",
            received.len(),
            publisher.lines().join("\n")
        );
        viewer.next_event(Some(Duration::from_millis(50))).unwrap();
        while let Some(sample) = viewer.take(&input).unwrap() {
            received.push(sample.value);
        }
    }
    let rgb: Vec<u8> = (0..3_u8)
        .flat_map(|y| (0..4_u8).flat_map(move |x| [10 * x, 20 * y, 7]))
        .collect();
    let mono: Vec<u8> = (0..480_usize)
        .flat_map(|y| (0..640_usize).map(move |x| ((x + y) % 256) as u8))
        .collect();
    let expected = [
        Image {
            width: 4,
            height: 3,
            encoding: ImageEncoding::Rgb8,
            stamp_ns: 1_500_000_000,
            frame_id: "py-front".into(),
            data: rgb.into(),
        },
        Image {
            width: 640,
            height: 480,
            encoding: ImageEncoding::Mono8,
            stamp_ns: 2_000_000_000,
            frame_id: "py-front".into(),
            data: mono.into(),
        },
    ];
    assert!(
        received == expected,
        "the images differ from what Python sent"
    );
}

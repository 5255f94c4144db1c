//! The Run view's video panel on its own: a frame of the simulated camera (the yard from the
//! robot's start) shown with its size, encoding, frame and age (snapshot); the output picked
//! from the list; a click gives the picture the keyboard focus that the arrow keys drive with;
//! frames too large to show or that do not decode are refused in words.
#![allow(clippy::unwrap_used)]

use armor_model::world::World;
use armor_module_api::Datum as _;
use armor_module_api::types::{Image, ImageEncoding};
use armor_module_catalog::camera::Shooter;
use armor_module_catalog::camera::render::Camera;
use armor_studio::run::video::{self, Clock, Frames, VideoPanel};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

/// A camera frame of the yard, seen from the start pose turned by `turn_rad`, taken at 1 s.
fn yard_frame(encoding: ImageEncoding, turn_rad: f64) -> Vec<u8> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("assets/worlds/yard.world")).unwrap();
    let world = World::parse(&text, "yard.world").unwrap();
    let mut shooter = Shooter::new(armor_module_catalog::camera::Settings {
        camera: Camera::default(),
        rate_hz: 10.0,
        max_real_hz: 10.0,
        encoding,
        jpeg_quality: 90,
        frame_id: "camera".into(),
    });
    let mut pose = world.start();
    pose.theta_rad += turn_rad;
    let mut image = Image {
        width: 0,
        height: 0,
        encoding,
        stamp_ns: 0,
        frame_id: String::new(),
        data: Default::default(),
    };
    shooter
        .shoot(&world, pose, 1_000_000_000, &mut image)
        .unwrap();
    let mut payload = Vec::new();
    image.encode(&mut payload).unwrap();
    payload
}

struct State {
    panel: VideoPanel,
    outputs: Vec<String>,
    frames: Frames,
    clock: Clock,
}

fn harness(state: State) -> Harness<'static, State> {
    let mut harness = Harness::builder()
        .with_size([380.0, 340.0])
        .wgpu()
        .build_ui_state(
            |ui, state: &mut State| {
                state
                    .panel
                    .ui(ui, &state.outputs, &state.frames, state.clock);
            },
            state,
        );
    harness.run();
    harness
}

#[test]
fn a_published_frame_is_shown_with_its_age() {
    let mut frames = Frames::default();
    frames
        .take("camera.image", &yard_frame(ImageEncoding::Jpeg, 0.0))
        .unwrap();
    let mut harness = harness(State {
        panel: VideoPanel::default(),
        outputs: vec!["camera.image".into(), "rear.image".into()],
        frames,
        // The play head of a recording 250 ms after the capture.
        clock: Clock::PlayHead(1_250_000_000),
    });
    harness.get_by_label_contains("320 × 240 jpeg · camera · age 250 ms");
    harness.get_by_label("Camera view");
    harness.snapshot("video_panel");

    // The other output has no frame yet.
    harness.get_by_label("Camera").click();
    harness.run();
    harness.get_by_label("rear.image").click();
    harness.run();
    assert_eq!(harness.state().panel.picked.as_deref(), Some("rear.image"));
    harness.get_by_label_contains("Waiting for a frame of rear.image");
}

#[test]
fn a_click_on_the_picture_takes_the_arrow_keys() {
    let mut frames = Frames::default();
    frames
        .take("camera.image", &yard_frame(ImageEncoding::Mono8, 1.0))
        .unwrap();
    let mut harness = harness(State {
        panel: VideoPanel::default(),
        outputs: vec!["camera.image".into()],
        frames,
        clock: Clock::Live,
    });
    harness.get_by_label_contains("320 × 240 mono8");
    assert!(!video::has_focus(&harness.ctx));
    harness.get_by_label("Camera view").click();
    harness.run();
    assert!(video::has_focus(&harness.ctx));
    harness.get_by_label_contains("Driving: arrow keys");
    // The arrows do not move the focus away: they are the robot's.
    harness.key_press(egui::Key::ArrowDown);
    harness.key_press(egui::Key::ArrowRight);
    harness.run();
    assert!(video::has_focus(&harness.ctx));
    harness.key_press(egui::Key::Escape);
    harness.run();
    assert!(!video::has_focus(&harness.ctx), "Esc lets go");
}

#[test]
fn hostile_frames_are_refused_in_words() {
    let mut frames = Frames::default();
    // A JPEG whose frame header claims 65535 × 65535 pixels: never decoded.
    let mut jpeg = vec![
        0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x11, 0x08, 0xFF, 0xFF, 0xFF, 0xFF, 3,
    ];
    jpeg.extend([0; 9]);
    let huge = Image {
        width: 16,
        height: 16,
        encoding: ImageEncoding::Jpeg,
        stamp_ns: 0,
        frame_id: "liar".into(),
        data: jpeg.into(),
    };
    let err = video::decode(&huge).unwrap_err();
    assert!(err.contains("65535 × 65535 pixels is larger"), "{err}");
    // A frame that claims more pixels than are shown is not taken.
    let mut payload = Vec::new();
    Image {
        width: 5000,
        height: 5000,
        encoding: ImageEncoding::Mono8,
        stamp_ns: 0,
        frame_id: String::new(),
        data: vec![0; 25_000_000].into(),
    }
    .encode(&mut payload)
    .unwrap();
    let err = frames.take("cam.image", &payload).unwrap_err();
    assert!(err.contains("larger than"), "{err}");
    let err = frames.take("cam.image", &[1, 2, 3]).unwrap_err();
    assert!(err.contains("Image"), "{err}");
    assert!(frames.get("cam.image").is_none());

    // A frame that passes its checks but does not decode: said under the picture.
    let mut bad = Vec::new();
    Image {
        width: 8,
        height: 8,
        encoding: ImageEncoding::Jpeg,
        stamp_ns: 0,
        frame_id: "broken".into(),
        data: vec![0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 0, 8, 0, 8, 1].into(),
    }
    .encode(&mut bad)
    .unwrap();
    frames.take("cam.image", &bad).unwrap();
    let harness = harness(State {
        panel: VideoPanel::default(),
        outputs: vec!["cam.image".into()],
        frames,
        clock: Clock::Live,
    });
    harness.get_by_label_contains("not shown: cannot decode the JPEG");
}

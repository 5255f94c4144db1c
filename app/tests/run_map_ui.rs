//! Issue 37, defect 4: the Run view's map places its labels and markers together. Seen from
//! the frame's own shapes (the texts egui was asked to draw): no text covers another or the
//! robot, and none stands outside the world, with the robot on a waypoint of the yard plan and
//! a module's texts at the robot.
#![allow(clippy::unwrap_used)]

mod common;

use armor_model::world::{Point, World};
use armor_module_api::Datum;
use armor_module_api::types::{Frame, Marker, Markers, Odometry, Pose2D, Shape, Twist};
use armor_runtime::replay::Recorded;
use armor_studio::StudioApp;
use armor_studio::app::View;
use armor_studio::run::live::Recording;
use common::{robot_file, studio_on};
use egui::{Pos2, Rect};
use egui_kittest::Harness;

fn recorded(at_secs: u64, data_name: &str, data_type: &str, datum: &impl Datum) -> Recorded {
    let mut payload = Vec::new();
    datum.encode(&mut payload).unwrap();
    Recorded {
        log_time_ns: at_secs * 1_000_000_000,
        data_name: data_name.to_owned(),
        data_type: data_type.to_owned(),
        payload,
    }
}

/// Every text drawn at the last frame whose box lies on the map (`map`): (text, box).
fn texts_on(harness: &Harness<'_, StudioApp>, map: Rect) -> Vec<(String, Rect)> {
    harness
        .output()
        .shapes
        .iter()
        .filter_map(|clipped| match &clipped.shape {
            egui::Shape::Text(text) => Some((
                text.galley.text().to_owned(),
                text.galley.rect.translate(text.pos.to_vec2()),
            )),
            _ => None,
        })
        .filter(|(text, rect)| {
            !text.trim().is_empty() && map.contains(rect.center()) && !is_scale(text)
        })
        .collect()
}

/// The scale bar's text ("5 m"), drawn in the map's corner, not a label of the world.
fn is_scale(text: &str) -> bool {
    text.strip_suffix(" km")
        .or_else(|| text.strip_suffix(" m"))
        .is_some_and(|number| number.parse::<f64>().is_ok())
}

/// The yard plan watched in the Run view, its robot on the waypoint `gate` (where its name
/// and the leg's labels are), what it believes a little off the truth; an observer's texts
/// at the robot and at the gate, its arc round the robot, and the follower's goal on the gate.
struct AtGate {
    harness: Harness<'static, StudioApp>,
    truth: Pose2D,
    estimated: Odometry,
    _dir: tempfile::TempDir,
}

fn robot_at_gate() -> AtGate {
    let dir = tempfile::tempdir().unwrap();
    let plan = robot_file("plan-yard.xml");
    let mut harness = studio_on(&dir.path().join("home"), plan.clone());
    let mission = harness.state().mission().unwrap();
    assert_eq!(mission.path(), Some(plan.as_path()));
    let origin = mission.surroundings.origin(mission.plan());
    let gate = mission
        .plan()
        .waypoint("gate")
        .unwrap()
        .position
        .to_local(origin);
    let truth = Pose2D {
        x_m: gate.x,
        y_m: gate.y,
        theta_rad: 0.3,
    };
    let estimated = Odometry {
        pose_in_odom: Pose2D {
            x_m: gate.x + 0.2,
            y_m: gate.y - 0.1,
            theta_rad: 0.35,
        },
        twist: Twist::default(),
    };
    let mut sweep = Marker::new(
        Shape::Text,
        Frame::World,
        [40, 40, 200, 255],
        [(gate.x, gate.y)],
    )
    .with_text("358° of 360°");
    sweep.size_px = 2.0;
    let goal = Marker::new(
        Shape::Text,
        Frame::World,
        [200, 40, 40, 255],
        [(gate.x + 0.5, gate.y)],
    )
    .with_text("goal reached");
    // The observer's arc about the robot, inside its disc at this zoom, and the follower's
    // goal, a dot on the gate: both were drawn over the robot.
    let mut arc = Marker::new(
        Shape::Polyline,
        Frame::Robot,
        [40, 160, 90, 230],
        (0..=20).map(|i| {
            let angle = f64::from(i) * 0.3;
            (0.1 * angle.cos(), 0.1 * angle.sin())
        }),
    );
    arc.size_px = 4.0;
    let dot = Marker::new(
        Shape::Points,
        Frame::World,
        [30, 140, 60, 255],
        [(gate.x, gate.y)],
    );
    let markers = Markers {
        markers: vec![sweep, goal, arc, dot],
    };
    let mut messages = Vec::new();
    for at in 1..=3 {
        messages.push(recorded(at, "sim.pose_truth", "Pose2D", &truth));
        messages.push(recorded(at, "sim.odometry", "Odometry", &estimated));
        messages.push(recorded(at, "observer.markers", "Markers", &markers));
    }
    let recording = Recording::of(&dir.path().join("run.mcap"), messages).unwrap();
    harness.state_mut().run_mut().recording = Some(recording);
    harness.state_mut().set_view(View::Run);
    for _ in 0..4 {
        harness.run();
    }
    AtGate {
        harness,
        truth,
        estimated,
        _dir: dir,
    }
}

#[test]
fn the_run_maps_labels_cover_neither_each_other_nor_the_robot_and_stay_in_the_world() {
    let AtGate {
        harness,
        truth,
        estimated,
        _dir,
    } = robot_at_gate();
    let mission = harness.state().mission().unwrap();
    let (centre, map) = mission
        .last_screen_of(Point::new(truth.x_m, truth.y_m))
        .unwrap();
    let (east, _) = mission
        .last_screen_of(Point::new(truth.x_m + 1.0, truth.y_m))
        .unwrap();
    // The robot as drawn: a disc of 0.6 m or 26 points across, whichever is larger, with the
    // truth's dashed ring 3 points out.
    let radius = (0.3 * east.distance(centre)).max(13.0) + 3.0;
    let (estimated_centre, _) = mission
        .last_screen_of(Point::new(
            estimated.pose_in_odom.x_m,
            estimated.pose_in_odom.y_m,
        ))
        .unwrap();
    let robots = [
        Rect::from_center_size(centre, egui::Vec2::splat(2.0 * radius)),
        Rect::from_center_size(estimated_centre, egui::Vec2::splat(2.0 * radius)),
    ];
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/worlds/yard.world"),
    )
    .unwrap();
    let bounds = World::parse(&text, "yard.world").unwrap().bounds();
    let corner = |x: f64, y: f64| -> Pos2 { mission.last_screen_of(Point::new(x, y)).unwrap().0 };
    let world = Rect::from_two_pos(
        corner(bounds.min_x, bounds.min_y),
        corner(bounds.max_x, bounds.max_y),
    );

    let texts = texts_on(&harness, map);
    let said = |wanted: &str| texts.iter().any(|(text, _)| text == wanted);
    assert!(
        said("truth (simulator)") && said("gate"),
        "the truth's tag and the waypoint's name are drawn: {texts:?}"
    );
    assert!(
        said("358° of 360°") || said("358°"),
        "the observer's text is drawn: {texts:?}"
    );
    let mut problems = Vec::new();
    for (i, (text, rect)) in texts.iter().enumerate() {
        for (other, other_rect) in &texts[i + 1..] {
            if rect.intersects(*other_rect) {
                problems.push(format!("`{text}` {rect:?} covers `{other}` {other_rect:?}"));
            }
        }
        for robot in &robots {
            if rect.intersects(*robot) {
                problems.push(format!("`{text}` {rect:?} covers the robot {robot:?}"));
            }
        }
        if !world.expand(1.0).contains_rect(*rect) {
            problems.push(format!("`{text}` {rect:?} is outside the world {world:?}"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // And the view's own account of its layout agrees.
    let layout = &harness.state().run().map_layout;
    assert_eq!(layout.robots.len(), 2, "{layout:?}");
    for (i, rect) in layout.labels.iter().enumerate() {
        assert!(
            layout.labels[i + 1..]
                .iter()
                .all(|other| !other.intersects(*rect))
                && layout.robots.iter().all(|robot| !robot.intersects(*rect)),
            "{layout:?}"
        );
    }
}

/// Every shape painted on the map at the last frame (clipped to it), flattened, in the order
/// painted.
fn map_shapes(harness: &Harness<'_, StudioApp>, map: Rect) -> Vec<egui::Shape> {
    fn flatten(shape: &egui::Shape, into: &mut Vec<egui::Shape>) {
        match shape {
            egui::Shape::Vec(shapes) => shapes.iter().for_each(|shape| flatten(shape, into)),
            shape => into.push(shape.clone()),
        }
    }
    let mut shapes = Vec::new();
    for clipped in &harness.output().shapes {
        if map.expand(0.5).contains_rect(clipped.clip_rect) {
            flatten(&clipped.shape, &mut shapes);
        }
    }
    shapes
}

/// Points along a segment, half a point apart.
fn along(line: [Pos2; 2]) -> impl Iterator<Item = Pos2> {
    let steps = (line[0].distance(line[1]) * 2.0).ceil().max(1.0) as usize;
    (0..=steps).map(move |i| line[0].lerp(line[1], i as f32 / steps as f32))
}

/// The shape paints inside the disc at `centre` of `radius` (by half a point or more).
fn reaches_into(shape: &egui::Shape, centre: Pos2, radius: f32) -> bool {
    let inside = |p: Pos2| p.distance(centre) < radius - 0.5;
    match shape {
        egui::Shape::Noop => false,
        egui::Shape::Circle(circle) => {
            circle.center.distance(centre)
                < circle.radius + circle.stroke.width / 2.0 + radius - 0.5
        }
        egui::Shape::LineSegment { points, .. } => along(*points).any(inside),
        egui::Shape::Path(path) => {
            path.points
                .windows(2)
                .any(|pair| along([pair[0], pair[1]]).any(inside))
                || (path.closed && path.points.iter().any(|p| inside(*p)))
        }
        egui::Shape::Text(text) => {
            text.galley
                .rect
                .translate(text.pos.to_vec2())
                .distance_to_pos(centre)
                < radius - 0.5
        }
        other => other.visual_bounding_rect().distance_to_pos(centre) < radius - 0.5,
    }
}

/// Issue 37, defect 4's last part: with the robot on a waypoint under an observer's arc and
/// a goal's dot, every shape painted after the robot's disc keeps off it (the truth's ring and
/// the markers were painted over it), the disc hides what lies under it, and every leader line
/// from a label standing off to its anchor crosses neither another label nor a robot.
#[test]
fn the_robot_is_painted_over_every_ring_and_leader_lines_cross_no_label_nor_robot() {
    let AtGate {
        harness,
        estimated,
        _dir,
        ..
    } = robot_at_gate();
    let mission = harness.state().mission().unwrap();
    let at = estimated.pose_in_odom;
    let (centre, map) = mission.last_screen_of(Point::new(at.x_m, at.y_m)).unwrap();
    let shapes = map_shapes(&harness, map);
    // The estimate's disc: its rim in the estimate's orange.
    let orange = egui::Color32::from_rgb(230, 120, 0);
    let (index, disc) = shapes
        .iter()
        .enumerate()
        .find_map(|(index, shape)| match shape {
            egui::Shape::Circle(circle)
                if circle.center.distance(centre) < 0.5 && circle.stroke.color == orange =>
            {
                Some((index, *circle))
            }
            _ => None,
        })
        .expect("the robot's disc is painted");
    assert_eq!(
        disc.fill.a(),
        255,
        "the robot's disc lets what lies under it show through: {:?}",
        disc.fill
    );
    let over: Vec<_> = shapes[index + 1..]
        .iter()
        // Its own arrow, in its colour, drawn on it.
        .filter(|shape| !matches!(shape, egui::Shape::Path(path) if path.fill == orange))
        .filter(|shape| reaches_into(shape, disc.center, disc.radius))
        .collect();
    assert!(
        over.is_empty(),
        "{} shapes painted over the robot {disc:?}: {over:#?}",
        over.len()
    );

    // Leader lines: thin segments from the edge of a label's box out to its anchor.
    let layout = &harness.state().run().map_layout;
    let on_edge =
        |p: Pos2, rect: &Rect| rect.expand(0.75).contains(p) && !rect.shrink(0.75).contains(p);
    let leaders: Vec<([Pos2; 2], Rect)> = shapes
        .iter()
        .filter_map(|shape| match shape {
            egui::Shape::LineSegment { points, stroke } if stroke.width <= 1.5 => {
                layout.labels.iter().find_map(|label| {
                    (on_edge(points[1], label) && !label.contains(points[0]))
                        .then_some((*points, *label))
                })
            }
            _ => None,
        })
        .collect();
    assert!(
        !leaders.is_empty(),
        "the labels crowded at the gate stand off with leader lines: {layout:?}"
    );
    let mut problems = Vec::new();
    for (line, own) in &leaders {
        for label in layout.labels.iter().filter(|label| *label != own) {
            if along(*line).any(|p| label.shrink(0.75).contains(p)) {
                problems.push(format!(
                    "the leader {line:?} of {own:?} crosses the label {label:?}"
                ));
            }
        }
        for robot in &layout.robots {
            if along(*line).any(|p| robot.shrink(0.75).contains(p)) {
                problems.push(format!(
                    "the leader {line:?} of {own:?} crosses the robot {robot:?}"
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

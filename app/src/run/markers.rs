//! Each module's own view on the live map: the `Markers` it publishes (on an output named
//! `markers` by convention, though any output of type `Markers` counts), one layer per module,
//! each with a switch. Markers in the robot's frame are drawn from the robot's pose (the truth
//! in simulation, else the estimate, as the scan is).

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use armor_model::world::Point;
use armor_module_api::types::{Frame, Markers, Pose2D, Shape};
use egui::{Color32, Pos2, Rect, Shape as EguiShape, Stroke, Ui, Vec2};

use crate::common::labels::{self, Importance, Label, Placed};

use super::untrusted::MAX_COORDINATE_M;

/// Points of all the markers of one sample, at most: 50 markers of 2,000 points each.
pub const MAX_MARKER_POINTS: usize = 100_000;
/// How far beyond its point a marker may paint (a text's width), for culling.
const TEXT_REACH_PX: f32 = 200.0;
/// A text marker's words, at most (in characters).
const MAX_TEXT_CHARS: usize = 200;

/// The latest markers of each module (by the module's name).
#[derive(Clone, Debug, Default)]
pub struct Layers {
    pub by_module: BTreeMap<String, Arc<Markers>>,
}

impl Layers {
    /// Takes a sample of `data_name` (`module.output`), checked: too many points, or a
    /// coordinate that is not a number or lies beyond the Earth, refuse it whole.
    pub fn take(&mut self, data_name: &str, markers: Markers) -> Result<(), String> {
        check(&markers)?;
        let module = data_name
            .split_once('.')
            .map_or(data_name, |(module, _)| module);
        self.by_module.insert(module.to_owned(), Arc::new(markers));
        Ok(())
    }
}

fn check(markers: &Markers) -> Result<(), String> {
    let points: usize = markers.markers.iter().map(|m| m.points.len()).sum();
    if points > MAX_MARKER_POINTS {
        return Err(format!(
            "{points} marker points, more than the {MAX_MARKER_POINTS} drawn"
        ));
    }
    for marker in &markers.markers {
        for point in &marker.points {
            for value in [point.x_m, point.y_m] {
                if !value.is_finite() || f64::from(value).abs() > MAX_COORDINATE_M {
                    return Err(format!("a marker point at {value} m"));
                }
            }
        }
        if !marker.size_px.is_finite() {
            return Err("a marker of size NaN".to_owned());
        }
    }
    Ok(())
}

/// Paints every layer not in `hidden`; returns how many markers of each module were drawn
/// (those out of view are not) and where their texts went. Text markers are placed as the
/// map places its labels: never over `taken` (the plan's labels, the robots and their tags)
/// nor `lines` (the plan's leader lines) nor over each other, inside `bounds` (the world),
/// moved aside with a leader line when their point is taken, and dropped when there is no
/// room near it.
#[allow(clippy::too_many_arguments)]
pub fn paint(
    painter: &egui::Painter,
    project: &dyn Fn(Point) -> Pos2,
    layers: &Layers,
    hidden: &BTreeSet<String>,
    robot: Option<&Pose2D>,
    taken: &[Rect],
    lines: &[[Pos2; 2]],
    bounds: Rect,
) -> (BTreeMap<String, usize>, Vec<Placed>) {
    let mut drawn = BTreeMap::new();
    let origin = robot.map_or(Point::new(0.0, 0.0), |pose| Point::new(pose.x_m, pose.y_m));
    let near = Affine::near(project, origin);
    let mut texts = Texts::default();
    for (module, markers) in &layers.by_module {
        if hidden.contains(module) {
            continue;
        }
        drawn.insert(
            module.clone(),
            paint_markers(painter, &near, markers, robot, &mut texts),
        );
    }
    let placed = texts.draw(painter, taken, lines, bounds);
    (drawn, placed)
}

/// The modules whose markers are not drawn: those the operator switched off (`hidden`), and
/// those no longer at work (`states`: stopped, ended, crashed), whose last markers would say
/// what is no longer so (an observer's "358° of 360°" long after it stopped).
pub fn not_drawn(
    hidden: &BTreeSet<String>,
    states: &BTreeMap<String, armor_protocol::ModuleState>,
) -> BTreeSet<String> {
    use armor_protocol::ModuleState;
    let stopped = states.iter().filter(|(_, state)| {
        !matches!(
            state,
            ModuleState::Running | ModuleState::Starting | ModuleState::Restarting
        )
    });
    hidden
        .iter()
        .cloned()
        .chain(stopped.map(|(module, _)| module.clone()))
        .collect()
}

/// The text markers of a frame, placed together once the shapes are drawn.
#[derive(Default)]
struct Texts {
    labels: Vec<Label>,
    /// Each text's size (a marker's `size_px` scales its text).
    fonts: BTreeMap<String, f32>,
}

impl Texts {
    fn add(&mut self, at: Pos2, text: String, size: f32, colour: Color32) {
        self.fonts.insert(text.clone(), size);
        self.labels.push(Label {
            anchors: vec![at],
            gap: 3.0,
            preferred: egui::Align2::LEFT_BOTTOM,
            text,
            colour,
            importance: Importance::Detail,
        });
    }

    fn draw(
        self,
        painter: &egui::Painter,
        taken: &[Rect],
        lines: &[[Pos2; 2]],
        bounds: Rect,
    ) -> Vec<Placed> {
        if self.labels.is_empty() {
            return Vec::new();
        }
        let font = |fonts: &BTreeMap<String, f32>, text: &str| {
            egui::FontId::proportional(fonts.get(text).copied().unwrap_or(12.0))
        };
        let mut measure = |text: &str| {
            painter
                .layout_no_wrap(text.to_owned(), font(&self.fonts, text), Color32::BLACK)
                .size()
        };
        let placed = labels::place(self.labels, taken, lines, bounds, &mut measure);
        for label in &placed {
            if let Some(leader) = label.leader {
                painter.line_segment(leader, Stroke::new(1.0, label.colour.gamma_multiply(0.7)));
            }
            let galley = painter.layout_no_wrap(
                label.text.clone(),
                font(&self.fonts, &label.text),
                label.colour,
            );
            painter.galley(label.rect.min + Vec2::splat(2.0), galley, label.colour);
        }
        placed
    }
}

/// The map's projection about a point, as an affine map: three projections a frame instead of
/// one (a logarithm and a tangent) for each of tens of thousands of points. Web Mercator's scale
/// changes by tan(latitude) per radian of latitude, about 1.5e-7 of itself per metre at 45°,
/// so within a kilometre of the point the affine map is off by less than a point on a map
/// where that kilometre fills the screen.
struct Affine {
    origin: Point,
    at: Pos2,
    per_x: Vec2,
    per_y: Vec2,
}

impl Affine {
    fn near(project: &dyn Fn(Point) -> Pos2, origin: Point) -> Self {
        // Measured over a hundred metres, so that the screen's f32 rounding is a hundredth as
        // large against it.
        const BASE_M: f64 = 100.0;
        let at = project(origin);
        Self {
            origin,
            at,
            per_x: (project(Point::new(origin.x + BASE_M, origin.y)) - at) / BASE_M as f32,
            per_y: (project(Point::new(origin.x, origin.y + BASE_M)) - at) / BASE_M as f32,
        }
    }

    fn project(&self, point: Point) -> Pos2 {
        self.at
            + self.per_x * (point.x - self.origin.x) as f32
            + self.per_y * (point.y - self.origin.y) as f32
    }
}

fn paint_markers(
    painter: &egui::Painter,
    near: &Affine,
    markers: &Markers,
    robot: Option<&Pose2D>,
    texts: &mut Texts,
) -> usize {
    let mut drawn = 0;
    let clip = painter.clip_rect();
    let robot = robot.map(|pose| (pose, pose.theta_rad.sin_cos()));
    for marker in &markers.markers {
        let to_screen = |x: f32, y: f32| -> Option<Pos2> {
            let (x, y) = (f64::from(x), f64::from(y));
            match marker.frame {
                Frame::World => Some(near.project(Point::new(x, y))),
                Frame::Robot => {
                    let (pose, (sin, cos)) = robot?;
                    Some(near.project(Point::new(
                        pose.x_m + x * cos - y * sin,
                        pose.y_m + x * sin + y * cos,
                    )))
                }
            }
        };
        let Some(points) = marker
            .points
            .iter()
            .map(|p| to_screen(p.x_m, p.y_m))
            .collect::<Option<Vec<Pos2>>>()
        else {
            continue; // robot-frame markers before any pose
        };
        // Out of view: nothing to paint (texts reach a little beyond their point).
        if !clip.intersects(egui::Rect::from_points(&points).expand(TEXT_REACH_PX)) {
            continue;
        }
        drawn += 1;
        let [r, g, b, a] = marker.rgba;
        let colour = Color32::from_rgba_unmultiplied(r, g, b, a);
        let width = marker.size_px.clamp(0.5, 12.0);
        let stroke = Stroke::new(width, colour);
        match marker.shape {
            Shape::Points => {
                for point in points {
                    painter.circle_filled(point, width, colour);
                }
            }
            Shape::Polyline => {
                painter.add(EguiShape::line(points, stroke));
            }
            Shape::Polygon if points.len() >= 3 => {
                painter.add(EguiShape::convex_polygon(
                    points,
                    colour.gamma_multiply(0.35),
                    stroke,
                ));
            }
            Shape::Polygon => {}
            Shape::Arrows => {
                for pair in points.chunks_exact(2) {
                    painter.arrow(pair[0], pair[1] - pair[0], stroke);
                }
            }
            Shape::Text => {
                if let Some(at) = points.first() {
                    let text: String = marker.text.chars().take(MAX_TEXT_CHARS).collect();
                    texts.add(*at, text, 12.0 * width.max(1.0) / 2.0 + 6.0, colour);
                }
            }
        }
    }
    drawn
}

/// The switch of each module's layer (checked: drawn), with how many markers it holds.
/// `stopped`: the modules no longer at work, whose markers are not drawn whatever the switch
/// says ([`not_drawn`]); their switch says so.
pub fn toggles_ui(
    ui: &mut Ui,
    layers: &Layers,
    hidden: &mut BTreeSet<String>,
    stopped: &BTreeSet<String>,
) {
    if layers.by_module.is_empty() {
        ui.label("No module publishes markers yet.");
        return;
    }
    for (module, markers) in &layers.by_module {
        let mut shown = !hidden.contains(module);
        let count = markers.markers.len();
        let label = if stopped.contains(module) {
            format!("{module} ({count} markers, not drawn: the module stopped)")
        } else {
            format!("{module} ({count} markers)")
        };
        if ui.checkbox(&mut shown, label).changed() {
            if shown {
                hidden.remove(module);
            } else {
                hidden.insert(module.clone());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::types::{Marker, MarkerPoint};

    #[test]
    fn the_affine_map_stays_within_a_point_of_web_mercator_over_a_kilometre() {
        // Web Mercator about 45° north, zoomed so that a kilometre is 1,000 points wide.
        const EARTH_M: f64 = 6_371_000.0;
        let latitude = 45f64.to_radians();
        let scale = 1000.0 / 1000.0 * EARTH_M;
        // As the map does: on the screen, about the view's centre (here the world's origin).
        let global = |point: Point| {
            let phi = latitude + point.y / EARTH_M;
            let lambda = point.x / (EARTH_M * latitude.cos());
            let y = (std::f64::consts::FRAC_PI_4 + phi / 2.0).tan().ln();
            (lambda * scale, -y * scale)
        };
        let centre = global(Point::new(0.0, 0.0));
        let mercator = |point: Point| {
            let (x, y) = global(point);
            Pos2::new((x - centre.0) as f32 + 640.0, (y - centre.1) as f32 + 400.0)
        };
        let origin = Point::new(120.0, -40.0);
        let near = Affine::near(&mercator, origin);
        let mut worst: f32 = 0.0;
        for (dx, dy) in [(1000.0, 0.0), (0.0, 1000.0), (-700.0, 700.0), (3.0, -2.0)] {
            let point = Point::new(origin.x + dx, origin.y + dy);
            worst = worst.max((near.project(point) - mercator(point)).length());
        }
        assert!(worst < 1.0, "off by {worst} points");
        assert!(worst > 0.0, "the test's projection is not affine");
    }

    #[test]
    fn layers_are_per_module_and_bad_samples_are_refused_whole() {
        let mut layers = Layers::default();
        let line = Marker::new(
            Shape::Polyline,
            Frame::World,
            [1, 2, 3, 255],
            [(0.0, 0.0), (1.0, 1.0)],
        );
        layers
            .take(
                "follower.markers",
                Markers {
                    markers: vec![line.clone()],
                },
            )
            .expect("taken");
        let mut bad = line.clone();
        bad.points.push(MarkerPoint {
            x_m: f32::NAN,
            y_m: 0.0,
        });
        let err = layers
            .take("vff.markers", Markers { markers: vec![bad] })
            .expect_err("refused");
        assert!(err.contains("NaN"), "{err}");
        let many = Marker::new(
            Shape::Points,
            Frame::World,
            [0; 4],
            (0..=MAX_MARKER_POINTS).map(|i| (i as f64, 0.0)),
        );
        assert!(
            layers
                .take(
                    "vff.markers",
                    Markers {
                        markers: vec![many]
                    }
                )
                .is_err()
        );
        assert_eq!(layers.by_module.keys().collect::<Vec<_>>(), ["follower"]);
    }
}

#[cfg(test)]
mod text_tests {
    use super::*;
    use armor_module_api::types::Marker;

    /// The boxes of the texts a frame painted.
    fn text_boxes(output: &egui::FullOutput) -> Vec<(String, Rect)> {
        output
            .shapes
            .iter()
            .filter_map(|clipped| match &clipped.shape {
                EguiShape::Text(text) => Some((
                    text.galley.text().to_owned(),
                    text.galley.rect.translate(text.pos.to_vec2()),
                )),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn texts_stand_clear_of_the_plans_labels_and_of_each_other() {
        let goal = |module_colour: u8| {
            let mut marker = Marker::new(
                Shape::Text,
                Frame::World,
                [0, module_colour, 0, 255],
                [(0.0, 0.0)],
            );
            marker.text = "goal".to_owned();
            Markers {
                markers: vec![marker],
            }
        };
        let mut layers = Layers::default();
        layers.take("follower.markers", goal(120)).expect("taken");
        layers.take("vff.markers", goal(200)).expect("taken");
        // The plan's label of the waypoint the goal is at, where a text would go first.
        let at = Pos2::new(400.0, 300.0);
        let plan_label = Rect::from_min_max(Pos2::new(395.0, 270.0), Pos2::new(460.0, 300.0));
        let project =
            |point: Point| Pos2::new(at.x + 10.0 * point.x as f32, at.y - 10.0 * point.y as f32);
        let ctx = egui::Context::default();
        let input = egui::RawInput {
            screen_rect: Some(Rect::from_min_size(Pos2::ZERO, egui::vec2(800.0, 600.0))),
            ..Default::default()
        };
        let mut drawn = BTreeMap::new();
        let mut output = ctx.run_ui(input, |ui| {
            drawn = paint(
                ui.painter(),
                &project,
                &layers,
                &BTreeSet::new(),
                None,
                &[plan_label],
                &[],
                ui.painter().clip_rect(),
            )
            .0;
        });
        assert_eq!(drawn.values().sum::<usize>(), 2);
        let boxes = text_boxes(&output);
        assert_eq!(boxes.len(), 2, "{boxes:?}");
        for (text, rect) in &boxes {
            assert_eq!(text, "goal");
            assert!(
                !rect.intersects(plan_label),
                "{rect:?} over the plan's label"
            );
            // Near its point still: in the first rings round it.
            assert!(rect.distance_to_pos(at) < 60.0, "{rect:?} far from {at:?}");
        }
        assert!(!boxes[0].1.intersects(boxes[1].1), "{boxes:?}");
        output.textures_delta.clear();
    }

    /// Issue 37, defect 4: a module's markers go when it stops (the observer's "358° of
    /// 360°" stayed on the map long after it had), and come back when it runs again.
    #[test]
    fn a_stopped_modules_markers_are_not_drawn() {
        use armor_protocol::ModuleState;
        let hidden: BTreeSet<String> = ["scan_layer".to_owned()].into();
        let mut states = BTreeMap::new();
        states.insert("observer".to_owned(), ModuleState::Running);
        states.insert("follower".to_owned(), ModuleState::Running);
        assert_eq!(not_drawn(&hidden, &states), hidden);
        states.insert("observer".to_owned(), ModuleState::Stopped);
        states.insert("follower".to_owned(), ModuleState::Exited);
        let off = not_drawn(&hidden, &states);
        assert!(off.contains("observer") && off.contains("follower") && off.contains("scan_layer"));
        states.insert("observer".to_owned(), ModuleState::Restarting);
        assert!(!not_drawn(&hidden, &states).contains("observer"));
    }

    /// The switch of a stopped module's layer says why its markers are not drawn.
    #[test]
    fn a_stopped_modules_switch_says_its_markers_are_not_drawn() {
        let mut layers = Layers::default();
        for module in ["observer", "follower"] {
            layers.by_module.insert(
                module.to_owned(),
                Arc::new(Markers {
                    markers: vec![Marker::default()],
                }),
            );
        }
        let stopped: BTreeSet<String> = ["observer".to_owned()].into();
        let ctx = egui::Context::default();
        let mut output = ctx.run_ui(egui::RawInput::default(), |ui| {
            toggles_ui(ui, &layers, &mut BTreeSet::new(), &stopped);
        });
        let texts: Vec<String> = text_boxes(&output)
            .into_iter()
            .map(|(text, _)| text)
            .collect();
        assert!(
            texts.contains(&"observer (1 markers, not drawn: the module stopped)".to_owned())
                && texts.contains(&"follower (1 markers)".to_owned()),
            "{texts:?}"
        );
        output.textures_delta.clear();
    }
}

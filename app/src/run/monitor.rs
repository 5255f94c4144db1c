//! The run view's pieces: one module's row (state, switches, cycle time, rates with a plot),
//! the firing timeline, and what is painted on the live map (the grid, the follower's paths, the
//! scan, the poses).

use std::collections::VecDeque;
use std::sync::Arc;

use armor_model::world::Point;
use armor_module_api::types::{LocalisationState, OccupancyGrid, Pose2D, PoseEstimate};
use armor_protocol::{FiringRecord, ModuleState, ModuleStatus, Request};
use egui::{Align2, Color32, Pos2, RichText, Stroke, Ui};
use egui_plot::{Line, Plot, Points};

use super::followed::FollowedLeg;
use super::live::LiveData;
use super::session::Sample;
use super::untrusted::{self, Refused};
use crate::common::draw::state_colour;
use crate::common::labels::{Importance, Label, Placed};
use crate::mission::Beside;

const TRUTH: Color32 = Color32::from_rgb(20, 110, 220);
const ESTIMATE: Color32 = Color32::from_rgb(230, 120, 0);
const SCAN: Color32 = Color32::from_rgb(220, 30, 60);

/// Rates and cycle time between the last two samples of a module's counters.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rates {
    /// Events per second taken by the module's loop.
    pub cycles_per_sec: f64,
    /// Real milliseconds of the module's own code per event.
    pub cycle_ms: f64,
    /// Samples per second, per output (data name) and per input (name, after the outputs).
    pub sent: Vec<(String, f64)>,
    pub received: Vec<(String, f64)>,
    /// Payload bytes per second, per input: the bandwidth of the link into it.
    pub received_bytes: Vec<(String, f64)>,
}

/// The rates between two samples (a process restarted in between counts from zero).
pub fn rates(before: &Sample, after: &Sample) -> Rates {
    let secs = (after.at_secs - before.at_secs).max(1e-6);
    let delta = |a: u64, b: u64| if b >= a { b - a } else { b };
    let per = |map_after: &std::collections::BTreeMap<String, u64>,
               map_before: &std::collections::BTreeMap<String, u64>| {
        map_after
            .iter()
            .map(|(name, count)| {
                let before = map_before.get(name).copied().unwrap_or(0);
                (name.clone(), delta(before, *count) as f64 / secs)
            })
            .collect()
    };
    let cycles = delta(before.stats.cycles, after.stats.cycles);
    let busy_us = delta(before.stats.busy_us, after.stats.busy_us);
    Rates {
        cycles_per_sec: cycles as f64 / secs,
        cycle_ms: if cycles == 0 {
            0.0
        } else {
            busy_us as f64 / 1e3 / cycles as f64
        },
        sent: per(&after.stats.sent, &before.stats.sent),
        received: per(&after.stats.received, &before.stats.received),
        received_bytes: per(&after.stats.received_bytes, &before.stats.received_bytes),
    }
}

/// A link's bandwidth, `12.3 kB/s` (decimal units, as network rates are given).
pub fn bandwidth_text(bytes_per_sec: f64) -> String {
    if bytes_per_sec >= 1e6 {
        format!("{:.1} MB/s", bytes_per_sec / 1e6)
    } else if bytes_per_sec >= 1e3 {
        format!("{:.1} kB/s", bytes_per_sec / 1e3)
    } else {
        format!("{bytes_per_sec:.0} B/s")
    }
}

/// One module: its state, restarts, switches, cycle time and rates. Returns what the operator
/// asked of it.
pub fn module_row(
    ui: &mut Ui,
    module: &ModuleStatus,
    history: Option<&VecDeque<Sample>>,
    running: bool,
) -> Option<Request> {
    let mut request = None;
    ui.horizontal_wrapped(|ui| {
        let colour = state_colour(module.state);
        ui.label(RichText::new("●").color(colour));
        ui.label(RichText::new(&module.name).strong())
            .on_hover_text(format!("type {}", module.module_type));
        ui.label(RichText::new(module.state.as_str()).color(colour));
        if let Some(host) = &module.host {
            ui.label(RichText::new(format!("on {host}")).weak())
                .on_hover_text("started by that computer's armor host");
        }
        // Why it runs (`place cross_drive`, `needed by follower.odometry`): activation on demand.
        if let (true, None, Some(why)) = (module.controllable, module.manual, &module.why) {
            ui.label(RichText::new(why).weak());
        }
        if module.restarts > 0 {
            let restarts = format!(
                "{} restart{}",
                module.restarts,
                if module.restarts == 1 { "" } else { "s" }
            );
            let label = ui.label(RichText::new(restarts).color(state_colour(ModuleState::Crashed)));
            if let Some(exit) = &module.last_exit {
                label.on_hover_text(format!("last crash: it {exit}"));
            }
        }
        if module.controllable {
            let mut on = !matches!(module.state, ModuleState::Stopped);
            let switch = ui
                .add_enabled(running, egui::Checkbox::new(&mut on, "on"))
                .on_hover_text("start or stop it by hand, whatever the mission wants");
            if switch.changed() {
                request = Some(if on {
                    Request::StartModule {
                        module: module.name.clone(),
                    }
                } else {
                    Request::StopModule {
                        module: module.name.clone(),
                    }
                });
            }
            if module.manual.is_some()
                && ui
                    .add_enabled(running, egui::Button::new("auto").small())
                    .on_hover_text("give it back to the mission")
                    .clicked()
            {
                request = Some(Request::ReleaseModule {
                    module: module.name.clone(),
                });
            }
        } else {
            ui.label(RichText::new("always on").weak())
                .on_hover_text("not controllable: it runs whenever its process does");
        }
    });
    if let Some(exit) = &module.last_exit {
        ui.label(
            RichText::new(format!("crashed: it {exit}"))
                .small()
                .color(state_colour(ModuleState::Crashed)),
        );
    }
    let Some(history) = history.filter(|history| history.len() >= 2) else {
        return request;
    };
    let samples: Vec<&Sample> = history.iter().collect();
    let now = rates(samples[samples.len() - 2], samples[samples.len() - 1]);
    let mut line = format!(
        "cycle {:.3} ms · {:.0} events/s",
        now.cycle_ms, now.cycles_per_sec
    );
    for (name, rate) in &now.sent {
        line.push_str(&format!(" · out {name} {rate:.1}/s"));
    }
    for (name, rate) in &now.received {
        line.push_str(&format!(" · in {name} {rate:.1}/s"));
        if let Some((_, bytes)) = now.received_bytes.iter().find(|(input, _)| input == name) {
            line.push_str(&format!(" {}", bandwidth_text(*bytes)));
        }
    }
    ui.label(RichText::new(line).small());
    // The first output's rate over time, else the loop's.
    let main = now.sent.first().map(|(name, _)| name.clone());
    let points: Vec<[f64; 2]> = samples
        .windows(2)
        .map(|pair| {
            let rates = rates(pair[0], pair[1]);
            let value = match &main {
                Some(name) => rates
                    .sent
                    .iter()
                    .find(|(n, _)| n == name)
                    .map_or(0.0, |(_, rate)| *rate),
                None => rates.cycles_per_sec,
            };
            [pair[1].at_secs, value]
        })
        .collect();
    Plot::new(("rate", &module.name))
        .height(36.0)
        .show_axes([false, true])
        .show_grid(false)
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
        .allow_boxed_zoom(false)
        .allow_double_click_reset(false)
        .include_y(0.0)
        .show_x(false)
        .show(ui, |plot| {
            plot.line(
                Line::new(main.as_deref().unwrap_or("events/s"), points)
                    .stroke(Stroke::new(1.5, state_colour(module.state))),
            );
        });
    request
}

/// The firings so far on a time line, with the latest listed.
pub fn timeline_ui(ui: &mut Ui, firings: &[FiringRecord]) {
    if firings.is_empty() {
        ui.label(RichText::new("none yet").weak());
        return;
    }
    let by_schedule: Vec<[f64; 2]> = firings
        .iter()
        .enumerate()
        .filter(|(_, f)| !f.by_hand)
        .map(|(i, f)| [f.run_secs, i as f64])
        .collect();
    let by_hand: Vec<[f64; 2]> = firings
        .iter()
        .enumerate()
        .filter(|(_, f)| f.by_hand)
        .map(|(i, f)| [f.run_secs, i as f64])
        .collect();
    Plot::new("firings")
        .height(90.0)
        .allow_scroll(false)
        .allow_zoom(false)
        .allow_drag(false)
        .show_axes([true, false])
        .show(ui, |plot| {
            plot.points(Points::new("fired", by_schedule).radius(3.0));
            plot.points(
                Points::new("fired by hand", by_hand)
                    .radius(4.0)
                    .color(Color32::from_rgb(200, 60, 160)),
            );
        });
    egui::ScrollArea::vertical()
        .id_salt("firings-list")
        .max_height(120.0)
        .stick_to_bottom(true)
        .show(ui, |ui| {
            for firing in firings {
                ui.label(
                    RichText::new(format!(
                        "{:>8.2} s  {}{}",
                        firing.run_secs,
                        firing.transition,
                        if firing.by_hand { " (by hand)" } else { "" }
                    ))
                    .monospace()
                    .small(),
                );
            }
        });
}

/// The colour of a localisation state: green when localised, amber when uncertain, red when
/// lost (the module states' colours, so that one colour means one thing across the view).
pub fn localisation_colour(state: LocalisationState) -> Color32 {
    match state {
        LocalisationState::Localised => state_colour(ModuleState::Running),
        LocalisationState::Uncertain => Color32::from_rgb(200, 130, 0),
        LocalisationState::Lost => state_colour(ModuleState::Failed),
    }
}

/// The localiser's estimate in words: `localised · σ 0.04 m, 1.2° · scan fit 0.81`.
pub fn estimate_text(estimate: &PoseEstimate) -> String {
    let heading_sigma_deg = estimate.covariance[8].max(0.0).sqrt().to_degrees();
    format!(
        "{} · σ {:.2} m, {:.1}° · scan fit {:.2}",
        estimate.state.as_str(),
        estimate.position_sigma_m(),
        heading_sigma_deg,
        estimate.fit
    )
}

/// How many standard deviations the uncertainty ellipse spans: two, where the robot is with a
/// probability of 86 % (a bivariate normal), as rviz draws AMCL's covariance.
pub const ELLIPSE_SIGMAS: f64 = 2.0;
/// An ellipse wider than this (metres, a semi-axis) says nothing a map can show: not drawn.
const MAX_ELLIPSE_M: f64 = 500.0;

/// The outline of the [`ELLIPSE_SIGMAS`] ellipse of `estimate`'s position covariance round
/// `centre` (world frame), `points` points; `None` when the covariance is not a covariance
/// (negative or non-finite variances) or too wide to draw.
pub fn uncertainty_ellipse(
    estimate: &PoseEstimate,
    centre: Point,
    points: usize,
) -> Option<Vec<Point>> {
    let c = &estimate.covariance;
    let (a, b, d) = (c[0], c[1], c[4]);
    if ![a, b, d].iter().all(|v| v.is_finite()) || a < 0.0 || d < 0.0 {
        return None;
    }
    let half_trace = (a + d) / 2.0;
    let spread = (((a - d) / 2.0).powi(2) + b * b).sqrt();
    let major = ELLIPSE_SIGMAS * (half_trace + spread).max(0.0).sqrt();
    let minor = ELLIPSE_SIGMAS * (half_trace - spread).max(0.0).sqrt();
    if !(major.is_finite() && major <= MAX_ELLIPSE_M) {
        return None;
    }
    // The major axis's direction: the eigenvector of the larger eigenvalue.
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    let (sin, cos) = angle.sin_cos();
    Some(
        (0..points)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / points as f64;
                let (u, v) = (major * t.cos(), minor * t.sin());
                Point::new(centre.x + u * cos - v * sin, centre.y + u * sin + v * cos)
            })
            .collect(),
    )
}

/// The poses in words, for the map's corner.
pub fn pose_text(live: &LiveData) -> String {
    let pose = |pose: &Option<Pose2D>| {
        pose.as_ref().map_or("—".to_owned(), |p| {
            format!(
                "({:.2}, {:.2}) {:.0}°",
                p.x_m,
                p.y_m,
                p.theta_rad.to_degrees()
            )
        })
    };
    format!(
        "estimated {} · true {}",
        pose(&live.estimated),
        pose(&live.truth)
    )
}

/// The occupancy grid as a picture at most `max_side` pixels a side (see
/// [`untrusted::grid_picture`]): unknown cells clear, free ones pale, occupied ones dark, the
/// grid's southern edge at the bottom. A grid that is too large or inconsistent is refused
/// before anything its size is allocated.
pub fn grid_image(grid: &OccupancyGrid, max_side: usize) -> Result<egui::ColorImage, Refused> {
    let picture = untrusted::grid_picture(grid, max_side)?;
    Ok(egui::ColorImage::from_rgba_unmultiplied(
        picture.size,
        &picture.rgba,
    ))
}

/// Paints what lies under the robots: the grid, the paths the follower follows and replaced,
/// the true path, the scan and the estimate's uncertainty. The modules' markers go over these,
/// then the robots over everything ([`paint_robots`]).
pub fn paint_live(
    painter: &egui::Painter,
    project: &dyn Fn(Point) -> Pos2,
    live: &LiveData,
    grid: Option<&(egui::TextureHandle, Arc<OccupancyGrid>)>,
    followed: &FollowedLeg,
) {
    if let Some((texture, grid)) = grid {
        let min = project(Point::new(grid.origin_x_m, grid.origin_y_m));
        let max = project(Point::new(
            grid.origin_x_m + grid.resolution_m * f64::from(grid.width),
            grid.origin_y_m + grid.resolution_m * f64::from(grid.height),
        ));
        painter.image(
            texture.id(),
            egui::Rect::from_two_pos(min, max),
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            Color32::WHITE,
        );
    }
    followed.paint(painter, project);
    let trail: Vec<Pos2> = live
        .trail
        .iter()
        .map(|(x, y)| project(Point::new(*x, *y)))
        .collect();
    // The trail fades out behind the robot: older segments are lighter.
    let segments = trail.len().saturating_sub(1);
    for (i, pair) in trail.windows(2).enumerate() {
        let age = (i + 1) as f32 / segments.max(1) as f32;
        painter.line_segment(
            [pair[0], pair[1]],
            Stroke::new(2.0, TRUTH.gamma_multiply(0.1 + 0.7 * age)),
        );
    }
    if let (Some(scan), Some(pose)) = (&live.scan, live.scan_pose()) {
        for (x_m, y_m) in untrusted::scan_hits(scan, pose) {
            painter.circle_filled(project(Point::new(x_m, y_m)), 1.6, SCAN);
        }
    }
    // The estimate's uncertainty under both robots, round the pose the follower drives by.
    if let (Some(estimate), Some(pose)) = (&live.estimate, &live.estimated)
        && let Some(outline) =
            uncertainty_ellipse(estimate, Point::new(pose.x_m, pose.y_m), ELLIPSE_POINTS)
    {
        let colour = localisation_colour(estimate.state);
        let outline: Vec<Pos2> = outline.into_iter().map(project).collect();
        // An ellipse inside the robot's disc says only "certain": drawn, it is one more ring
        // round the robot (the tag says the state in words).
        let beyond_robot = on_screen(project, pose).is_some_and(|(centre, _, radius)| {
            outline
                .iter()
                .any(|p| p.distance(centre) > radius + ROBOT_RING_POINTS)
        });
        if beyond_robot && outline.iter().all(|p| p.is_finite()) {
            painter.add(egui::Shape::convex_polygon(
                outline,
                colour.gamma_multiply(0.18),
                Stroke::new(2.0, colour),
            ));
        }
    }
}

/// Paints both poses and their tags (placed with the plan's labels, `robot_tags`), last of
/// the map's shapes, so that no ring, path or marker runs over the robot: a newcomer must see
/// it whole.
pub fn paint_robots(
    painter: &egui::Painter,
    project: &dyn Fn(Point) -> Pos2,
    live: &LiveData,
    tags: Vec<Placed>,
) {
    // The truth first, hollow, so that the estimate over it stays whole when they agree.
    if let Some(pose) = &live.truth {
        true_robot(painter, project, pose);
    }
    if let Some(pose) = &live.estimated {
        robot(painter, project, pose, ESTIMATE);
    }
    for placed in tags {
        if let Some(leader) = placed.leader {
            painter.line_segment(leader, Stroke::new(1.5, placed.colour));
        }
        painter.rect(
            placed.rect,
            4.0,
            placed.colour,
            Stroke::new(1.0, Color32::WHITE),
            egui::StrokeKind::Inside,
        );
        let galley = painter.layout_no_wrap(placed.text, TAG_FONT, Color32::WHITE);
        let inset = (placed.rect.size() - galley.size()) / 2.0;
        painter.galley(placed.rect.min + inset, galley, Color32::WHITE);
    }
}

/// What the map's labels are placed with while a run is watched: the robots' boxes, which no
/// label covers, and their tags (`localised`, `truth (simulator)`), placed first.
pub fn robot_tags(
    painter: &egui::Painter,
    project: &dyn Fn(Point) -> Pos2,
    live: &LiveData,
) -> Beside {
    let mut tags = Vec::new();
    if let Some(pose) = &live.estimated {
        let (text, colour) = match &live.estimate {
            Some(estimate) => (
                estimate.state.as_str().to_owned(),
                localisation_colour(estimate.state),
            ),
            None => ("estimate".to_owned(), ESTIMATE),
        };
        tags.extend(tag_label(
            project,
            pose,
            text,
            colour,
            Align2::CENTER_BOTTOM,
        ));
    }
    if let Some(pose) = &live.truth {
        tags.extend(tag_label(
            project,
            pose,
            TRUTH_LABEL.to_owned(),
            TRUTH,
            Align2::CENTER_TOP,
        ));
    }
    let tags = tags
        .into_iter()
        .map(|tag| {
            let size = painter
                .layout_no_wrap(tag.text.clone(), TAG_FONT, Color32::WHITE)
                .size()
                + TAG_PADDING;
            (tag, size)
        })
        .collect();
    Beside {
        obstacles: robot_boxes(project, live),
        tags,
    }
}

/// The tags' text size, and the room round their text (beyond the placer's margin).
const TAG_FONT: egui::FontId = egui::FontId::proportional(14.0);
const TAG_PADDING: egui::Vec2 = egui::vec2(6.0, 0.0);
/// How far the truth's dashed ring stands out of the robot's disc, its stroke included.
const ROBOT_RING_POINTS: f32 = 5.0;

/// The boxes the robots take on the map (the estimate's disc, the truth's ring and heading):
/// no label may cover them.
pub fn robot_boxes(project: &dyn Fn(Point) -> Pos2, live: &LiveData) -> Vec<egui::Rect> {
    [&live.estimated, &live.truth]
        .into_iter()
        .flatten()
        .filter_map(|pose| on_screen(project, pose))
        .map(|(centre, _, radius)| {
            egui::Rect::from_center_size(
                centre,
                egui::Vec2::splat(2.0 * (radius + ROBOT_RING_POINTS)),
            )
        })
        .collect()
}

/// A robot's tag, to place beside it (first on the `preferred` side).
fn tag_label(
    project: &dyn Fn(Point) -> Pos2,
    pose: &Pose2D,
    text: String,
    colour: Color32,
    preferred: Align2,
) -> Option<Label> {
    let (centre, _, radius) = on_screen(project, pose)?;
    Some(Label {
        anchors: vec![centre],
        gap: radius + ROBOT_RING_POINTS + 1.0,
        preferred,
        text,
        colour,
        importance: Importance::Robot,
    })
}

/// Points of the uncertainty ellipse's outline.
const ELLIPSE_POINTS: usize = 48;
/// The label of the simulator's pose on the map: it is the judge, not something the robot
/// knows.
pub const TRUTH_LABEL: &str = "truth (simulator)";

/// The simulator's pose: the robot's outline only, dashed, with its heading as a line, so that
/// it never reads as a second robot nor hides the estimate drawn over it.
fn true_robot(painter: &egui::Painter, project: &dyn Fn(Point) -> Pos2, pose: &Pose2D) {
    let Some((centre, dir, radius)) = on_screen(project, pose) else {
        return;
    };
    let radius = radius + 3.0;
    let outline: Vec<Pos2> = (0..=40)
        .map(|i| {
            let t = std::f32::consts::TAU * i as f32 / 40.0;
            centre + egui::vec2(t.cos(), t.sin()) * radius
        })
        .collect();
    painter.extend(egui::Shape::dashed_line(
        &outline,
        Stroke::new(2.5, TRUTH),
        6.0,
        4.0,
    ));
    painter.line_segment(
        [centre, centre + dir * (radius + 8.0)],
        Stroke::new(2.5, TRUTH),
    );
}

/// A button of the drive pad: an arrow pointing along `direction` (screen axes), drawn rather
/// than taken from the font (which lacks ▲ and ▼), named `name` for screen readers and tests.
/// True while the pointer holds it down.
pub fn pad_button(ui: &mut Ui, direction: egui::Vec2, name: &str) -> bool {
    let (rect, response) =
        ui.allocate_exact_size(egui::vec2(40.0, 32.0), egui::Sense::click_and_drag());
    response.widget_info(|| egui::WidgetInfo::labeled(egui::WidgetType::Button, true, name));
    let visuals = ui.style().interact(&response);
    ui.painter().rect(
        rect,
        visuals.corner_radius,
        visuals.bg_fill,
        visuals.bg_stroke,
        egui::StrokeKind::Inside,
    );
    let centre = rect.center();
    let side = egui::vec2(-direction.y, direction.x);
    ui.painter().add(egui::Shape::convex_polygon(
        vec![
            centre + direction * 9.0,
            centre - direction * 6.0 + side * 8.0,
            centre - direction * 6.0 - side * 8.0,
        ],
        visuals.fg_stroke.color,
        Stroke::NONE,
    ));
    response.on_hover_text(name).is_pointer_button_down_on()
}

/// The least a robot is drawn across, in points, whatever the zoom: a newcomer must find it.
pub const ROBOT_MIN_POINTS: f32 = 26.0;

/// Where a robot at `pose` is drawn: its centre, the unit vector of its heading on the screen
/// and its radius (its real 0.3 m or half [`ROBOT_MIN_POINTS`], whichever is larger); `None`
/// when the projection is not finite.
fn on_screen(project: &dyn Fn(Point) -> Pos2, pose: &Pose2D) -> Option<(Pos2, egui::Vec2, f32)> {
    let centre = project(Point::new(pose.x_m, pose.y_m));
    let (sin, cos) = pose.theta_rad.sin_cos();
    let ahead = project(Point::new(pose.x_m + cos, pose.y_m + sin)) - centre;
    let metre = ahead.length();
    if !metre.is_finite() || !centre.is_finite() {
        return None;
    }
    let dir = if metre > 0.0 {
        ahead / metre
    } else {
        egui::vec2(1.0, 0.0)
    };
    Some((centre, dir, (0.3 * metre).max(ROBOT_MIN_POINTS / 2.0)))
}

/// `colour` mixed with white, two parts in three white, opaque.
fn pale(colour: Color32) -> Color32 {
    let mix = |channel: u8| ((u16::from(channel) + 2 * 255) / 3) as u8;
    Color32::from_rgb(mix(colour.r()), mix(colour.g()), mix(colour.b()))
}

/// A robot: a disc with an arrow pointing where it heads, its real size (0.6 m) or
/// [`ROBOT_MIN_POINTS`] across, whichever is larger, rimmed so it shows on any tile.
fn robot(painter: &egui::Painter, project: &dyn Fn(Point) -> Pos2, pose: &Pose2D, colour: Color32) {
    let Some((centre, dir, radius)) = on_screen(project, pose) else {
        return;
    };
    // Opaque (the colour paled towards white, not made transparent): what lies under the
    // robot (its true pose's ring, a waypoint's) does not show through it.
    painter.circle(centre, radius, pale(colour), Stroke::new(2.0, colour));
    let side = egui::vec2(-dir.y, dir.x);
    let points = vec![
        centre + dir * radius * 0.85,
        centre - dir * radius * 0.55 + side * radius * 0.55,
        centre - dir * radius * 0.55 - side * radius * 0.55,
    ];
    painter.add(egui::Shape::convex_polygon(
        points,
        colour,
        Stroke::new(1.5, Color32::WHITE),
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::protocol::NodeStats;
    use std::f64::consts::PI;

    fn sample(at_secs: f64, cycles: u64, busy_us: u64, sent: u64) -> Sample {
        Sample {
            at_secs,
            stats: NodeStats {
                cycles,
                busy_us,
                sent: [("sim.odometry".to_owned(), sent)].into(),
                received: Default::default(),
                ..Default::default()
            },
        }
    }

    fn estimate(covariance: [f64; 9]) -> PoseEstimate {
        PoseEstimate {
            covariance,
            ..PoseEstimate::default()
        }
    }

    /// The outline's farthest point from the centre: its distance and direction (radians).
    fn major(outline: &[Point]) -> (f64, f64) {
        outline
            .iter()
            .map(|p| (p.x.hypot(p.y), p.y.atan2(p.x)))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or_default()
    }

    #[test]
    fn the_ellipse_spans_two_standard_deviations_along_the_covariance_s_axes() {
        // σx = 0.2 m, σy = 0.1 m: 0.4 m along x, 0.2 m along y.
        let outline = uncertainty_ellipse(
            &estimate([0.04, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0]),
            Point::new(0.0, 0.0),
            360,
        )
        .expect("an ellipse");
        let (length, direction) = major(&outline);
        assert!((length - 0.4).abs() < 1e-9, "{length}");
        assert!(direction.abs() < 1e-9 || (direction.abs() - PI).abs() < 1e-9);
        let least = outline
            .iter()
            .map(|p| p.x.hypot(p.y))
            .fold(f64::INFINITY, f64::min);
        assert!((least - 0.2).abs() < 1e-9, "{least}");
        // Correlated x and y: eigenvalues 0.03 and 0.01, the long axis (2 × √0.03 m) on the
        // diagonal.
        let outline = uncertainty_ellipse(
            &estimate([0.02, 0.01, 0.0, 0.01, 0.02, 0.0, 0.0, 0.0, 0.0]),
            Point::new(3.0, 4.0),
            360,
        )
        .expect("an ellipse");
        let centred: Vec<Point> = outline
            .iter()
            .map(|p| Point::new(p.x - 3.0, p.y - 4.0))
            .collect();
        let (length, direction) = major(&centred);
        assert!((length - 2.0 * 0.03_f64.sqrt()).abs() < 1e-9, "{length}");
        assert!(
            (direction.abs() - PI / 4.0).abs() < 1e-6
                || (direction.abs() - 3.0 * PI / 4.0).abs() < 1e-6,
            "{direction}"
        );
    }

    #[test]
    fn a_covariance_that_is_none_or_too_wide_draws_no_ellipse() {
        let at = Point::new(0.0, 0.0);
        for covariance in [
            [f64::NAN, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0],
            [-0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0],
            [1e300, 0.0, 0.0, 0.0, 1e300, 0.0, 0.0, 0.0, 0.0],
            [f64::INFINITY, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0],
        ] {
            assert_eq!(
                uncertainty_ellipse(&estimate(covariance), at, 8),
                None,
                "{covariance:?}"
            );
        }
        assert!(
            uncertainty_ellipse(&estimate([0.0; 9]), at, 8).is_some(),
            "a point is one"
        );
    }

    #[test]
    fn rates_are_differences_over_time() {
        let rates = rates(&sample(1.0, 100, 1_000, 50), &sample(1.5, 200, 3_000, 75));
        assert_eq!(rates.cycles_per_sec, 200.0);
        assert_eq!(rates.cycle_ms, 0.02);
        assert_eq!(rates.sent, vec![("sim.odometry".to_owned(), 50.0)]);
    }

    #[test]
    fn a_links_bandwidth_is_its_bytes_over_time() {
        let mut before = sample(1.0, 0, 0, 0);
        let mut after = sample(2.0, 0, 0, 0);
        before.stats.received_bytes = [("odometry".to_owned(), 1_000)].into();
        after.stats.received_bytes = [("odometry".to_owned(), 26_000)].into();
        let rates = rates(&before, &after);
        assert_eq!(
            rates.received_bytes,
            vec![("odometry".to_owned(), 25_000.0)]
        );
        assert_eq!(bandwidth_text(25_000.0), "25.0 kB/s");
        assert_eq!(bandwidth_text(2_500_000.0), "2.5 MB/s");
        assert_eq!(bandwidth_text(12.0), "12 B/s");
    }

    #[test]
    fn a_restart_counts_from_zero() {
        let rates = rates(&sample(1.0, 100, 1_000, 50), &sample(2.0, 10, 100, 5));
        assert_eq!(rates.sent, vec![("sim.odometry".to_owned(), 5.0)]);
    }

    #[test]
    fn the_grid_picture_has_its_south_row_at_the_bottom() {
        let grid = OccupancyGrid {
            resolution_m: 0.5,
            width: 2,
            height: 2,
            origin_x_m: 0.0,
            origin_y_m: 0.0,
            cells: vec![100, 0, -1, -1],
        };
        let image = grid_image(&grid, 2048).expect("a good grid");
        assert_eq!(image.size, [2, 2]);
        assert_eq!(image.pixels[0], Color32::TRANSPARENT, "unknown, top row");
        assert!(
            image.pixels[2].r() < image.pixels[3].r(),
            "occupied darker than free"
        );
    }

    #[test]
    fn a_huge_or_inconsistent_grid_has_no_picture() {
        // The old code allocated `width × height` pixels on the grid's word: 2^64 − 2^33 + 1
        // of them here, a capacity overflow.
        let huge = OccupancyGrid {
            resolution_m: 0.5,
            width: u32::MAX,
            height: u32::MAX,
            cells: vec![0; 4],
            ..OccupancyGrid::default()
        };
        let err = grid_image(&huge, 2048).expect_err("refused");
        assert!(matches!(err, Refused::GridTooLarge { .. }), "{err}");
        let inconsistent = OccupancyGrid {
            width: 3,
            height: 3,
            ..huge
        };
        let err = grid_image(&inconsistent, 2048).expect_err("refused");
        assert!(
            matches!(err, Refused::GridInconsistent { cells: 4, .. }),
            "{err}"
        );
    }
}

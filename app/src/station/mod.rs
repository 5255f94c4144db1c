//! The operator's station (issue 41): every robot of a team in one table (its colour, mission
//! state, leg, localisation, the age of its last report, its link's quality, its camera's
//! rate) and on one map
//! with its plan's route, and a command or a plan update sent to one robot or to all, with the
//! station's rights: an observer's station reads, and its commands are greyed with the reason.
//!
//! The data comes from `armor-team station` ([`link`]), which holds the sessions with the
//! robots over zenoh; a robot not heard from in 2 s is shown greyed with its last known state,
//! and catches up when it is heard again. `armor-studio --station ARGS…` opens this view in a
//! window of its own ([`crate::run_station`]).

pub mod link;

use std::collections::BTreeMap;

use armor_protocol::team::{RobotReport, StationEvent};
use egui::{Color32, Pos2, Rect, Stroke, Vec2};

pub use link::{FromStation, Link, team_program};

/// A report older than this is the robot's last known state, drawn greyed.
pub const STALE_SECS: f64 = 2.0;

/// Distinct colours for the robots, in the order of their names.
const COLOURS: [Color32; 10] = [
    Color32::from_rgb(31, 119, 180),
    Color32::from_rgb(255, 127, 14),
    Color32::from_rgb(44, 160, 44),
    Color32::from_rgb(214, 39, 40),
    Color32::from_rgb(148, 103, 189),
    Color32::from_rgb(140, 86, 75),
    Color32::from_rgb(227, 119, 194),
    Color32::from_rgb(127, 127, 127),
    Color32::from_rgb(188, 189, 34),
    Color32::from_rgb(23, 190, 207),
];

/// Why an observer's commands are greyed.
pub const OBSERVER_CANNOT: &str = "an observer's station cannot command: its key is the observer role's (the operator's key commands: armor secret derive --role operator)";

/// What a command goes to.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Target {
    One(String),
    All,
}

/// The station view's state.
pub struct StationView {
    link: Link,
    /// `operator` or `observer`, once the station said.
    role: Option<String>,
    robots: BTreeMap<String, RobotReport>,
    /// The robots in the order the station names them (the operator's order), for the table
    /// and the colours.
    order: Vec<String>,
    target: Target,
    /// The plan file a plan update sends (read by the station program, on this computer).
    plan_path: String,
    /// The latest answers and errors, newest last.
    answers: Vec<(bool, String)>,
    closed: Option<String>,
}

impl std::fmt::Debug for StationView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StationView")
            .field("role", &self.role)
            .field("robots", &self.robots.len())
            .finish()
    }
}

/// How many answers the view keeps.
const ANSWERS: usize = 6;

impl StationView {
    pub fn new(link: Link) -> StationView {
        StationView {
            link,
            role: None,
            robots: BTreeMap::new(),
            order: Vec::new(),
            target: Target::All,
            plan_path: String::new(),
            answers: Vec::new(),
            closed: None,
        }
    }

    /// Whether this station may command (it proved the operator's role).
    pub fn can_command(&self) -> bool {
        self.role.as_deref() == Some("operator")
    }

    /// The robots shown, in the station's order.
    pub fn robots(&self) -> impl Iterator<Item = &RobotReport> {
        self.order.iter().filter_map(|robot| self.robots.get(robot))
    }

    /// Takes what the station sent since the last frame.
    pub fn take_events(&mut self) {
        while let Ok(event) = self.link.events.try_recv() {
            match event {
                FromStation::Event(StationEvent::Station { role, robots }) => {
                    self.role = Some(role);
                    self.order.clone_from(&robots);
                    for robot in robots {
                        self.robots.entry(robot.clone()).or_insert(RobotReport {
                            robot,
                            ..RobotReport::default()
                        });
                    }
                }
                FromStation::Event(StationEvent::Robot(report)) => {
                    if !self.order.contains(&report.robot) {
                        self.order.push(report.robot.clone());
                    }
                    self.robots.insert(report.robot.clone(), *report);
                }
                // The command names its robot; a refusal's message says why in words.
                FromStation::Event(StationEvent::Answer {
                    robot,
                    command,
                    ok,
                    message,
                }) => {
                    let text = if ok {
                        format!("{command}: {robot} done: {message}")
                    } else {
                        format!("{command}: {robot}: {message}")
                    };
                    self.answer(ok, text);
                }
                FromStation::Event(StationEvent::Error { message }) => {
                    self.answer(false, message);
                }
                FromStation::Closed(why) => self.closed = Some(why),
            }
        }
    }

    fn answer(&mut self, ok: bool, text: String) {
        self.answers.push((ok, text));
        let extra = self.answers.len().saturating_sub(ANSWERS);
        self.answers.drain(..extra);
    }

    fn send(&mut self, command: &str) {
        let target = match &self.target {
            Target::One(robot) => robot.clone(),
            Target::All => "all".to_owned(),
        };
        let line = format!("{target} {command}");
        if self.link.commands.send(line.clone()).is_err() {
            self.answer(false, format!("{line}: the station program has ended"));
        } else {
            self.answer(true, format!("{line}: sent"));
        }
    }

    fn colour(&self, robot: &str) -> Color32 {
        let index = self.order.iter().position(|name| name == robot);
        COLOURS[index.unwrap_or(0) % COLOURS.len()]
    }

    /// The whole view: the title bar, the table and commands on the left, the map.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        self.take_events();
        egui::Panel::top("station-title").show(ui, |ui| self.title_ui(ui));
        // Wide enough for the table's eight columns, and no wider: the map gets the rest.
        egui::Panel::left("station-robots")
            .exact_size(640.0)
            .resizable(false)
            .show(ui, |ui| {
                self.table_ui(ui);
                ui.separator();
                self.commands_ui(ui);
            });
        egui::CentralPanel::default().show(ui, |ui| self.map_ui(ui));
        // Reports come every half second; the ages in the table move between them.
        ui.ctx()
            .request_repaint_after(std::time::Duration::from_millis(250));
    }

    fn title_ui(&self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.heading("Team station");
            let role = self.role.as_deref().unwrap_or("connecting…");
            ui.label(format!("role: {role}"));
            ui.label(format!("{} robots", self.robots.len()));
            let stale = self
                .robots
                .values()
                .filter(|report| is_stale(report))
                .count();
            if stale > 0 {
                ui.colored_label(
                    ui.visuals().warn_fg_color,
                    format!("{stale} not heard from in {STALE_SECS:.0} s"),
                );
            }
            if let Some(why) = &self.closed {
                ui.colored_label(ui.visuals().error_fg_color, why);
            }
        });
    }

    fn table_ui(&mut self, ui: &mut egui::Ui) {
        let mut chosen = None;
        egui::ScrollArea::vertical()
            .max_height(ui.available_height() * 0.62)
            .show(ui, |ui| {
                egui::Grid::new("station-table")
                    .striped(true)
                    .num_columns(8)
                    .show(ui, |ui| {
                        for header in [
                            "Robot",
                            "State",
                            "Leg",
                            "Localisation",
                            "Report",
                            "Link",
                            "kbit/s",
                            "Camera",
                        ] {
                            ui.strong(header);
                        }
                        ui.end_row();
                        for report in self.robots() {
                            let colour = self.colour(&report.robot);
                            let stale = is_stale(report);
                            let text = |text: String| {
                                let text = egui::RichText::new(text);
                                if stale { text.weak().italics() } else { text }
                            };
                            let selected = self.target == Target::One(report.robot.clone());
                            ui.horizontal(|ui| {
                                let (rect, _) =
                                    ui.allocate_exact_size(Vec2::splat(10.0), egui::Sense::hover());
                                ui.painter().circle_filled(
                                    rect.center(),
                                    5.0,
                                    if stale { grey(colour) } else { colour },
                                );
                                if ui
                                    .selectable_label(selected, text(report.robot.clone()))
                                    .clicked()
                                {
                                    chosen = Some(report.robot.clone());
                                }
                            });
                            let status = report.status.as_ref();
                            let state = match (status, stale) {
                                (Some(status), true) => format!("last known: {}", status.state),
                                (Some(status), false) => status.state.clone(),
                                (None, _) if report.session => "no report yet".to_owned(),
                                (None, _) => report
                                    .refusal
                                    .clone()
                                    .map_or("no session yet".to_owned(), |why| {
                                        format!("no session: {why}")
                                    }),
                            };
                            ui.label(text(state));
                            ui.label(text(
                                status
                                    .and_then(|status| status.leg.clone())
                                    .unwrap_or_else(|| "-".to_owned()),
                            ));
                            ui.label(text(
                                status
                                    .and_then(|status| status.localisation.clone())
                                    .unwrap_or_else(|| "-".to_owned()),
                            ));
                            ui.label(text(
                                report.report_age_secs.map_or_else(
                                    || "-".to_owned(),
                                    |age| format!("{age:.1} s ago"),
                                ),
                            ));
                            ui.label(text(link_text(report)));
                            ui.label(text(format!("{:.1}", report.kbit_per_sec)));
                            ui.label(text(report.camera.as_ref().map_or_else(
                                || "-".to_owned(),
                                |camera| {
                                    format!(
                                        "{:.1}/s, {:.0} kbit/s",
                                        camera.frames_per_sec, camera.kbit_per_sec
                                    )
                                },
                            )));
                            ui.end_row();
                        }
                    });
            });
        if let Some(robot) = chosen {
            self.target = Target::One(robot);
        }
    }

    fn commands_ui(&mut self, ui: &mut egui::Ui) {
        let can = self.can_command();
        ui.horizontal(|ui| {
            ui.strong("Command");
            let name = match &self.target {
                Target::One(robot) => robot.clone(),
                Target::All => "all robots".to_owned(),
            };
            egui::ComboBox::from_id_salt("station-target")
                .selected_text(name)
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut self.target, Target::All, "all robots");
                    let robots = self.order.clone();
                    for robot in robots {
                        ui.selectable_value(&mut self.target, Target::One(robot.clone()), robot);
                    }
                });
        });
        if !can {
            ui.colored_label(ui.visuals().warn_fg_color, OBSERVER_CANNOT);
        }
        let reason = if self.role.is_none() {
            "the station has not proved its role yet"
        } else {
            OBSERVER_CANNOT
        };
        let mut sent = None;
        ui.horizontal(|ui| {
            for (label, command) in [
                ("Pause", "pause"),
                ("Resume", "resume"),
                ("Abort", "abort"),
                ("Status", "status"),
            ] {
                if ui
                    .add_enabled(can, egui::Button::new(label))
                    .on_disabled_hover_text(reason)
                    .clicked()
                {
                    sent = Some(command.to_owned());
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("Plan update:");
            ui.add(
                egui::TextEdit::singleline(&mut self.plan_path)
                    .hint_text("PLAN.xml")
                    .desired_width(260.0),
            );
            let path = self.plan_path.trim().to_owned();
            if ui
                .add_enabled(can && !path.is_empty(), egui::Button::new("Send update"))
                .on_disabled_hover_text(if can {
                    "type the plan file's path first"
                } else {
                    reason
                })
                .clicked()
            {
                sent = Some(format!("update {path}"));
            }
        });
        if let Some(command) = sent {
            self.send(&command);
        }
        for (ok, text) in &self.answers {
            if *ok {
                ui.label(text);
            } else {
                ui.colored_label(ui.visuals().warn_fg_color, text);
            }
        }
    }

    fn map_ui(&self, ui: &mut egui::Ui) {
        let (rect, _) = ui.allocate_exact_size(ui.available_size(), egui::Sense::hover());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
        let Some(bounds) = self.bounds() else {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "no robot has reported where it is yet",
                egui::FontId::proportional(14.0),
                ui.visuals().weak_text_color(),
            );
            return;
        };
        // Room on the right for the names written beside the robots.
        let inner = Rect::from_min_max(
            rect.min + Vec2::splat(24.0),
            rect.max - Vec2::new(80.0, 24.0),
        );
        let frame = MapFrame::fit(bounds, inner);
        frame.grid(&painter, rect, ui.visuals().weak_text_color());
        let text_colour = ui.visuals().text_color();
        for report in self.robots() {
            let colour = self.colour(&report.robot);
            let colour = if is_stale(report) {
                grey(colour)
            } else {
                colour
            };
            if report.route.len() > 1 {
                let points: Vec<Pos2> = report
                    .route
                    .iter()
                    .map(|point| frame.to_screen(point.x_m, point.y_m))
                    .collect();
                painter.add(egui::Shape::line(
                    points.clone(),
                    Stroke::new(2.0, colour.gamma_multiply(0.55)),
                ));
                for point in points {
                    painter.circle_filled(point, 3.0, colour.gamma_multiply(0.55));
                }
            }
            let Some([x_m, y_m, heading_rad]) = report.pose else {
                continue;
            };
            let at = frame.to_screen(x_m, y_m);
            let ahead = at + Vec2::new(heading_rad.cos() as f32, -heading_rad.sin() as f32) * 14.0;
            if self.target == Target::One(report.robot.clone()) {
                painter.circle_stroke(at, 12.0, Stroke::new(2.0, text_colour));
            }
            painter.circle_filled(at, 7.0, colour);
            painter.line_segment([at, ahead], Stroke::new(2.5, colour));
            painter.text(
                at + Vec2::new(10.0, -10.0),
                egui::Align2::LEFT_BOTTOM,
                &report.robot,
                egui::FontId::proportional(13.0),
                text_colour,
            );
        }
    }

    /// The world's box round every pose and route shown.
    fn bounds(&self) -> Option<Rect> {
        let mut bounds: Option<Rect> = None;
        let points = self.robots.values().flat_map(|report| {
            report
                .route
                .iter()
                .map(|point| (point.x_m, point.y_m))
                .chain(report.pose.map(|[x, y, _]| (x, y)))
        });
        for (x, y) in points {
            let point = Pos2::new(x as f32, y as f32);
            bounds = Some(bounds.map_or(Rect::from_min_max(point, point), |bounds| {
                bounds.union(Rect::from_min_max(point, point))
            }));
        }
        // At least 10 m across, so that a lone robot is not drawn at an absurd scale.
        bounds
            .map(|bounds| bounds.expand2((Vec2::splat(10.0) - bounds.size()).max(Vec2::ZERO) / 2.0))
    }
}

fn is_stale(report: &RobotReport) -> bool {
    report.report_age_secs.is_some_and(|age| age > STALE_SECS)
}

/// The link's quality in words (`good`, `fair`, `poor`, `lost`) and the share of reports lost.
fn link_text(report: &RobotReport) -> String {
    let word = report.link.word(report.report_age_secs);
    match report.link.loss() {
        Some(loss) => format!("{word}, loss {:.0} %", loss * 100.0),
        None => word.to_owned(),
    }
}

fn grey(colour: Color32) -> Color32 {
    let [r, g, b, _] = colour.to_array();
    let mean = ((u16::from(r) + u16::from(g) + u16::from(b)) / 3) as u8;
    Color32::from_rgba_unmultiplied(mean, mean, mean, 160)
}

/// The world frame (metres, y up) fitted into a rectangle of the screen (points, y down), one
/// scale for both axes.
struct MapFrame {
    world: Rect,
    screen: Rect,
    points_per_m: f32,
}

impl MapFrame {
    fn fit(world: Rect, screen: Rect) -> MapFrame {
        let points_per_m = (screen.width() / world.width()).min(screen.height() / world.height());
        MapFrame {
            world,
            screen,
            points_per_m,
        }
    }

    fn to_screen(&self, x_m: f64, y_m: f64) -> Pos2 {
        let offset = Vec2::new(
            x_m as f32 - self.world.center().x,
            -(y_m as f32 - self.world.center().y),
        );
        self.screen.center() + offset * self.points_per_m
    }

    /// Lines every 5 or 10 m (whichever leaves at least 40 points between them), so that
    /// distances read at a glance, and the spacing written in a corner.
    fn grid(&self, painter: &egui::Painter, rect: Rect, colour: Color32) {
        let step_m = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0]
            .into_iter()
            .find(|step| step * self.points_per_m >= 40.0)
            .unwrap_or(1000.0);
        let stroke = Stroke::new(1.0, colour.gamma_multiply(0.25));
        // Half the screen in metres, and a step more: the map's centre is not the screen's.
        let half = rect.size() / self.points_per_m / 2.0 + Vec2::splat(step_m);
        let centre = self.world.center();
        let mut x = ((centre.x - half.x) / step_m).floor() * step_m;
        while x <= centre.x + half.x {
            let top = self.to_screen(f64::from(x), f64::from(centre.y + half.y));
            painter.vline(top.x, rect.y_range(), stroke);
            x += step_m;
        }
        let mut y = ((centre.y - half.y) / step_m).floor() * step_m;
        while y <= centre.y + half.y {
            let left = self.to_screen(f64::from(centre.x - half.x), f64::from(y));
            painter.hline(rect.x_range(), left.y, stroke);
            y += step_m;
        }
        painter.text(
            rect.left_bottom() + Vec2::new(8.0, -8.0),
            egui::Align2::LEFT_BOTTOM,
            format!("grid {step_m} m"),
            egui::FontId::proportional(12.0),
            colour,
        );
    }
}

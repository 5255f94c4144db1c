//! Drawing helpers more than one view uses: a module state's colour (the Run view's monitor,
//! the System view's blocks) and a route with its arrowhead (the Mission view's legs, the Run
//! view's followed paths).

use armor_protocol::ModuleState;
use egui::{Color32, Pos2, Stroke};

/// The colour of a module state, in the monitor and on the diagram.
pub fn state_colour(state: ModuleState) -> Color32 {
    match state {
        ModuleState::Running => Color32::from_rgb(40, 160, 70),
        ModuleState::Starting | ModuleState::Restarting => Color32::from_rgb(80, 140, 220),
        ModuleState::Stopped | ModuleState::Exited | ModuleState::Ended => {
            Color32::from_rgb(140, 140, 140)
        }
        ModuleState::Crashed => Color32::from_rgb(230, 140, 0),
        ModuleState::Failed => Color32::from_rgb(210, 40, 40),
    }
}

/// A route as a leg is drawn: a line (`dashed` or not) with an arrowhead halfway along its
/// longest piece, when that piece is long enough to show one. Returns where the arrowhead is,
/// for a label. The Run view draws the paths the follower follows with it.
pub fn draw_route(
    painter: &egui::Painter,
    route: &[Pos2],
    stroke: Stroke,
    dashed: bool,
) -> Option<Pos2> {
    if dashed {
        painter.extend(egui::Shape::dashed_line(route, stroke, 10.0, 6.0));
    } else {
        painter.add(egui::Shape::line(route.to_vec(), stroke));
    }
    let piece = route
        .windows(2)
        .max_by(|a, b| a[0].distance(a[1]).total_cmp(&b[0].distance(b[1])))?;
    if piece[0].distance(piece[1]) <= 24.0 {
        return None;
    }
    let direction = (piece[1] - piece[0]).normalized();
    let middle = piece[0] + (piece[1] - piece[0]) * 0.5;
    let side = direction.rot90() * 6.0;
    let tip = middle + direction * 7.0;
    painter.add(egui::Shape::convex_polygon(
        vec![
            tip,
            middle - direction * 5.0 + side,
            middle - direction * 5.0 - side,
        ],
        stroke.color,
        Stroke::NONE,
    ));
    Some(middle)
}

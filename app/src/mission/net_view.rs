//! The compiled Petri net beside the map: a layered layout (left to right, in the order the
//! net can fire) and its drawing, with the elements of the selected leg highlighted and a click
//! on an element reported so that the map can select its leg.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use armor_model::net::{Marking, MissionNet};
use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui, Vec2, pos2, vec2};

/// Distance between layers and between rows, in points.
const LAYER_STEP: f32 = 84.0;
const ROW_STEP: f32 = 56.0;
const MARGIN: f32 = 28.0;
const PLACE_RADIUS: f32 = 11.0;
const TRANSITION_SIZE: Vec2 = vec2(7.0, 24.0);

const INK: Color32 = Color32::from_rgb(40, 40, 40);
const PAPER: Color32 = Color32::from_rgb(248, 246, 238);
const HIGHLIGHT: Color32 = Color32::from_rgb(230, 150, 20);
const FINAL: Color32 = Color32::from_rgb(60, 150, 80);
const OPERATOR: Color32 = Color32::from_rgb(40, 110, 200);

/// Where each place and transition goes, in points from the top left of the drawing.
#[derive(Clone, Debug, Default)]
pub struct Layout {
    pub nodes: BTreeMap<String, Node>,
    pub size: Vec2,
}

#[derive(Clone, Debug)]
pub struct Node {
    pub pos: Pos2,
    pub is_place: bool,
}

/// Lays `net` out in layers by breadth-first distance from the initially marked places (or,
/// without any, from the places no transition feeds), each node in the row of the first
/// node that reached it where it is free, so that a chain of legs reads as one line and a
/// contingency branches off below it. What the search never reaches goes in a last layer.
pub fn layout(net: &MissionNet) -> Layout {
    let mut successors: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    let mut fed: BTreeSet<&str> = BTreeSet::new();
    for transition in &net.transitions {
        for arc in &transition.inputs {
            successors
                .entry(arc.place.as_str())
                .or_default()
                .push(&transition.name);
        }
        for arc in &transition.outputs {
            successors
                .entry(transition.name.as_str())
                .or_default()
                .push(&arc.place);
            fed.insert(&arc.place);
        }
    }
    let mut roots: Vec<&str> = net
        .places
        .iter()
        .filter(|place| place.tokens > 0)
        .map(|place| place.name.as_str())
        .collect();
    if roots.is_empty() {
        roots = net
            .places
            .iter()
            .filter(|place| !fed.contains(place.name.as_str()))
            .map(|place| place.name.as_str())
            .collect();
    }
    let mut layer_of: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    let mut taken: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut queue = VecDeque::new();
    for (row, root) in roots.iter().enumerate() {
        layer_of.insert(root, (0, row));
        taken.insert((0, row));
        queue.push_back(*root);
    }
    while let Some(node) = queue.pop_front() {
        let (layer, row) = layer_of[node];
        for next in successors.get(node).into_iter().flatten() {
            if layer_of.contains_key(next) {
                continue;
            }
            let mut free = row;
            while taken.contains(&(layer + 1, free)) {
                free += 1;
            }
            taken.insert((layer + 1, free));
            layer_of.insert(next, (layer + 1, free));
            queue.push_back(next);
        }
    }
    let last = layer_of
        .values()
        .map(|(layer, _)| layer + 1)
        .max()
        .unwrap_or(0);
    let mut row = 0;
    let mut nodes = BTreeMap::new();
    let all = net
        .places
        .iter()
        .map(|p| (p.name.as_str(), true))
        .chain(net.transitions.iter().map(|t| (t.name.as_str(), false)));
    for (name, is_place) in all {
        let (layer, row) = layer_of.get(name).copied().unwrap_or_else(|| {
            row += 1;
            (last, row - 1)
        });
        let pos = pos2(
            MARGIN + layer as f32 * LAYER_STEP,
            MARGIN + row as f32 * ROW_STEP,
        );
        nodes.insert(name.to_owned(), Node { pos, is_place });
    }
    let size = nodes.values().fold(Vec2::ZERO, |size, node| {
        size.max(node.pos.to_vec2() + Vec2::splat(MARGIN + 40.0))
    });
    Layout { nodes, size }
}

/// What the net drawing shows besides the net.
pub struct NetStyle<'a> {
    /// Elements drawn highlighted (the selected leg's).
    pub highlighted: &'a BTreeSet<String>,
    /// A marking to draw as tokens; without one, the initial marking.
    pub marking: Option<&'a Marking>,
    /// Scroll so that the highlighted elements are in view (once, after the selection changed).
    pub scroll_to_highlight: bool,
}

/// Draws the net; returns the element clicked, if any.
pub fn net_ui(ui: &mut Ui, net: &MissionNet, layout: &Layout, style: &NetStyle) -> Option<String> {
    let mut clicked = None;
    egui::ScrollArea::both()
        .id_salt("net-scroll")
        .auto_shrink([false, false])
        .show_viewport(ui, |ui, viewport| {
            let (rect, _) =
                ui.allocate_exact_size(layout.size.max(ui.available_size()), Sense::hover());
            // Paper, as the map: the net's ink reads the same in a dark or a light theme.
            ui.painter().rect_filled(ui.clip_rect(), 0.0, PAPER);
            let origin = rect.min.to_vec2();
            let visible = viewport.translate(origin).expand(LAYER_STEP);
            let painter = ui.painter();
            let at = |name: &str| layout.nodes.get(name).map(|node| node.pos + origin);
            for transition in &net.transitions {
                let Some(t) = at(&transition.name) else {
                    continue;
                };
                let lit = style.highlighted.contains(&transition.name);
                let colour = if lit { HIGHLIGHT } else { Color32::GRAY };
                for arc in &transition.inputs {
                    if let Some(p) = at(&arc.place) {
                        arrow(painter, p, t, colour, visible);
                    }
                }
                for arc in &transition.outputs {
                    if let Some(p) = at(&arc.place) {
                        arrow(painter, t, p, colour, visible);
                    }
                }
            }
            let marking = style
                .marking
                .cloned()
                .unwrap_or_else(|| net.initial_marking());
            let font = egui::FontId::proportional(10.0);
            for place in &net.places {
                let Some(p) = at(&place.name).filter(|p| visible.contains(*p)) else {
                    continue;
                };
                let lit = style.highlighted.contains(&place.name);
                let outline = match (lit, place.is_final) {
                    (true, _) => HIGHLIGHT,
                    (false, true) => FINAL,
                    (false, false) => INK,
                };
                painter.circle(p, PLACE_RADIUS, Color32::WHITE, Stroke::new(2.0, outline));
                if place.is_final {
                    painter.circle_stroke(p, PLACE_RADIUS - 3.0, Stroke::new(1.0, FINAL));
                }
                match marking.get(&place.name).copied().unwrap_or(0) {
                    0 => {}
                    1 => {
                        painter.circle_filled(p, 4.0, INK);
                    }
                    n => {
                        painter.text(
                            p,
                            egui::Align2::CENTER_CENTER,
                            n.to_string(),
                            font.clone(),
                            INK,
                        );
                    }
                }
                label(
                    painter,
                    p + vec2(0.0, PLACE_RADIUS + 2.0),
                    &place.name,
                    &font,
                );
                let response = ui.interact(
                    Rect::from_center_size(p, Vec2::splat(PLACE_RADIUS * 2.0)),
                    ui.id().with(("place", &place.name)),
                    Sense::click(),
                );
                // Named for screen readers (and the UI tests), as the text is painted.
                response.widget_info(|| {
                    egui::WidgetInfo::labeled(egui::WidgetType::Button, true, &place.name)
                });
                if response.on_hover_text(place_tooltip(place)).clicked() {
                    clicked = Some(place.name.clone());
                }
            }
            for transition in &net.transitions {
                let Some(t) = at(&transition.name).filter(|t| visible.contains(*t)) else {
                    continue;
                };
                let lit = style.highlighted.contains(&transition.name);
                let fill = match (lit, transition.condition.operator) {
                    (true, _) => HIGHLIGHT,
                    (false, true) => OPERATOR,
                    (false, false) => INK,
                };
                let bar = Rect::from_center_size(t, TRANSITION_SIZE);
                painter.rect_filled(bar, 1.0, fill);
                label(
                    painter,
                    t + vec2(0.0, TRANSITION_SIZE.y / 2.0 + 2.0),
                    &transition.name,
                    &font,
                );
                let response = ui.interact(
                    bar.expand(4.0),
                    ui.id().with(("transition", &transition.name)),
                    Sense::click(),
                );
                response.widget_info(|| {
                    egui::WidgetInfo::labeled(egui::WidgetType::Button, true, &transition.name)
                });
                if response
                    .on_hover_text(transition_tooltip(transition))
                    .clicked()
                {
                    clicked = Some(transition.name.clone());
                }
            }
            if style.scroll_to_highlight {
                let lit = style
                    .highlighted
                    .iter()
                    .filter_map(|name| at(name))
                    .fold(Rect::NOTHING, |rect, p| {
                        rect.union(Rect::from_center_size(p, Vec2::splat(40.0)))
                    });
                if lit.is_positive() {
                    ui.scroll_to_rect(lit, Some(egui::Align::Center));
                }
            }
        });
    clicked
}

fn label(painter: &egui::Painter, top: Pos2, text: &str, font: &egui::FontId) {
    painter.text(top, egui::Align2::CENTER_TOP, text, font.clone(), INK);
}

/// An arc from `a` to `b` with its head at the target's edge; arcs going back (to the left)
/// bend below the line so they do not run over the nodes between.
fn arrow(painter: &egui::Painter, a: Pos2, b: Pos2, colour: Color32, visible: Rect) {
    if !visible.intersects(Rect::from_two_pos(a, b)) {
        return;
    }
    let stroke = Stroke::new(1.2, colour);
    let head_at;
    let direction;
    if b.x >= a.x {
        direction = (b - a).normalized();
        head_at = b - direction * (PLACE_RADIUS + 1.0);
        painter.line_segment([a, head_at], stroke);
    } else {
        let dip = vec2(0.0, ROW_STEP * 0.45);
        let points = [a, a + dip, b + dip, b];
        for pair in points.windows(2) {
            painter.line_segment([pair[0], pair[1]], stroke);
        }
        direction = vec2(0.0, -1.0);
        head_at = b + vec2(0.0, PLACE_RADIUS + 1.0);
    }
    let side = direction.rot90() * 3.5;
    let back = head_at - direction * 7.0;
    painter.add(egui::Shape::convex_polygon(
        vec![head_at, back + side, back - side],
        colour,
        Stroke::NONE,
    ));
}

fn place_tooltip(place: &armor_model::net::Place) -> String {
    let mut text = format!("place {}", place.name);
    if !place.modules.is_empty() {
        text += &format!("\nruns: {}", place.modules.join(", "));
    }
    for param in &place.params {
        text += &format!("\n{}.{} = {}", param.module, param.name, param.value);
    }
    if place.is_final {
        text += "\nfinal: the mission ends here";
    }
    text
}

pub fn transition_tooltip(transition: &armor_model::net::Transition) -> String {
    let mut text = format!("transition {}", transition.name);
    let condition = &transition.condition;
    if let Some(event) = &condition.event {
        text += &format!("\nwaits for the event {event}");
    }
    if let Some(delay) = condition.delay_secs {
        text += &format!("\nfires {delay} s after it is enabled");
    }
    if let Some(at) = condition.at_unix_secs {
        text += &format!("\nnot before {}", armor_model::net::format_rfc3339(at));
    }
    if condition.operator {
        text += "\nfired by the operator";
    }
    if condition.is_empty() {
        text += "\nfires as soon as it is enabled";
    }
    text
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_reads_left_to_right_on_one_row_and_a_branch_goes_below() {
        let net = MissionNet::parse(
            r#"<mission name="m" system="s.xml">
                 <place name="a" tokens="1"/><place name="b"/><place name="c" final="true"/>
                 <place name="held"/><place name="orphan"/>
                 <transition name="t1"><input place="a"/><output place="b"/></transition>
                 <transition name="t2"><input place="b"/><output place="c"/></transition>
                 <transition name="stuck"><input place="b"/><output place="held"/></transition>
                 <transition name="retry"><input place="held"/><output place="b"/></transition>
               </mission>"#,
        )
        .unwrap();
        let layout = layout(&net);
        let pos = |name: &str| layout.nodes[name].pos;
        let xs: Vec<f32> = ["a", "t1", "b", "t2", "c"]
            .iter()
            .map(|n| pos(n).x)
            .collect();
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "{xs:?}");
        assert!(
            ["t1", "b", "t2", "c"]
                .iter()
                .all(|n| pos(n).y == pos("a").y)
        );
        assert_eq!(pos("stuck").x, pos("t2").x);
        assert!(pos("stuck").y > pos("t2").y);
        // Nothing reaches it: it still has a place, in the last layer, apart from the others.
        assert!(pos("orphan").x > pos("c").x);
        let distinct: BTreeSet<(i32, i32)> = layout
            .nodes
            .values()
            .map(|n| (n.pos.x as i32, n.pos.y as i32))
            .collect();
        assert_eq!(distinct.len(), layout.nodes.len(), "two nodes at one spot");
        assert!(
            layout
                .nodes
                .values()
                .all(|n| n.pos.x < layout.size.x && n.pos.y < layout.size.y)
        );
    }
}

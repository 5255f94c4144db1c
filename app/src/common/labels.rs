//! Map labels that never overlap: every label is placed after the shapes are drawn, most
//! important first, at the first of several positions round its anchor (or anchors: a phase
//! line's two ends) where it covers no label placed before and no symbol; a label that finds no
//! room close by goes a step further out with a leader line to its anchor, then is shortened,
//! and is dropped last (the inspector still names everything). Each label is drawn once.
//!
//! Placed rectangles are kept in a grid of cells, so that a plan of 500 waypoints (over a
//! thousand labels) is placed in a few milliseconds (`armor-bench label_place_ms_500_waypoints`).

use std::collections::HashMap;

use egui::{Align2, Color32, Pos2, Rect, Vec2, pos2, vec2};

/// How much a label matters: the lower, the sooner it is placed (and the less it is dropped).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Importance {
    /// A robot's tag on a watched map (its localisation, the simulator's truth): placed
    /// first, beside the robot it names.
    Robot,
    /// A waypoint's name.
    Waypoint,
    /// A unit's name, a time constraint (NET, NLT, wait).
    Constraint,
    /// An area's or a line's name.
    Graphic,
    /// A leg's name, the modules of an arrival action.
    Detail,
}

/// A label to place: `text` near one of `anchors`, at `gap` points from it, first on the
/// `preferred` side.
#[derive(Clone, Debug)]
pub struct Label {
    pub anchors: Vec<Pos2>,
    pub gap: f32,
    pub preferred: Align2,
    pub text: String,
    pub colour: Color32,
    pub importance: Importance,
}

/// A label's place: its box (text and margin), the text drawn (perhaps shortened), and the
/// leader line from its anchor when it stands off.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed {
    pub rect: Rect,
    pub text: String,
    pub colour: Color32,
    pub leader: Option<[Pos2; 2]>,
    pub importance: Importance,
}

/// The sides tried round an anchor, in order after the preferred one.
const SIDES: [Align2; 8] = [
    Align2::CENTER_BOTTOM,
    Align2::LEFT_CENTER,
    Align2::CENTER_TOP,
    Align2::RIGHT_CENTER,
    Align2::LEFT_BOTTOM,
    Align2::RIGHT_BOTTOM,
    Align2::LEFT_TOP,
    Align2::RIGHT_TOP,
];
/// How much further out the rings of positions beyond the first are (with a leader line).
const STAND_OFF: [f32; 5] = [0.0, 16.0, 34.0, 52.0, 72.0];
/// Margin round a label's text.
const MARGIN: f32 = 2.0;
const CELL: f32 = 64.0;

/// The direction from the anchor towards a label on `side` (a label `CENTER_BOTTOM`-aligned
/// sits above its anchor).
fn outward(side: Align2) -> Vec2 {
    let x = match side.x() {
        egui::Align::Min => 1.0,
        egui::Align::Center => 0.0,
        egui::Align::Max => -1.0,
    };
    let y = match side.y() {
        egui::Align::Min => 1.0,
        egui::Align::Center => 0.0,
        egui::Align::Max => -1.0,
    };
    vec2(x, y)
}

/// Rectangles placed so far and the leader lines drawn, bucketed by grid cell.
#[derive(Default)]
struct Taken {
    cells: HashMap<(i32, i32), Vec<usize>>,
    rects: Vec<Rect>,
    line_cells: HashMap<(i32, i32), Vec<usize>>,
    lines: Vec<[Pos2; 2]>,
}

impl Taken {
    fn cells_of(rect: Rect) -> impl Iterator<Item = (i32, i32)> {
        let (x0, x1) = (
            (rect.min.x / CELL).floor() as i32,
            (rect.max.x / CELL).floor() as i32,
        );
        let (y0, y1) = (
            (rect.min.y / CELL).floor() as i32,
            (rect.max.y / CELL).floor() as i32,
        );
        (x0..=x1).flat_map(move |x| (y0..=y1).map(move |y| (x, y)))
    }

    /// The box covers no rectangle taken and no leader line drawn.
    fn is_free(&self, rect: Rect) -> bool {
        Self::cells_of(rect).all(|cell| {
            self.cells.get(&cell).is_none_or(|indices| {
                indices
                    .iter()
                    .all(|&index| !self.rects[index].intersects(rect))
            }) && self.line_cells.get(&cell).is_none_or(|indices| {
                indices
                    .iter()
                    .all(|&index| !crosses(self.lines[index], rect))
            })
        })
    }

    /// The line runs through no rectangle taken (it starts where it leaves its own symbol:
    /// [`Self::leader_start`]).
    fn line_is_free(&self, line: [Pos2; 2]) -> bool {
        Self::cells_of(Rect::from_two_pos(line[0], line[1])).all(|cell| {
            self.cells.get(&cell).is_none_or(|indices| {
                indices
                    .iter()
                    .all(|&index| !crosses(line, self.rects[index]))
            })
        })
    }

    fn take(&mut self, rect: Rect) {
        let index = self.rects.len();
        self.rects.push(rect);
        for cell in Self::cells_of(rect) {
            self.cells.entry(cell).or_default().push(index);
        }
    }

    fn take_line(&mut self, line: [Pos2; 2]) {
        let index = self.lines.len();
        self.lines.push(line);
        for cell in Self::cells_of(Rect::from_two_pos(line[0], line[1])) {
            self.line_cells.entry(cell).or_default().push(index);
        }
    }

    /// Where a leader line from `anchor` towards `to` leaves the rectangles taken that hold
    /// the anchor (its own symbol, or the robot it names, or a robot standing on it): the
    /// line starts there, so that it never runs over them.
    fn leader_start(&self, anchor: Pos2, to: Pos2) -> Pos2 {
        let mut t_out: f32 = 0.0;
        for cell in Self::cells_of(Rect::from_pos(anchor)) {
            for &index in self.cells.get(&cell).into_iter().flatten() {
                let rect = self.rects[index];
                if rect.contains(anchor) {
                    t_out = t_out.max(exit_along(anchor, to, rect));
                }
            }
        }
        anchor + (to - anchor) * t_out
    }
}

/// How far along from `a` to `b` (0 to 1) the segment leaves `rect`, which holds `a`.
fn exit_along(a: Pos2, b: Pos2, rect: Rect) -> f32 {
    let d = b - a;
    let axis = |from: f32, delta: f32, min: f32, max: f32| {
        if delta > 0.0 {
            (max - from) / delta
        } else if delta < 0.0 {
            (min - from) / delta
        } else {
            f32::INFINITY
        }
    };
    axis(a.x, d.x, rect.min.x, rect.max.x)
        .min(axis(a.y, d.y, rect.min.y, rect.max.y))
        .clamp(0.0, 1.0)
}

/// The segment runs through the inside of `rect` (touching its edge is not crossing it):
/// Liang–Barsky clipping against the rectangle shrunk by a hair.
pub fn crosses(line: [Pos2; 2], rect: Rect) -> bool {
    let rect = rect.shrink(0.5);
    if !rect.is_positive() {
        return false;
    }
    let [a, b] = line;
    let d = b - a;
    let (mut t0, mut t1) = (0.0_f32, 1.0_f32);
    for (p, q) in [
        (-d.x, a.x - rect.min.x),
        (d.x, rect.max.x - a.x),
        (-d.y, a.y - rect.min.y),
        (d.y, rect.max.y - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

/// Places `labels` (their text measured by `size_of`) round `obstacles` (symbols, robots)
/// and off `lines` (leader lines drawn already), inside `bounds`. No two placed boxes overlap,
/// nor a box and an obstacle; a leader line starts where it leaves its anchor's own symbol
/// (or the robot on it) and crosses no other box, and no box is placed over one.
pub fn place(
    mut labels: Vec<Label>,
    obstacles: &[Rect],
    lines: &[[Pos2; 2]],
    bounds: Rect,
    size_of: &mut dyn FnMut(&str) -> Vec2,
) -> Vec<Placed> {
    // Most important first; among equals, in the order given (stable sort).
    labels.sort_by_key(|label| label.importance);
    let mut taken = Taken::default();
    for &obstacle in obstacles {
        taken.take(obstacle);
    }
    for &line in lines {
        taken.take_line(line);
    }
    let mut seen: HashMap<(String, Color32), Vec<Pos2>> = HashMap::new();
    let mut placed = Vec::with_capacity(labels.len());
    for label in labels {
        // The same text in the same colour at the same anchor is one label.
        let twins = seen.entry((label.text.clone(), label.colour)).or_default();
        if label
            .anchors
            .iter()
            .all(|anchor| twins.iter().any(|seen| seen.distance(*anchor) < 1.0))
        {
            continue;
        }
        twins.extend(label.anchors.iter().copied());
        // Only anchors on the map: the label of a point off it would stand at the map's edge,
        // where it names nothing seen (a map made small, by the net enlarged, would pile
        // them up there).
        let mut anchors: Vec<Pos2> = label
            .anchors
            .iter()
            .copied()
            .filter(|anchor| bounds.contains(*anchor))
            .collect();
        if anchors.is_empty() {
            continue;
        }
        // An anchor buried under an obstacle larger than the label's own symbol (a robot
        // standing on the waypoint) is walled in by the labels round that obstacle, and a
        // leader line from it would cross them or the robot: the label is anchored to the
        // obstacle's rim instead, and named beside it.
        let mut gap = label.gap;
        if let Some(rim) = obstacles.iter().find(|obstacle| {
            anchors
                .iter()
                .any(|anchor| obstacle.shrink(1.0).contains(*anchor))
                && obstacle.width().min(obstacle.height()) / 2.0 > label.gap
        }) {
            anchors = rim_points(*rim);
            gap = RIM_GAP;
        }
        let shortened = shorten(&label.text);
        let texts = std::iter::once(label.text.clone()).chain(shortened);
        'texts: for text in texts {
            let size = size_of(&text) + Vec2::splat(2.0 * MARGIN);
            for ring in STAND_OFF {
                for &anchor in &anchors {
                    let sides = std::iter::once(label.preferred)
                        .chain(SIDES.into_iter().filter(|side| *side != label.preferred));
                    for side in sides {
                        let at = anchor + outward(side) * (gap + ring);
                        let rect = side.anchor_size(at, size);
                        if !bounds.contains_rect(rect) || !taken.is_free(rect) {
                            continue;
                        }
                        let leader = if ring > 0.0 {
                            let end = nearest_point(rect, anchor);
                            let line = [taken.leader_start(anchor, end), end];
                            if !taken.line_is_free(line) {
                                continue;
                            }
                            Some(line)
                        } else {
                            None
                        };
                        taken.take(rect);
                        if let Some(line) = leader {
                            taken.take_line(line);
                        }
                        placed.push(Placed {
                            rect,
                            text,
                            colour: label.colour,
                            leader,
                            importance: label.importance,
                        });
                        break 'texts;
                    }
                }
            }
        }
    }
    placed
}

/// A shorter form of a label that found no room: its first word, else its first characters.
fn shorten(text: &str) -> Option<String> {
    let first = text.split_whitespace().next().unwrap_or(text);
    if first.len() < text.len() && first.chars().count() >= 2 {
        return Some(first.to_owned());
    }
    let chars: Vec<char> = text.chars().collect();
    (chars.len() > 6).then(|| chars[..5].iter().collect::<String>() + "…")
}

/// The gap between an obstacle's rim and a label anchored to it.
const RIM_GAP: f32 = 2.0;

/// The middles of a rectangle's sides, then its corners.
fn rim_points(rect: Rect) -> Vec<Pos2> {
    let centre = rect.center();
    vec![
        pos2(rect.max.x, centre.y),
        pos2(rect.min.x, centre.y),
        pos2(centre.x, rect.min.y),
        pos2(centre.x, rect.max.y),
        rect.right_top(),
        rect.left_top(),
        rect.right_bottom(),
        rect.left_bottom(),
    ]
}

fn nearest_point(rect: Rect, p: Pos2) -> Pos2 {
    pos2_clamped(p, rect)
}

fn pos2_clamped(p: Pos2, rect: Rect) -> Pos2 {
    Pos2::new(
        p.x.clamp(rect.min.x, rect.max.x),
        p.y.clamp(rect.min.y, rect.max.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measure(text: &str) -> Vec2 {
        vec2(6.5 * text.chars().count() as f32, 13.0)
    }

    fn label(at: Pos2, text: &str, importance: Importance) -> Label {
        Label {
            anchors: vec![at],
            gap: 8.0,
            preferred: Align2::CENTER_BOTTOM,
            text: text.to_owned(),
            colour: Color32::BLACK,
            importance,
        }
    }

    fn overlaps(placed: &[Placed]) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        for i in 0..placed.len() {
            for j in i + 1..placed.len() {
                if placed[i].rect.intersects(placed[j].rect) {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    /// Twenty labels on almost the same spot from `x`, as at a busy waypoint `gate` at
    /// (400, 300).
    fn crowd(x: f32) -> Vec<Label> {
        let mut labels = vec![label(pos2(400.0, 300.0), "gate", Importance::Waypoint)];
        for i in 0..20 {
            labels.push(label(
                pos2(x + i as f32, 300.0),
                &format!("NLT 08:0{i}:30Z"),
                Importance::Constraint,
            ));
        }
        labels
    }

    #[test]
    fn crowded_labels_never_overlap_and_the_important_ones_stay() {
        let bounds = Rect::from_min_size(Pos2::ZERO, vec2(800.0, 600.0));
        let placed = place(crowd(400.0), &[], &[], bounds, &mut measure);
        assert!(overlaps(&placed).is_empty(), "{placed:#?}");
        assert_eq!(
            placed[0].text, "gate",
            "the waypoint's name is placed first"
        );
        // A leader line crosses no label: round one point, the labels placed are those of
        // the ring next to it and those whose line finds a way between them; the others are
        // left to the inspector.
        assert!(
            placed.len() >= 5,
            "the ring round the point is filled: {}",
            placed.len()
        );
        assert!(placed.iter().any(|p| p.leader.is_some()), "some stand off");
    }

    #[test]
    fn a_label_keeps_off_symbols_and_inside_the_map() {
        let bounds = Rect::from_min_size(Pos2::ZERO, vec2(300.0, 200.0));
        let symbol = Rect::from_center_size(pos2(150.0, 100.0), Vec2::splat(44.0));
        let placed = place(
            vec![label(pos2(150.0, 100.0), "enemy_post", Importance::Graphic)],
            &[symbol],
            &[],
            bounds,
            &mut measure,
        );
        assert_eq!(placed.len(), 1);
        assert!(!placed[0].rect.intersects(symbol));
        assert!(bounds.contains_rect(placed[0].rect));
    }

    #[test]
    fn the_same_label_is_drawn_once_and_a_line_label_at_one_of_its_ends() {
        let bounds = Rect::from_min_size(Pos2::ZERO, vec2(800.0, 600.0));
        let line = Label {
            anchors: vec![pos2(100.0, 100.0), pos2(700.0, 100.0)],
            ..label(pos2(0.0, 0.0), "PL AMBER", Importance::Graphic)
        };
        let placed = place(vec![line.clone(), line], &[], &[], bounds, &mut measure);
        assert_eq!(placed.len(), 1, "{placed:#?}");
    }

    /// A robot stands on a busy waypoint: the labels that stand off draw their leader lines
    /// from the robot's edge, and no leader line runs through another label or the robot.
    #[test]
    fn leader_lines_cross_no_label_and_start_clear_of_the_robot() {
        let bounds = Rect::from_min_size(Pos2::ZERO, vec2(800.0, 600.0));
        let robot = Rect::from_center_size(pos2(400.0, 300.0), Vec2::splat(36.0));
        let drawn_before = [pos2(300.0, 250.0), pos2(330.0, 250.0)];
        let placed = place(
            crowd(395.0),
            &[robot],
            &[drawn_before],
            bounds,
            &mut measure,
        );
        let leaders: Vec<_> = placed.iter().filter_map(|p| p.leader).collect();
        assert!(leaders.len() >= 4, "{placed:#?}");
        for (i, label) in placed.iter().enumerate() {
            assert!(!label.rect.intersects(robot), "{label:?}");
            assert!(!crosses(drawn_before, label.rect), "{label:?}");
            if let Some(leader) = label.leader {
                assert!(!crosses(leader, robot), "{label:?} crosses the robot");
                for (j, other) in placed.iter().enumerate() {
                    assert!(
                        i == j || !crosses(leader, other.rect),
                        "the leader of {label:?} crosses {other:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_segment_crosses_a_box_only_through_its_inside() {
        let rect = Rect::from_min_max(pos2(10.0, 10.0), pos2(20.0, 20.0));
        assert!(crosses([pos2(0.0, 15.0), pos2(30.0, 15.0)], rect));
        assert!(crosses([pos2(15.0, 15.0), pos2(15.0, 16.0)], rect));
        assert!(!crosses([pos2(0.0, 0.0), pos2(30.0, 5.0)], rect));
        assert!(
            !crosses([pos2(20.0, 0.0), pos2(20.0, 30.0)], rect),
            "along its edge"
        );
        assert!(!crosses([pos2(0.0, 0.0), pos2(9.0, 9.0)], rect));
    }

    #[test]
    fn a_label_with_no_room_is_shortened_before_it_is_dropped() {
        assert_eq!(shorten("NO-GO contaminated").as_deref(), Some("NO-GO"));
        assert_eq!(shorten("northern_limit").as_deref(), Some("north…"));
        assert_eq!(shorten("gate"), None);
    }

    fn pos2(x: f32, y: f32) -> Pos2 {
        Pos2::new(x, y)
    }
}

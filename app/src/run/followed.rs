//! The paths the follower follows, on the live map: the one followed now, drawn as a leg is
//! (`common::draw::draw_route`) in a colour of its own, and those it replaced by replanning,
//! faint and dashed, with a marker where each replan happened ("replan 1/3").
//!
//! Which paths are replans is told by the plan: the follower sets out on the path the plan
//! planned for the leg, so a path equal to it is the leg's own (the follower started afresh,
//! which also restarts its count), and every other path to the same goal is a replan; when the
//! leg's own was published before the studio subscribed, the plan's stands for it. Without a
//! plan (a system's run), the first path seen is taken for the leg's own.

use std::sync::Arc;

use armor_model::world::Point;
use egui::{Color32, Pos2, Stroke};

use super::live::{Followed, SAME_POINT_M};

/// The path being followed.
const FOLLOWED: Color32 = Color32::from_rgb(0, 150, 130);
/// A path replaced by a replan.
const REPLACED: Color32 = Color32::from_rgb(110, 110, 110);

/// One path on the live map.
#[derive(Clone, Debug, PartialEq)]
pub struct DrawnPath {
    /// In the world frame (the follower's odometry frame, which the simulated robot shares).
    pub points: Arc<[Point]>,
    /// Replaced by a later replan: drawn faint and dashed.
    pub replaced: bool,
    /// The replan that made it, from 1 in each leg; `None` for the leg's own path.
    pub replan: Option<usize>,
}

/// The follower's paths of the current leg, as the live map draws them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FollowedLeg {
    /// Oldest first; the last is the one followed now.
    pub paths: Vec<DrawnPath>,
    /// The follower's `max_replans`, when the run's system says it.
    pub max_replans: Option<u32>,
}

impl FollowedLeg {
    /// Tells the leg's own path from the replans among `followed`, given the path the plan
    /// planned for the current leg (`None` without a plan).
    pub fn of(followed: &Followed, planned: Option<&[Point]>, max_replans: Option<u32>) -> Self {
        // The paths to another goal than the leg's are the next leg's, published before the
        // run's marking said the leg changed: the plan cannot tell their replans then.
        let goal = |path: &[Point]| path.last().copied();
        let planned = planned.filter(|planned| {
            match (goal(planned), followed.paths.last().and_then(|p| goal(p))) {
                (Some(a), Some(b)) => (a.x - b.x).hypot(a.y - b.y) < SAME_POINT_M,
                _ => true,
            }
        });
        let own = |path: &[Point]| planned.is_some_and(|planned| same_route(path, planned));
        // The leg's own path, the last time the follower set out on it; without a plan, the
        // first path seen.
        let start = match planned {
            Some(_) => followed.paths.iter().rposition(|path| own(path)),
            None => (!followed.paths.is_empty()).then_some(0),
        };
        let from = start.unwrap_or(0);
        let count = followed.paths.len() - from;
        // The leg's own path, published before the studio listened, is the plan's: drawn as
        // replaced all the same, since the follower set out on it.
        let missed = match (start, planned) {
            (None, Some(planned)) if count > 0 => Some(DrawnPath {
                points: planned.into(),
                replaced: true,
                replan: None,
            }),
            _ => None,
        };
        let paths = missed
            .into_iter()
            .chain(
                followed.paths[from..]
                    .iter()
                    .enumerate()
                    .map(|(index, points)| DrawnPath {
                        points: Arc::clone(points),
                        replaced: index + 1 < count,
                        // Paths after the leg's own are replans 1, 2, …; when the leg's own was not
                        // seen (published before the studio subscribed), the first seen is one too.
                        replan: match start {
                            Some(_) if index == 0 => None,
                            Some(_) => Some(index),
                            None => Some(index + 1),
                        },
                    }),
            )
            .collect();
        FollowedLeg { paths, max_replans }
    }

    /// Replans so far in this leg.
    pub fn replans(&self) -> usize {
        self.paths.last().and_then(|path| path.replan).unwrap_or(0)
    }

    /// `replan 2/3` (or `replan 2` when the bound is not known).
    pub fn replan_text(&self, replan: usize) -> String {
        match self.max_replans {
            Some(max) => format!("replan {replan}/{max}"),
            None => format!("replan {replan}"),
        }
    }

    /// The leg's paths in words, for the map's corner and the mission panel: `None` when no
    /// path is followed.
    pub fn summary(&self) -> Option<String> {
        self.paths.last()?;
        Some(match (self.replans(), self.max_replans) {
            (0, _) => "following the planned path (no replan)".to_owned(),
            (replans, Some(max)) => format!("following replan {replans} of {max} this leg"),
            (replans, None) => format!("following replan {replans} this leg"),
        })
    }

    /// Paints the replaced paths, then the followed one over them, then the replans' markers.
    pub fn paint(&self, painter: &egui::Painter, project: &dyn Fn(Point) -> Pos2) {
        let screen =
            |path: &DrawnPath| -> Vec<Pos2> { path.points.iter().map(|p| project(*p)).collect() };
        for path in self.paths.iter().filter(|path| path.replaced) {
            crate::common::draw::draw_route(
                painter,
                &screen(path),
                Stroke::new(2.0, REPLACED.gamma_multiply(0.6)),
                true,
            );
        }
        if let Some(path) = self.paths.last() {
            crate::common::draw::draw_route(
                painter,
                &screen(path),
                Stroke::new(3.0, FOLLOWED),
                false,
            );
        }
        for path in &self.paths {
            let (Some(replan), Some(at)) = (path.replan, path.points.first()) else {
                continue;
            };
            let at = project(*at);
            if !at.is_finite() {
                continue;
            }
            painter.circle(at, 5.0, Color32::WHITE, Stroke::new(2.0, FOLLOWED));
            let galley = painter.layout_no_wrap(
                self.replan_text(replan),
                egui::FontId::proportional(12.0),
                Color32::from_rgb(20, 20, 20),
            );
            // Above and to the right of the marker, clear of the robot drawn on it.
            let rect = egui::Rect::from_min_size(
                at + egui::vec2(10.0, -12.0 - galley.size().y),
                galley.size(),
            );
            painter.rect_filled(rect.expand(2.0), 3.0, Color32::from_white_alpha(225));
            painter.galley(rect.min, galley, Color32::BLACK);
        }
    }
}

/// The same route, to [`SAME_POINT_M`], ignoring a last point repeated (the follower ends its
/// path at the goal, added when the planned path stops just short of it).
fn same_route(a: &[Point], b: &[Point]) -> bool {
    let close = |p: &Point, q: &Point| (p.x - q.x).hypot(p.y - q.y) < SAME_POINT_M;
    let trimmed = |path: &[Point]| -> usize {
        let mut len = path.len();
        while len >= 2 && close(&path[len - 1], &path[len - 2]) {
            len -= 1;
        }
        len
    };
    let (a, b) = (&a[..trimmed(a)], &b[..trimmed(b)]);
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| close(p, q))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(points: &[(f64, f64)]) -> Arc<[Point]> {
        points.iter().map(|(x, y)| Point::new(*x, *y)).collect()
    }

    fn check(followed: &[&[(f64, f64)]], planned: Option<&[(f64, f64)]>, expected: &[&str]) {
        let followed = Followed {
            paths: followed.iter().map(|points| path(points)).collect(),
        };
        let planned = planned.map(path);
        let leg = FollowedLeg::of(&followed, planned.as_deref(), Some(3));
        let drawn: Vec<String> = leg
            .paths
            .iter()
            .map(|p| {
                let role = if p.replaced { "replaced" } else { "followed" };
                match p.replan {
                    Some(n) => format!("{role} {}", leg.replan_text(n)),
                    None => format!("{role} own"),
                }
            })
            .collect();
        assert_eq!(drawn, expected);
    }

    const OWN: &[(f64, f64)] = &[(4.0, 4.0), (16.0, 4.0)];
    const REPLAN_1: &[(f64, f64)] = &[(8.0, 4.0), (10.0, 5.5), (16.0, 4.0)];
    const REPLAN_2: &[(f64, f64)] = &[(10.0, 5.5), (12.0, 5.0), (16.0, 4.0)];

    #[test]
    fn replans_are_told_from_the_legs_own_path() {
        check(&[], Some(OWN), &[]);
        check(&[OWN], Some(OWN), &["followed own"]);
        check(
            &[OWN, REPLAN_1, REPLAN_2],
            Some(OWN),
            &["replaced own", "replaced replan 1/3", "followed replan 2/3"],
        );
        // The leg's own path was published before the studio listened: the plan's is drawn.
        check(
            &[REPLAN_1],
            Some(OWN),
            &["replaced own", "followed replan 1/3"],
        );
        // Started afresh (a pause and a resume): the count starts again.
        check(&[OWN, REPLAN_1, OWN], Some(OWN), &["followed own"]);
        // The follower ends the path at the goal, a millimetre from the planned end.
        check(
            &[&[(4.0, 4.0), (16.0, 4.0), (16.001, 4.0)]],
            Some(OWN),
            &["followed own"],
        );
        // The next leg's path, before the marking says so: not counted against this leg.
        check(&[&[(16.0, 4.0), (20.0, 4.0)]], Some(OWN), &["followed own"]);
        // No plan: the first path seen is the leg's own.
        check(
            &[REPLAN_1, REPLAN_2],
            None,
            &["replaced own", "followed replan 1/3"],
        );
    }

    #[test]
    fn the_summary_counts_this_legs_replans() {
        let followed = Followed {
            paths: vec![path(OWN), path(REPLAN_1)],
        };
        let leg = FollowedLeg::of(&followed, Some(&path(OWN)), Some(3));
        assert_eq!(leg.replans(), 1);
        assert_eq!(
            leg.summary().as_deref(),
            Some("following replan 1 of 3 this leg")
        );
        let none = FollowedLeg::of(&Followed::default(), None, None);
        assert_eq!(none.summary(), None);
    }
}

//! Repair when the world contradicts the plan, in a run: when a leg holds for the operator
//! (`LEG_hold`: the navigation was blocked, a no-go area reported left it no way, or its
//! deadline passed before it arrived), the run computes the options
//! (`armor_model::plan::repair`) from where the robot is, shows them in the status, and takes
//! the one chosen (`armor ctl repair N`, or the best when the plan says `<contingency
//! on="blocked" do="repair"/>`, at once or `after_secs` later) as a plan update
//! ([`crate::update`]): checked, migrated and recorded as any update, then the held leg drives
//! again from where the robot is (`docs/plans.md`, "Repair when the world contradicts the
//! plan").

use armor_model::geo::{LatLon, Point, Polygon};
use armor_model::plan::memory::PathMemory;
use armor_model::plan::repair::{self, Candidate, Kind, Situation};
use armor_model::plan::{AreaKind, Graphic, GraphicKind, Origin, Response, Trigger};
use armor_model::planner::Keepout;
use armor_model::world::World;
use armor_protocol::{LegProgress, Repair, RepairKind, RepairOption};

use crate::config_server::ConfigServer;
use crate::controller::Controller;
use std::path::PathBuf;

use crate::update::{Asked, Checked, Refused, Running};

/// A repair proposed, with the plans of its options.
pub struct Proposal {
    /// The held place it answers: once the mission leaves it, the proposal is withdrawn; none
    /// for a later leg cut by an area reported (withdrawn when an update is taken).
    pub place: Option<String>,
    pub candidates: Vec<Candidate>,
    pub shown: Repair,
    /// What an option's update is recorded under, before its number and summary
    /// (`repair option`, or the area reported and `repair option`).
    pub label: String,
    /// When the plan's default is to be applied (run seconds), while the operator has not
    /// chosen: its contingency's `after_secs` after the proposal.
    pub default_at_run_secs: Option<f64>,
    /// The plan's default checked and compiled when it was proposed ([`Proposal::check_default`]),
    /// so that when it comes due only its migration is left: a check takes seconds of real
    /// time on a loaded machine, which at ten times real time made the default tens of run
    /// seconds late. It holds as long as the proposal: any update taken withdraws both.
    default_checked: Option<Checked>,
    /// Whether the default was checked when proposed, taken or not: it is checked once.
    default_check_tried: bool,
}

/// The plan's default come due: checked already (with what was asked, to check again if it
/// cannot be swapped in now), or to check.
pub enum Due {
    Checked { checked: Box<Checked>, asked: Asked },
    Asked(Asked),
}

impl Proposal {
    /// The plan's default, once, when the operator has not chosen by the time it gave.
    fn default_due(&mut self, run_secs: f64) -> Option<Due> {
        if !self.default_at_run_secs.is_some_and(|at| run_secs >= at) {
            return None;
        }
        self.default_at_run_secs = None;
        tracing::warn!(
            "leg `{}`: no option chosen in time, the plan's default (option 1) is applied",
            self.shown.leg
        );
        let asked = asked(Some(self), 1).ok()?;
        Some(match self.default_checked.take() {
            Some(checked) => Due::Checked {
                checked: Box::new(checked),
                asked,
            },
            None => Due::Asked(asked),
        })
    }

    /// Checks and compiles the plan's default now, when it is to come later (`after_secs`):
    /// the slow part of taking it, done while the operator has time to choose. A default that
    /// does not check is left to be checked again when due, and refused then with its reason.
    pub fn check_default(&mut self, running: &mut Running, module_path: &[PathBuf]) {
        if self.default_at_run_secs.is_none() || self.default_check_tried {
            return;
        }
        self.default_check_tried = true;
        let Ok(default) = asked(Some(self), 1) else {
            return;
        };
        match default.check(running, module_path) {
            Ok(checked) => self.default_checked = Some(checked),
            Err(why) => tracing::warn!(
                "leg `{}`: the plan's default (option 1) does not check now: {why}",
                self.shown.leg
            ),
        }
    }
}

/// A leg forecast to miss its deadline is late now: while it drives, once its arrival at the
/// plan's speed from where the robot is (`progress`, the distance left as the run's live line
/// measures it) comes after its `arrive_by`, its `LEG_late` fires, rather than when the
/// deadline passes, so that its contingency (a repair's options, for `hold` and `repair`)
/// comes while there is time to act on it (`docs/plans.md`, "Contingencies").
pub fn forecast_late(
    controller: &mut Controller,
    progress: Option<&LegProgress>,
    server: &ConfigServer,
) {
    let Some(progress) = progress else {
        return;
    };
    let (Some(slack_secs), Some(left_m), Some(deadline)) = (
        progress.slack_secs,
        progress.left_m,
        progress.deadline_run_secs,
    ) else {
        return;
    };
    if slack_secs >= 0.0 {
        return;
    }
    let leg = &progress.leg;
    let (drive, drive_late) = (format!("{leg}_drive"), format!("{leg}_drive_late"));
    // The way it drives (its alternative's suffix), unless it drives late already.
    let Some(suffix) = controller.marking().into_keys().find_map(|place| {
        if place.starts_with(&drive_late) {
            return None;
        }
        place.strip_prefix(&drive).map(str::to_owned)
    }) else {
        return;
    };
    let forecast = format!(
        "forecast: {} m left, at the plan's speed it arrives {:.1} s after its deadline at {:.1} s",
        geo_m(left_m),
        -slack_secs,
        deadline
    );
    controller.fire_forecast(&format!("{leg}_late{suffix}"), &forecast, server);
}

/// Metres to the decimetre, for a sentence.
fn geo_m(metres: f64) -> f64 {
    (metres * 10.0).round() / 10.0
}

/// The held place of the mission, and its leg's index, if a leg holds for the operator.
fn held(controller: &Controller, running: &Running) -> Option<(String, usize)> {
    controller.marking().into_keys().find_map(|place| {
        let Some(&Origin::Leg(index)) = running.compiled.trace.get(&place) else {
            return None;
        };
        let leg = running.plan.legs.get(index)?;
        (place == format!("{}_hold", leg.name)).then_some((place, index))
    })
}

/// The operator's `LEG_retry` of the leg that holds, if one does: what a repair taken fires.
pub fn retry_of(controller: &Controller, running: &Running) -> Option<String> {
    let (_, index) = held(controller, running)?;
    Some(format!("{}_retry", running.plan.legs.get(index)?.name))
}

/// Where the mission stands against the proposal: withdraws it when the held place is left,
/// proposes one when a leg has just started to hold. Returns the option to apply, when the
/// plan names the default (`do="repair"`) and an option other than waiting is left: at once,
/// or once its `after_secs` have passed.
pub fn watch(
    proposal: &mut Option<Proposal>,
    controller: &mut Controller,
    running: &mut Running,
    here: Option<Point>,
    now: (f64, f64),
    world: impl FnOnce(&mut Running) -> Result<Option<World>, Refused>,
) -> Option<Due> {
    let held = held(controller, running);
    let (run_secs, now_unix_secs) = now;
    match (proposal.as_mut(), &held) {
        (Some(proposal), Some((place, _))) if proposal.place.as_ref() == Some(place) => {
            return proposal.default_due(run_secs);
        }
        (Some(proposal), None) if proposal.place.is_none() => {
            return proposal.default_due(run_secs);
        }
        (None, None) => return None,
        _ => {}
    }
    if proposal.take().is_some() {
        controller.set_repair(None);
    }
    let (place, index) = held?;
    let leg = running.plan.legs[index].clone();
    // The leg holds because its deadline passed (`LEG_late…` led there), or because it had no
    // way (`LEG_blocked…`, an area reported).
    let late = controller
        .last_fired_into(&place)
        .is_some_and(|transition| transition.starts_with(&format!("{}_late", leg.name)));
    let trigger = if late {
        Trigger::Late
    } else {
        Trigger::Blocked
    };
    // Without odometry followed, the options are costed from the leg's start.
    let here = here.or_else(|| running.compiled.positions.get(&leg.from).copied())?;
    let world = match world(running) {
        Ok(world) => world,
        Err(why) => {
            tracing::warn!(
                "leg `{}` holds and no repair can be proposed: {why}",
                leg.name
            );
            return None;
        }
    };
    // A leg blocked where the plan's map has a way was stopped by something the map does not
    // have: the options are planned round it, and hold it.
    let blockage = if late {
        None
    } else {
        blockage(running, world.as_ref(), index, here)
    };
    let compiled = &running.compiled;
    let mut keepouts = compiled.keepouts.clone();
    keepouts.extend(blockage.as_ref().map(|(_, keepout)| keepout.clone()));
    // A leg of the plan whose route comes near what stopped the follower is planned again
    // round it (its length is not known), the others keep theirs.
    let lengths: Vec<Option<f64>> = compiled
        .routes
        .iter()
        .map(|route| {
            let clear = blockage.as_ref().is_none_or(|(_, keepout)| {
                route.windows(2).all(|segment| {
                    armor_model::planner::clear_of_keepouts(
                        &compiled.robot,
                        std::slice::from_ref(keepout),
                        segment[0],
                        segment[1],
                    )
                })
            });
            clear.then(|| armor_model::geo::path_length(route))
        })
        .collect();
    let situation = Situation {
        plan: &running.plan,
        positions: &compiled.positions,
        route_lengths_m: &lengths,
        index,
        here,
        now_unix_secs,
        blockage: blockage.as_ref().map(|(area, _)| area),
    };
    let planner = planner(
        &mut running.memory.paths,
        world.as_ref(),
        &compiled.robot,
        &keepouts,
    );
    let (candidates, why) = if late {
        let due = leg
            .arrive_by_unix_secs
            .map_or_else(String::new, |by| format!(" (due by {})", repair::clock(by)));
        // Forecast late (`forecast_late`) before its deadline, or its deadline passed.
        let passed = leg.arrive_by_unix_secs.is_none_or(|by| now_unix_secs >= by);
        let how = if passed {
            "its deadline passed before it arrived"
        } else {
            "at the plan's speed it would arrive after its deadline"
        };
        (
            repair::late_options(situation, planner),
            format!(
                "leg `{}` is late{due}: {how}, it holds in `{place}`",
                leg.name
            ),
        )
    } else {
        let stopped = blockage.as_ref().map_or_else(String::new, |(area, _)| {
            format!(
                ", stopped before something the plan's map does not have (held as the no-go \
                 area `{}` across its way ahead)",
                area.name
            )
        });
        (
            repair::options(situation, planner),
            format!(
                "leg `{}` cannot be completed as planned: it holds in `{place}`{stopped}",
                leg.name
            ),
        )
    };
    let (made, default) = propose(
        controller,
        running,
        (index, why, run_secs),
        candidates,
        ("repair option", &trigger),
    );
    *proposal = Some(Proposal {
        place: Some(place),
        ..made
    });
    default.map(Due::Asked)
}

/// How far across the way ahead the area of what stopped the follower reaches, each side: a
/// follower that reports `blocked` has found no way past it (its own replans spent), so the
/// area closes a passage of up to twice this.
const BLOCKAGE_HALF_WIDTH_M: f64 = 2.0;
/// How deep that area is along the way.
const BLOCKAGE_DEPTH_M: f64 = 1.0;
/// How far the robot's body keeps from that area when planning: the follower's own clearance
/// from obstacles, not a no-go area's default margin, since the robot stopped close to it.
const BLOCKAGE_MARGIN_M: f64 = 0.1;
/// How much further than the robot's radius and that margin the area starts ahead of where the
/// robot believes it is: the follower stops while its body is nearer a no-go area than twice
/// the localiser's standard deviation (0.28 m seen on a loaded machine), and the costmap's
/// cells err on the safe side; so that the robot is clear of it and drives away. The avoider
/// stops the robot 0.35 m short of an obstacle, so the area still covers a deep one's front.
const BLOCKAGE_SLACK_M: f64 = 0.6;
/// How far along the way from where the robot stopped its direction is taken.
const BLOCKAGE_LOOK_AHEAD_M: f64 = 1.5;

/// What stopped the follower on leg `index` at `here`, when the plan's map (`world` and the
/// running plan's no-go areas) has a way from there to the leg's destination: a no-go area
/// across that way just ahead of the robot (the map's own way being the one the follower was
/// driving and could not pass), as a plan's area and as the planner's keepout. None when the
/// map has no way from there (the map says why: an area reported), when the plan has no
/// geographic frame, or when the area would come near a waypoint (a plan with a waypoint in a
/// no-go area does not check).
fn blockage(
    running: &mut Running,
    world: Option<&World>,
    index: usize,
    here: Point,
) -> Option<(Graphic, Keepout)> {
    let leg = running.plan.legs.get(index)?;
    let compiled = &running.compiled;
    let origin = compiled.origin?;
    let goal = *compiled.positions.get(&leg.to)?;
    let robot = compiled.robot;
    let way = running
        .memory
        .paths
        .plan_others(world, &robot, &compiled.keepouts, &[(here, goal)])
        .ok()?
        .into_iter()
        .next()?
        .ok()?;
    let ahead = point_along(&way.points, BLOCKAGE_LOOK_AHEAD_M)?;
    let length = ahead.distance(here);
    if length < 0.05 {
        return None;
    }
    let (dx, dy) = ((ahead.x - here.x) / length, (ahead.y - here.y) / length);
    let at = |along: f64, across: f64| {
        Point::new(
            here.x + dx * along - dy * across,
            here.y + dy * along + dx * across,
        )
    };
    let near = robot.radius_m + BLOCKAGE_MARGIN_M + BLOCKAGE_SLACK_M;
    let far = near + BLOCKAGE_DEPTH_M;
    let corners = vec![
        at(near, -BLOCKAGE_HALF_WIDTH_M),
        at(far, -BLOCKAGE_HALF_WIDTH_M),
        at(far, BLOCKAGE_HALF_WIDTH_M),
        at(near, BLOCKAGE_HALF_WIDTH_M),
    ];
    let polygon = Polygon::new(corners.clone());
    let keep = robot.radius_m + BLOCKAGE_MARGIN_M + BLOCKAGE_SLACK_M;
    if compiled
        .positions
        .values()
        .any(|&waypoint| polygon.contains(waypoint) || polygon.distance_to_outline(waypoint) < keep)
    {
        return None;
    }
    let plan = &running.plan;
    let taken = |name: &str| {
        plan.graphics.iter().any(|graphic| graphic.name == name)
            || plan.waypoints.iter().any(|waypoint| waypoint.name == name)
            || plan.legs.iter().any(|leg| leg.name == name)
    };
    let wanted = format!("{}_blocked", leg.name);
    let name = std::iter::once(wanted.clone())
        .chain((2..).map(|n| format!("{wanted}_{n}")))
        .find(|name| !taken(name))?;
    let area = Graphic {
        kind: GraphicKind::Area(AreaKind::NoGo),
        name: name.clone(),
        points: corners
            .iter()
            .map(|&corner| LatLon::from_local(corner, origin))
            .collect(),
        margin_m: Some(BLOCKAGE_MARGIN_M),
        ..Default::default()
    };
    Some((area, Keepout::new(name, polygon, BLOCKAGE_MARGIN_M)))
}

/// The point `distance_m` along the polyline `points` (its last point when it is shorter).
fn point_along(points: &[Point], distance_m: f64) -> Option<Point> {
    let mut left = distance_m;
    for segment in points.windows(2) {
        let (a, b) = (segment[0], segment[1]);
        let length = a.distance(b);
        if length >= left && length > 0.0 {
            let t = left / length;
            return Some(Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t));
        }
        left -= length;
    }
    points.last().copied()
}

/// The length of the way between each pair of points on `world` for `robot` round
/// `keepouts` (all on one costmap, the one `memory` keeps when it is that one), `None` where
/// there is none: the repair's costs.
fn planner<'a>(
    memory: &'a mut PathMemory,
    world: Option<&'a World>,
    robot: &'a armor_model::planner::Robot,
    keepouts: &'a [armor_model::planner::Keepout],
) -> impl FnOnce(&[(Point, Point)]) -> Vec<Option<f64>> + 'a {
    move |pairs| {
        memory
            .plan_others(world, robot, keepouts, pairs)
            .map(|paths| {
                paths
                    .into_iter()
                    .map(|path| {
                        path.ok()
                            .map(|path| armor_model::geo::path_length(&path.points))
                    })
                    .collect()
            })
            .unwrap_or_else(|_| vec![None; pairs.len()])
    }
}

/// Shows the options of a repair of leg `index` (for `why`, at `run_secs`) in the status and
/// the log; with the plan's default (`do="repair"` on the `trigger` for the leg, and an option
/// other than waiting), the update of option 1, recorded under `label` and its summary, when
/// it is to be applied at once (else the proposal says when).
fn propose(
    controller: &mut Controller,
    running: &Running,
    (index, why, run_secs): (usize, String, f64),
    candidates: Vec<Candidate>,
    (label, trigger): (&str, &Trigger),
) -> (Proposal, Option<Asked>) {
    let leg = &running.plan.legs[index];
    let after_secs = running
        .plan
        .contingency(leg, trigger)
        .and_then(|contingency| match contingency.response {
            Response::Repair { after_secs } => Some(after_secs),
            _ => None,
        })
        .filter(|_| {
            candidates
                .first()
                .is_some_and(|candidate| candidate.kind != Kind::Wait)
        });
    let by_default = after_secs.is_some();
    let default_at_run_secs = after_secs
        .flatten()
        .map(|after_secs| run_secs + f64::from(after_secs));
    let shown = Repair {
        run_secs,
        leg: leg.name.clone(),
        why,
        options: candidates.iter().zip(1..).map(option).collect(),
        default_option: by_default.then_some(1),
        default_at_run_secs,
    };
    tracing::warn!("{}", crate::summary::repair_lines(&shown).join("\n"));
    controller.set_repair(Some(shown.clone()));
    let made = Proposal {
        place: None,
        candidates,
        shown,
        label: label.to_owned(),
        default_at_run_secs,
        default_checked: None,
        default_check_tried: false,
    };
    let default = if by_default && default_at_run_secs.is_none() {
        asked(Some(&made), 1).ok()
    } else {
        None
    };
    (made, default)
}

/// An area reported that cuts a leg after the leg in force (no way left from its start to its
/// end, the leg in force untouched): the repair of the first such leg, costed from where it
/// starts, at the time the robot would get there as planned. `plan` is the running plan with
/// the area added. Returns the proposal, and the update to take at once when the plan names
/// the default (the area and option 1 together); `None` when the area's problems are not
/// only legs cut after the leg in force (it is then refused as it stands).
pub fn for_cut_leg(
    controller: &mut Controller,
    running: &mut Running,
    area_label: &str,
    plan: &armor_model::plan::Plan,
    now: (f64, f64),
    world: Option<&World>,
) -> Option<(Proposal, Option<Asked>)> {
    let (run_secs, now_unix_secs) = now;
    let in_force = controller.marking().into_keys().find_map(|place| {
        match running.compiled.trace.get(&place) {
            Some(&Origin::Leg(index)) => Some(index),
            _ => None,
        }
    })?;
    let robot = running.compiled.robot;
    let legs = armor_model::plan::plan_legs_with(plan, world, &robot, &mut running.memory.paths);
    let cut: Vec<usize> = legs
        .paths
        .iter()
        .enumerate()
        .filter(|(_, path)| matches!(path, Some(Err(_))))
        .map(|(index, _)| index)
        .collect();
    let first = *cut.first()?;
    if first <= in_force || legs.problems.len() != cut.len() {
        return None;
    }
    let lengths: Vec<Option<f64>> = legs
        .paths
        .iter()
        .map(|path| match path {
            Some(Ok(path)) => Some(armor_model::geo::path_length(&path.points)),
            _ => None,
        })
        .collect();
    // When the robot gets to the cut leg's start, as planned: the legs before it driven at the
    // plan's speed, with their arrivals and waits.
    let speed_mps = plan.navigation.speed_mps.max(f64::EPSILON);
    let until_secs: f64 = plan.legs[in_force..first]
        .iter()
        .zip(&lengths[in_force..first])
        .map(|(leg, length)| {
            length.unwrap_or(0.0) / speed_mps
                + leg
                    .arrival
                    .as_ref()
                    .and_then(|arrival| arrival.for_secs)
                    .unwrap_or(0.0)
                + leg.wait_secs.unwrap_or(0.0)
        })
        .sum();
    let leg = &plan.legs[first];
    let here = *legs.positions.get(&leg.from)?;
    let candidates = repair::options(
        Situation {
            plan,
            positions: &legs.positions,
            route_lengths_m: &lengths,
            index: first,
            here,
            now_unix_secs: now_unix_secs + until_secs,
            blockage: None,
        },
        planner(&mut running.memory.paths, world, &robot, &legs.keepouts),
    );
    let why = format!(
        "{area_label} leaves leg `{}` no way from `{}` to `{}`: costed from `{}`",
        leg.name, leg.from, leg.to, leg.from
    );
    // The options are plans with the area: shown against the running plan, whose leg of that
    // name is the one cut.
    let running_with_area = Running {
        plan: plan.clone(),
        ..running.clone()
    };
    Some(propose(
        controller,
        &running_with_area,
        (first, why, run_secs),
        candidates,
        (&format!("{area_label}, repair option"), &Trigger::Blocked),
    ))
}

/// The protocol's form of an option.
fn option((candidate, number): (&Candidate, u32)) -> RepairOption {
    RepairOption {
        number,
        kind: match candidate.kind {
            Kind::WayRound => RepairKind::WayRound,
            Kind::Skip => RepairKind::Skip,
            Kind::Return => RepairKind::Return,
            Kind::Wait => RepairKind::Wait,
            Kind::PushBack => RepairKind::PushBack,
            Kind::DropDeadline => RepairKind::DropDeadline,
        },
        summary: candidate.summary.clone(),
        via: candidate.via.clone(),
        legs_dropped: candidate.legs_dropped.clone(),
        distance_m: candidate.distance_m,
        duration_secs: candidate.duration_secs,
        deadlines_missed: candidate.deadlines_missed.clone(),
    }
}

/// Why an option of a repair cannot be applied.
#[derive(Debug, thiserror::Error)]
pub enum NotApplied {
    #[error("no repair is proposed: no leg holds for want of a way")]
    NoneProposed,
    #[error("the repair proposed for leg `{leg}` has options 1 to {count}, not {number}")]
    NoSuchOption {
        leg: String,
        count: usize,
        number: u32,
    },
    #[error(
        "option {number} is to wait: the leg holds as it is (update the plan, fire `{leg}_retry` \
         or `{leg}_skip`, or abort)"
    )]
    Wait { number: u32, leg: String },
}

/// The update option `number` of the proposal asks for, or why there is none.
pub fn asked(proposal: Option<&Proposal>, number: u32) -> Result<Asked, NotApplied> {
    let Some(proposal) = proposal else {
        return Err(NotApplied::NoneProposed);
    };
    let index = usize::try_from(number).unwrap_or(usize::MAX);
    let Some(candidate) = index
        .checked_sub(1)
        .and_then(|index| proposal.candidates.get(index))
    else {
        return Err(NotApplied::NoSuchOption {
            leg: proposal.shown.leg.clone(),
            count: proposal.candidates.len(),
            number,
        });
    };
    match &candidate.plan {
        Some(plan) => Ok(Asked::Repair {
            label: format!("{} {number}: {}", proposal.label, candidate.summary),
            plan: Box::new(plan.clone()),
        }),
        None => Err(NotApplied::Wait {
            number,
            leg: proposal.shown.leg.clone(),
        }),
    }
}

//! The robot's data as the run view shows it: poses (estimated and true), the laser scan, the
//! occupancy grid and the paths the follower follows. During a run, a node of the studio's own (named `studio`) subscribes to the
//! outputs that carry them, as any module would, best-effort and at most [`MAX_RATE_HZ`] samples
//! a second (the providers skip the others): it never holds a provider back. A recording (an MCAP file of the recorder) feeds the same
//! views from its messages instead.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use armor_model::SystemConfig;
use armor_model::world::Point;
use armor_module_api::types::{
    LaserScan, Markers, OccupancyGrid, Odometry, Pose2D, PoseEstimate, Text,
};
use armor_module_api::{Datum, Event, ModuleDescription, ModuleSpec, Node, Standalone};

use super::inspector::Outputs;
use super::markers::Layers;
use super::untrusted::{self, Refused, Timeline};

/// The studio node's name, as the agent and the providers' logs show it.
pub const NODE_NAME: &str = "studio";
/// Points of the true path kept for the trail.
const MAX_TRAIL: usize = 4000;
/// Paths kept for one goal: the follower's first and at most 100 replans (its `max_replans`
/// range), and one more for a restart.
const MAX_FOLLOWED: usize = 102;
/// Samples per second asked of each provider: a display needs no more, and a simulation run
/// fast publishes thousands, each of which would cost its provider a send.
pub const MAX_RATE_HZ: f64 = 30.0;

/// The data names the live views read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Sources {
    /// The robot's own estimate: the localiser's pose on the map when there is one, else a
    /// corrected pose (the mapper's), else odometry.
    pub estimated: Option<String>,
    /// The localiser's estimate with its covariance and state (`PoseEstimate`).
    pub estimate: Option<String>,
    /// The simulator's ground truth.
    pub truth: Option<String>,
    pub scan: Option<String>,
    pub grid: Option<String>,
    /// The path the navigation follows (the follower's `path` output, `Text`).
    pub path: Option<String>,
    /// Every `Image` output, for the video panel to pick from.
    pub images: Vec<String>,
    /// Every output (data name, data type), for the inspector and the markers' layers.
    pub outputs: Vec<(String, String)>,
}

impl Sources {
    /// Picks the outputs of a system by their data types: `Odometry` and `Pose2D` outputs named
    /// like truth (`*truth*`) or not, the first `PoseEstimate`, the first `LaserScan`, the
    /// first `OccupancyGrid`.
    pub fn of(
        system: &SystemConfig,
        describe: impl Fn(&str) -> Option<ModuleDescription>,
    ) -> Sources {
        let mut outputs = Vec::new();
        for module in &system.modules {
            if let Some(description) = describe(&module.module_type) {
                for port in &description.outputs {
                    outputs.push((
                        module.module_type.clone(),
                        format!("{}.{}", module.name, port.name),
                        port.data_type.clone(),
                    ));
                }
            }
        }
        let find = |wanted: &dyn Fn(&str, &str, &str) -> bool| {
            outputs
                .iter()
                .find(|(module_type, name, data_type)| wanted(module_type, name, data_type))
                .map(|(_, name, _)| name.clone())
        };
        Sources {
            truth: find(&|_, name, data_type| data_type == "Pose2D" && name.contains("truth")),
            // What the robot drives by: the pose linked to the follower's odometry (in the
            // bundled systems the localiser's; the mapper's in a building nobody mapped), else
            // a localiser's, a mapper's, any odometry.
            estimated: driven_by(system)
                .filter(|name| {
                    outputs
                        .iter()
                        .any(|(_, output, data_type)| output == name && data_type == "Odometry")
                })
                .or_else(|| {
                    find(&|module_type, _, data_type| {
                        module_type == "localiser" && data_type == "Odometry"
                    })
                })
                .or_else(|| {
                    find(&|module_type, _, data_type| {
                        module_type == "mapper" && data_type == "Odometry"
                    })
                })
                .or_else(|| find(&|_, _, data_type| data_type == "Odometry")),
            estimate: find(&|_, _, data_type| data_type == PoseEstimate::TYPE),
            scan: find(&|_, _, data_type| data_type == "LaserScan"),
            grid: find(&|_, _, data_type| data_type == "OccupancyGrid"),
            path: find(&|module_type, name, data_type| {
                module_type == "follower" && data_type == "Text" && name.ends_with(".path")
            }),
            images: outputs
                .iter()
                .filter(|(_, _, data_type)| data_type == "Image")
                .map(|(_, name, _)| name.clone())
                .collect(),
            outputs: outputs
                .into_iter()
                .map(|(_, name, data_type)| (name, data_type))
                .collect(),
        }
    }

    /// Every data name to subscribe to, once each.
    fn names(&self) -> impl Iterator<Item = &String> {
        let mut names: Vec<&String> = [
            &self.estimated,
            &self.estimate,
            &self.truth,
            &self.scan,
            &self.grid,
            &self.path,
        ]
        .into_iter()
        .flatten()
        .chain(&self.images)
        .chain(self.outputs.iter().map(|(name, _)| name))
        .collect();
        names.sort();
        names.dedup();
        names.into_iter()
    }

    /// The data type of an output, as the system declares it.
    fn data_type(&self, data_name: &str) -> Option<&str> {
        self.outputs
            .iter()
            .find(|(name, _)| name == data_name)
            .map(|(_, data_type)| data_type.as_str())
    }
}

/// The output linked to the `odometry` input of the system's follower (`localiser.pose`).
fn driven_by(system: &SystemConfig) -> Option<String> {
    let follower = system
        .modules
        .iter()
        .find(|module| module.module_type == "follower")?;
    system
        .links
        .iter()
        .filter(|link| link.to.module == follower.name && link.to.port == "odometry")
        .min_by_key(|link| link.fallback)
        .map(|link| format!("{}.{}", link.from.module, link.from.port))
}

/// The latest of each, with the true path so far.
#[derive(Clone, Debug, Default)]
pub struct LiveData {
    pub estimated: Option<Pose2D>,
    /// The localiser's latest estimate: its covariance and state (none without a localiser).
    pub estimate: Option<PoseEstimate>,
    pub truth: Option<Pose2D>,
    pub scan: Option<LaserScan>,
    /// Shared, not copied, by each frame's snapshot: it may hold millions of cells.
    pub grid: Option<Arc<OccupancyGrid>>,
    /// Bumped with each new grid, so that its picture is made again only then.
    pub grid_revision: u64,
    pub trail: VecDeque<(f64, f64)>,
    /// The paths followed towards the current goal.
    pub followed: Followed,
    /// The latest frame of each image output.
    pub video: super::video::Frames,
    /// Samples received, all sources together.
    pub samples: u64,
    /// The last sample that was not taken, and why (`mapper.grid: …`); the view keeps showing
    /// the last good one of that source.
    pub refused: Option<String>,
    /// Every output's recent samples, for the inspector.
    pub outputs: Outputs,
    /// Each module's latest markers.
    pub markers: Layers,
}

impl LiveData {
    /// Takes one sample of `data_name` (encoded as on the wire); unknown names are ignored. A
    /// sample that cannot be decoded, or whose sizes or numbers cannot be drawn
    /// ([`untrusted`]), is not taken: the reason is kept in `refused` (and logged when it
    /// changes), and nothing the size it claims is allocated.
    pub fn take(&mut self, sources: &Sources, data_name: &str, payload: &[u8]) {
        let is = |source: &Option<String>| source.as_deref() == Some(data_name);
        self.samples += 1;
        let data_type = sources.data_type(data_name);
        if let Some(data_type) = data_type {
            self.outputs.take(data_name, data_type, payload);
        }
        let taken = if data_type == Some(Markers::TYPE) {
            Markers::decode(payload)
                .map_err(|err| err.to_string())
                .and_then(|markers| self.markers.take(data_name, markers))
        } else if is(&sources.truth) {
            checked(Pose2D::decode(payload), untrusted::check_pose).map(|pose| {
                self.trail_to(&pose);
                self.truth = Some(pose);
            })
        } else if is(&sources.estimated) {
            let pose = Odometry::decode(payload)
                .map(|odometry| odometry.pose_in_odom)
                .or_else(|_| Pose2D::decode(payload));
            checked(pose, untrusted::check_pose).map(|pose| self.estimated = Some(pose))
        } else if is(&sources.estimate) {
            checked(PoseEstimate::decode(payload), |estimate| {
                untrusted::check_pose(&estimate.pose_in_map)
            })
            .map(|estimate| self.estimate = Some(estimate))
        } else if is(&sources.scan) {
            checked(LaserScan::decode(payload), untrusted::check_scan)
                .map(|scan| self.scan = Some(scan))
        } else if is(&sources.grid) {
            checked(OccupancyGrid::decode(payload), untrusted::check_grid).map(|grid| {
                self.grid = Some(Arc::new(grid));
                self.grid_revision += 1;
            })
        } else if is(&sources.path) {
            Text::decode(payload)
                .map_err(|err| err.to_string())
                .and_then(|text| untrusted::parse_path(&text.0).map_err(|err| err.to_string()))
                .map(|points| {
                    self.followed
                        .take(points.into_iter().map(|(x, y)| Point::new(x, y)).collect());
                })
        } else if sources.images.iter().any(|name| name == data_name) {
            self.video.take(data_name, payload)
        } else {
            Ok(())
        };
        if let Err(reason) = taken {
            let refused = format!("`{data_name}`: {reason}");
            if self.refused.as_ref() != Some(&refused) {
                tracing::warn!("a sample was not shown: {refused}");
            }
            self.refused = Some(refused);
        }
    }

    fn trail_to(&mut self, pose: &Pose2D) {
        let moved = self
            .trail
            .back()
            .is_none_or(|(x, y)| (x - pose.x_m).hypot(y - pose.y_m) > 0.05);
        if moved {
            if self.trail.len() == MAX_TRAIL {
                self.trail.pop_front();
            }
            self.trail.push_back((pose.x_m, pose.y_m));
        }
    }

    /// The pose the scan is drawn from: the truth in simulation (where the laser really is),
    /// else the estimate.
    pub fn scan_pose(&self) -> Option<&Pose2D> {
        self.truth.as_ref().or(self.estimated.as_ref())
    }
}

/// The paths the follower published towards its current goal, oldest first: the one it set
/// out on (unless it was published before the studio subscribed), then one per replan, and the
/// leg's own again if it was started afresh. A path to another goal (the next leg) starts the
/// list again; which of them are replans is the view's to tell, with the plan's routes.
#[derive(Clone, Debug, Default)]
pub struct Followed {
    pub paths: Vec<Arc<[Point]>>,
}

impl Followed {
    /// Takes a newly published path (the same one again is not a new one); an empty one (no
    /// path: the follower heads for its goal) ends the list.
    pub fn take(&mut self, points: Vec<Point>) {
        let goal = |path: &[Point]| path.last().copied();
        let same_goal = match (self.paths.last().and_then(|p| goal(p)), goal(&points)) {
            (Some(a), Some(b)) => (a.x - b.x).hypot(a.y - b.y) < SAME_POINT_M,
            _ => false,
        };
        if !same_goal {
            self.paths.clear();
        }
        let again = self
            .paths
            .last()
            .is_some_and(|last| **last == *points.as_slice());
        if points.len() >= 2 && !again {
            if self.paths.len() == MAX_FOLLOWED {
                self.paths.remove(0);
            }
            self.paths.push(points.into());
        }
    }
}

/// Points this close are the same (paths are published to the millimetre).
pub const SAME_POINT_M: f64 = 0.05;

/// A decoded sample that passes `check`, else why not.
fn checked<T>(
    decoded: Result<T, armor_module_api::types::CodecError>,
    check: impl FnOnce(&T) -> Result<(), Refused>,
) -> Result<T, String> {
    let value = decoded.map_err(|err| err.to_string())?;
    check(&value).map_err(|refused| refused.to_string())?;
    Ok(value)
}

/// The live data of a run: written by the studio's node, read by the frame.
pub type SharedLive = Arc<Mutex<LiveData>>;

pub fn lock(live: &SharedLive) -> MutexGuard<'_, LiveData> {
    live.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Starts the studio's node on a thread: it subscribes to `sources` through the agent at
/// `agent` and writes what arrives into `shared` until `stop`.
pub fn start(
    agent: SocketAddr,
    secret: Option<PathBuf>,
    sources: Sources,
    shared: &SharedLive,
    stop: &Arc<AtomicBool>,
    ctx: &egui::Context,
) {
    if sources.names().next().is_none() {
        return;
    }
    let shared = Arc::clone(shared);
    let stop = Arc::clone(stop);
    let ctx = ctx.clone();
    std::thread::spawn(move || {
        if let Err(err) = watch(agent, secret, &sources, &shared, &stop, &ctx) {
            tracing::warn!("the live views have no data: {err}");
        }
    });
}

fn watch(
    agent: SocketAddr,
    secret: Option<PathBuf>,
    sources: &Sources,
    shared: &SharedLive,
    stop: &AtomicBool,
    ctx: &egui::Context,
) -> anyhow::Result<()> {
    let spec = ModuleSpec::new(NODE_NAME, "ArMoR Studio's run view.");
    // Attached with a role's key (an observer's, say) rather than the secret, the node proves
    // the role's reader name, which the agent lets look data up and nothing more.
    let name = secret
        .as_deref()
        .and_then(|file| armor_module_api::auth::RoleKey::load(file).ok())
        .map_or(NODE_NAME, |key| key.role.data_identity());
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some(name.to_owned()),
            agent: Some(agent.to_string()),
            secret,
            ..Standalone::default()
        },
    )?;
    let inputs: Vec<_> = sources
        .names()
        .map(|name| Ok((node.subscribe_raw_at_most(name, MAX_RATE_HZ)?, name.clone())))
        .collect::<anyhow::Result<_>>()?;
    while !stop.load(Ordering::Relaxed) {
        match node.next_event(Some(Duration::from_millis(100)))? {
            Event::Input(id) => {
                let Some((input, name)) = inputs.iter().find(|(input, _)| input.id() == id) else {
                    continue;
                };
                if let Some(sample) = node.take_raw(input) {
                    lock(shared).take(sources, name, &sample.payload);
                    ctx.request_repaint_after(Duration::from_millis(30));
                }
            }
            Event::Shutdown => break,
            _ => {}
        }
    }
    Ok(())
}

/// A recording opened in the run view: its messages, played into the live views at a chosen
/// time.
pub struct Recording {
    pub file: std::path::PathBuf,
    /// In the order of their log times (a file may hold them in any order).
    messages: Vec<armor_runtime::replay::Recorded>,
    timeline: Timeline,
    pub sources: Sources,
    /// Seconds from the first message to the last.
    pub duration_secs: f64,
    /// The time shown, from the first message.
    pub at_secs: f64,
    pub playing: bool,
    /// What the views show at `at_secs`.
    pub live: LiveData,
    shown_up_to: usize,
}

impl Recording {
    /// Reads a recording; its sources are picked by data type among its channels.
    pub fn open(file: &Path) -> anyhow::Result<Recording> {
        let messages =
            armor_runtime::replay::read_recording_within(file, untrusted::MAX_RECORDING_BYTES)?;
        Recording::of(file, messages)
    }

    /// A recording of `messages`, read from `file`, shown at its end.
    pub fn of(
        file: &Path,
        mut messages: Vec<armor_runtime::replay::Recorded>,
    ) -> anyhow::Result<Recording> {
        // Stable: messages logged at the same time keep the order the file gives them.
        messages.sort_by_key(|message| message.log_time_ns);
        let Some(timeline) = Timeline::of(messages.iter().map(|message| message.log_time_ns))
        else {
            anyhow::bail!("{} holds no message", file.display());
        };
        let first_of = |wanted: &dyn Fn(&armor_runtime::replay::Recorded) -> bool| {
            messages
                .iter()
                .find(|message| wanted(message))
                .map(|message| message.data_name.clone())
        };
        let sources = Sources {
            truth: first_of(&|m| m.data_type == "Pose2D" && m.data_name.contains("truth")),
            // A localiser's pose (`localiser.pose`) before plain odometry, as in a run.
            estimated: first_of(&|m| m.data_type == "Odometry" && m.data_name.ends_with(".pose"))
                .or_else(|| first_of(&|m| m.data_type == "Odometry"))
                .or_else(|| {
                    first_of(&|m| m.data_type == "Pose2D" && !m.data_name.contains("truth"))
                }),
            estimate: first_of(&|m| m.data_type == PoseEstimate::TYPE),
            scan: first_of(&|m| m.data_type == "LaserScan"),
            grid: first_of(&|m| m.data_type == "OccupancyGrid"),
            path: first_of(&|m| m.data_type == "Text" && m.data_name.ends_with(".path")),
            images: messages
                .iter()
                .filter(|message| message.data_type == "Image")
                .fold(Vec::new(), |mut names, message| {
                    if !names.contains(&message.data_name) {
                        names.push(message.data_name.clone());
                    }
                    names
                }),
            outputs: {
                let mut channels: Vec<(String, String)> = messages
                    .iter()
                    .map(|m| (m.data_name.clone(), m.data_type.clone()))
                    .collect();
                channels.sort();
                channels.dedup();
                channels
            },
        };
        let mut recording = Recording {
            file: file.to_path_buf(),
            duration_secs: timeline.duration_secs(),
            messages,
            timeline,
            sources,
            at_secs: 0.0,
            playing: false,
            live: LiveData::default(),
            shown_up_to: 0,
        };
        recording.seek(recording.duration_secs);
        Ok(recording)
    }

    /// The run time the play head shows, in nanoseconds (as the messages' log times).
    pub fn play_head_ns(&self) -> u64 {
        self.timeline.until_ns(self.at_secs)
    }

    pub fn message_count(&self) -> usize {
        self.messages.len()
    }

    /// Shows the recording as it was `at_secs` after its first message (clamped to the
    /// recording; NaN is its start).
    pub fn seek(&mut self, at_secs: f64) {
        let at_secs = self.timeline.clamp_secs(at_secs);
        if at_secs < self.at_secs || self.shown_up_to == 0 {
            self.live = LiveData::default();
            self.shown_up_to = 0;
        }
        self.at_secs = at_secs;
        let until = self.timeline.until_ns(at_secs);
        while let Some(message) = self.messages.get(self.shown_up_to)
            && message.log_time_ns <= until
        {
            self.live
                .take(&self.sources, &message.data_name, &message.payload);
            self.shown_up_to += 1;
        }
    }

    /// Moves the play head by `real_secs` when playing; true at the end.
    pub fn advance(&mut self, real_secs: f64) -> bool {
        if self.playing {
            self.seek(self.at_secs + real_secs);
            if self.at_secs >= self.duration_secs {
                self.playing = false;
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode<T: Datum>(value: &T) -> Vec<u8> {
        let mut out = Vec::new();
        value.encode(&mut out).unwrap_or_default();
        out
    }

    #[test]
    fn samples_go_to_their_view_and_the_truth_leaves_a_trail() {
        let sources = Sources {
            truth: Some("sim.pose_truth".into()),
            estimated: Some("sim.odometry".into()),
            ..Sources::default()
        };
        let mut live = LiveData::default();
        for x in [0.0, 0.01, 1.0] {
            let pose = Pose2D {
                x_m: x,
                y_m: 2.0,
                theta_rad: 0.0,
            };
            live.take(&sources, "sim.pose_truth", &encode(&pose));
        }
        assert_eq!(live.trail.len(), 2, "a move under 5 cm is not a new point");
        let odometry = Odometry {
            pose_in_odom: Pose2D {
                x_m: 0.9,
                y_m: 2.1,
                theta_rad: 0.1,
            },
            ..Odometry::default()
        };
        live.take(&sources, "sim.odometry", &encode(&odometry));
        assert_eq!(live.estimated.map(|pose| pose.x_m), Some(0.9));
        assert_eq!(live.truth.map(|pose| pose.x_m), Some(1.0));
        live.take(&sources, "other.thing", &[1, 2, 3]);
        assert_eq!(live.samples, 5);
    }

    fn description(module_type: &str, outputs: &[(&str, &str)]) -> ModuleDescription {
        let mut description = ModuleDescription::new(module_type, "");
        for (name, data_type) in outputs {
            description
                .outputs
                .push(armor_module_api::describe::PortSpec {
                    name: (*name).to_owned(),
                    data_type: (*data_type).to_owned(),
                    doc: String::new(),
                });
        }
        description
    }

    #[test]
    fn the_estimated_pose_is_the_one_the_follower_drives_by() {
        let descriptions = [
            description("sim", &[("odometry", "Odometry"), ("pose_truth", "Pose2D")]),
            description(
                "localiser",
                &[("pose", "Odometry"), ("estimate", "PoseEstimate")],
            ),
            description("mapper", &[("pose", "Odometry")]),
            description("follower", &[]),
        ];
        let describe = |module_type: &str| {
            descriptions
                .iter()
                .find(|d| d.module_type == module_type)
                .cloned()
        };
        let system = |driven_by: &str| {
            SystemConfig::parse(&format!(
                r#"<system name="s">
                     <module name="sim" type="sim"/><module name="mapper" type="mapper"/>
                     <module name="localiser" type="localiser"/>
                     <module name="follower" type="follower"/>
                     <link from="{driven_by}" to="follower.odometry"/>
                   </system>"#
            ))
            .expect("a valid system")
        };
        let sources = Sources::of(&system("localiser.pose"), describe);
        assert_eq!(sources.estimated.as_deref(), Some("localiser.pose"));
        assert_eq!(sources.estimate.as_deref(), Some("localiser.estimate"));
        assert_eq!(sources.truth.as_deref(), Some("sim.pose_truth"));
        let sources = Sources::of(&system("mapper.pose"), describe);
        assert_eq!(sources.estimated.as_deref(), Some("mapper.pose"));
        // Driven by the sim's odometry, the map shows that, with the localiser's estimate.
        let sources = Sources::of(&system("sim.odometry"), describe);
        assert_eq!(sources.estimated.as_deref(), Some("sim.odometry"));
        assert_eq!(sources.estimate.as_deref(), Some("localiser.estimate"));
    }

    #[test]
    fn an_estimate_is_taken_unless_its_pose_cannot_be_drawn() {
        let sources = Sources {
            estimate: Some("localiser.estimate".into()),
            ..Sources::default()
        };
        let mut live = LiveData::default();
        let good = PoseEstimate {
            pose_in_map: Pose2D {
                x_m: 4.0,
                y_m: 4.0,
                theta_rad: 0.0,
            },
            covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.001],
            fit: 0.9,
            state: armor_module_api::types::LocalisationState::Localised,
            proven: true,
        };
        live.take(&sources, "localiser.estimate", &encode(&good));
        assert_eq!(live.estimate, Some(good));
        let hostile = PoseEstimate {
            pose_in_map: Pose2D {
                x_m: f64::NAN,
                ..good.pose_in_map
            },
            ..good
        };
        live.take(&sources, "localiser.estimate", &encode(&hostile));
        assert_eq!(live.estimate, Some(good), "the last good one stays");
        assert!(live.refused.is_some_and(|r| r.contains("pose's x")));
    }

    #[test]
    fn the_followers_paths_are_kept_per_goal() {
        let sources = Sources {
            path: Some("follower.path".into()),
            ..Sources::default()
        };
        let mut live = LiveData::default();
        let mut send = |text: &str| {
            live.take(&sources, "follower.path", &encode(&Text(text.into())));
            (
                live.followed
                    .paths
                    .iter()
                    .map(|path| path.len())
                    .collect::<Vec<_>>(),
                live.refused.clone(),
            )
        };
        assert_eq!(send("4,4 16,4"), (vec![2], None));
        // A replan: from where the robot is, to the same goal (to the millimetre).
        assert_eq!(send("9,4 10,5 16.001,4"), (vec![2, 3], None));
        // The next leg's path, to another goal.
        assert_eq!(send("16,4 20,4"), (vec![2], None));
        let (kept, refused) = send("16,4 x");
        assert_eq!(kept, vec![2], "a broken path leaves the last good one");
        assert!(refused.is_some_and(|r| r.contains("point 2")));
        // No path: nothing is followed.
        assert_eq!(send("").0, Vec::<usize>::new());
    }

    fn grid(width: u32, height: u32, cells: Vec<i8>) -> OccupancyGrid {
        OccupancyGrid {
            resolution_m: 0.5,
            width,
            height,
            cells,
            ..OccupancyGrid::default()
        }
    }

    #[test]
    fn hostile_samples_are_refused_and_the_last_good_ones_stay() {
        let sources = Sources {
            truth: Some("sim.pose_truth".into()),
            scan: Some("sim.scan".into()),
            grid: Some("mapper.grid".into()),
            ..Sources::default()
        };
        let mut live = LiveData::default();
        live.take(&sources, "mapper.grid", &encode(&grid(2, 1, vec![0, 100])));
        assert_eq!(live.grid_revision, 1);
        assert_eq!(live.refused, None);

        // Width × height of 2^64 − 2^33 + 1 cells, four of them sent: refused on sight.
        live.take(
            &sources,
            "mapper.grid",
            &encode(&grid(u32::MAX, u32::MAX, vec![0; 4])),
        );
        let refused = live.refused.clone().unwrap_or_default();
        assert!(
            refused.starts_with("`mapper.grid`: a grid of 4294967295 × 4294967295 cells is larger"),
            "{refused}"
        );
        live.take(&sources, "mapper.grid", &encode(&grid(3, 3, vec![0; 4])));
        let refused = live.refused.clone().unwrap_or_default();
        assert!(refused.contains("3 × 3 cells came with 4"), "{refused}");
        assert_eq!(live.grid_revision, 1, "no new picture for a refused grid");
        assert_eq!(live.grid.as_ref().map(|grid| grid.width), Some(2));

        let good = Pose2D {
            x_m: 1.0,
            ..Pose2D::default()
        };
        live.take(&sources, "sim.pose_truth", &encode(&good));
        for hostile in [f64::NAN, f64::INFINITY, 1e300] {
            let pose = Pose2D {
                x_m: hostile,
                ..Pose2D::default()
            };
            live.take(&sources, "sim.pose_truth", &encode(&pose));
        }
        assert_eq!(live.truth, Some(good));
        assert_eq!(live.trail.len(), 1);
        assert!(
            live.refused
                .as_deref()
                .is_some_and(|r| r.contains("pose's x"))
        );

        let long = LaserScan {
            ranges_m: vec![1.0; untrusted::MAX_SCAN_RANGES + 1],
            ..LaserScan::default()
        };
        live.take(&sources, "sim.scan", &encode(&long));
        assert_eq!(live.scan, None);
        live.take(&sources, "sim.scan", &[0xFF; 3]);
        let refused = live.refused.clone().unwrap_or_default();
        assert!(refused.contains("cannot decode LaserScan"), "{refused}");
    }

    /// A recording of truth poses whose x is the message's place in the file.
    fn recording_at(times_ns: &[u64]) -> anyhow::Result<Recording> {
        let messages = times_ns
            .iter()
            .enumerate()
            .map(|(index, &log_time_ns)| armor_runtime::replay::Recorded {
                log_time_ns,
                data_name: "sim.pose_truth".into(),
                data_type: "Pose2D".into(),
                payload: encode(&Pose2D {
                    x_m: index as f64,
                    ..Pose2D::default()
                }),
            })
            .collect();
        Recording::of(Path::new("hostile.mcap"), messages)
    }

    fn shown_x(recording: &Recording) -> Option<f64> {
        recording.live.truth.map(|pose| pose.x_m)
    }

    #[test]
    fn messages_out_of_order_are_played_in_the_order_of_their_times() {
        let mut recording = recording_at(&[30, 10, 20, 10]).expect("opens");
        assert!((recording.duration_secs - 20e-9).abs() < 1e-18);
        assert_eq!(shown_x(&recording), Some(0.0), "the latest, at the end");
        recording.seek(0.0);
        assert_eq!(shown_x(&recording), Some(3.0), "at 10 ns, in file order");
        assert_eq!(recording.live.samples, 2);
        recording.seek(15e-9);
        assert_eq!(shown_x(&recording), Some(2.0));
    }

    #[test]
    fn hostile_timestamps_neither_overflow_nor_panic() {
        // The first at 1 ns, the last at u64::MAX: the old play head added the duration, rounded
        // up to 2^64 ns, to the first.
        let mut recording = recording_at(&[1, u64::MAX]).expect("opens");
        assert_eq!(
            shown_x(&recording),
            Some(1.0),
            "the last is shown at the end"
        );
        for at_secs in [f64::MAX, f64::INFINITY, 1e300, recording.duration_secs] {
            recording.seek(at_secs);
            assert_eq!(recording.at_secs, recording.duration_secs);
            assert_eq!(shown_x(&recording), Some(1.0));
        }
        for at_secs in [f64::NAN, -1.0, f64::NEG_INFINITY, 0.0] {
            recording.seek(at_secs);
            assert_eq!(recording.at_secs, 0.0);
            assert_eq!(shown_x(&recording), Some(0.0));
        }
        recording.playing = true;
        assert!(recording.advance(f64::INFINITY), "played to the end");
        assert_eq!(shown_x(&recording), Some(1.0));

        // Last before first in the file, at both ends of the range.
        let mut backwards = recording_at(&[u64::MAX, 0]).expect("opens");
        assert_eq!(backwards.duration_secs, u64::MAX as f64 / 1e9);
        assert_eq!(shown_x(&backwards), Some(0.0));
        backwards.seek(0.0);
        assert_eq!(shown_x(&backwards), Some(1.0));

        let mut all_at_the_end = recording_at(&[u64::MAX; 3]).expect("opens");
        assert_eq!(all_at_the_end.duration_secs, 0.0);
        assert_eq!(all_at_the_end.live.samples, 3);
        all_at_the_end.seek(5.0);
        assert_eq!(all_at_the_end.at_secs, 0.0);
        assert_eq!(all_at_the_end.live.samples, 3);

        let err = recording_at(&[]).err().map(|err| err.to_string());
        assert_eq!(err.as_deref(), Some("hostile.mcap holds no message"));
    }
}

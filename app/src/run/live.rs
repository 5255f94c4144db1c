//! The robot's data as the run view shows it: poses (estimated and true), the laser scan and the
//! occupancy grid. During a run, a node of the studio's own (named `studio`) subscribes to the
//! outputs that carry them, as any module would, best-effort and at most [`MAX_RATE_HZ`] samples
//! a second (the providers skip the others): it never holds a provider back. A recording (an MCAP file of the recorder) feeds the same
//! views from its messages instead.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use armor_model::SystemConfig;
use armor_module_api::types::{LaserScan, OccupancyGrid, Odometry, Pose2D};
use armor_module_api::{Datum, Event, ModuleDescription, ModuleSpec, Node, Standalone};

use super::session::{SharedRef, lock};

/// The studio node's name, as the agent and the providers' logs show it.
pub const NODE_NAME: &str = "studio";
/// Points of the true path kept for the trail.
const MAX_TRAIL: usize = 4000;
/// Samples per second asked of each provider: a display needs no more, and a simulation run
/// fast publishes thousands, each of which would cost its provider a send.
pub const MAX_RATE_HZ: f64 = 30.0;

/// The data names the live views read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Sources {
    /// The robot's own estimate: a corrected pose (the mapper's) when there is one, else
    /// odometry.
    pub estimated: Option<String>,
    /// The simulator's ground truth.
    pub truth: Option<String>,
    pub scan: Option<String>,
    pub grid: Option<String>,
}

impl Sources {
    /// Picks the outputs of a system by their data types: `Odometry` and `Pose2D` outputs named
    /// like truth (`*truth*`) or not, the first `LaserScan`, the first `OccupancyGrid`.
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
            estimated: find(&|module_type, _, data_type| {
                module_type == "mapper" && data_type == "Odometry"
            })
            .or_else(|| find(&|_, _, data_type| data_type == "Odometry")),
            scan: find(&|_, _, data_type| data_type == "LaserScan"),
            grid: find(&|_, _, data_type| data_type == "OccupancyGrid"),
        }
    }

    fn names(&self) -> impl Iterator<Item = &String> {
        [&self.estimated, &self.truth, &self.scan, &self.grid]
            .into_iter()
            .flatten()
    }
}

/// The latest of each, with the true path so far.
#[derive(Clone, Debug, Default)]
pub struct LiveData {
    pub estimated: Option<Pose2D>,
    pub truth: Option<Pose2D>,
    pub scan: Option<LaserScan>,
    pub grid: Option<OccupancyGrid>,
    /// Bumped with each new grid, so that its picture is made again only then.
    pub grid_revision: u64,
    pub trail: VecDeque<(f64, f64)>,
    /// Samples received, all sources together.
    pub samples: u64,
}

impl LiveData {
    /// Takes one sample of `data_name` (encoded as on the wire); unknown names are ignored.
    pub fn take(&mut self, sources: &Sources, data_name: &str, payload: &[u8]) {
        let is = |source: &Option<String>| source.as_deref() == Some(data_name);
        self.samples += 1;
        if is(&sources.truth) {
            if let Ok(pose) = Pose2D::decode(payload) {
                self.trail_to(&pose);
                self.truth = Some(pose);
            }
        } else if is(&sources.estimated) {
            let pose = Odometry::decode(payload)
                .map(|odometry| odometry.pose_in_odom)
                .or_else(|_| Pose2D::decode(payload));
            if let Ok(pose) = pose {
                self.estimated = Some(pose);
            }
        } else if is(&sources.scan) {
            self.scan = LaserScan::decode(payload).ok();
        } else if is(&sources.grid)
            && let Ok(grid) = OccupancyGrid::decode(payload)
        {
            self.grid = Some(grid);
            self.grid_revision += 1;
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

/// Starts the studio's node on a thread: it subscribes to `sources` through the agent at
/// `agent` and writes what arrives into the session's live data until `stop`.
pub fn start(
    agent: SocketAddr,
    secret: Option<PathBuf>,
    sources: Sources,
    shared: &SharedRef,
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
    shared: &SharedRef,
    stop: &AtomicBool,
    ctx: &egui::Context,
) -> anyhow::Result<()> {
    let spec = ModuleSpec::new(NODE_NAME, "ArMoR Studio's run view.");
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some(NODE_NAME.to_owned()),
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
                    lock(shared).live.take(sources, name, &sample.payload);
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
    messages: Vec<armor_runtime::replay::Recorded>,
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
        let messages = armor_runtime::replay::read_recording(file)?;
        if messages.is_empty() {
            anyhow::bail!("{} holds no message", file.display());
        }
        let first_of = |wanted: &dyn Fn(&armor_runtime::replay::Recorded) -> bool| {
            messages
                .iter()
                .find(|message| wanted(message))
                .map(|message| message.data_name.clone())
        };
        let sources = Sources {
            truth: first_of(&|m| m.data_type == "Pose2D" && m.data_name.contains("truth")),
            estimated: first_of(&|m| m.data_type == "Odometry").or_else(|| {
                first_of(&|m| m.data_type == "Pose2D" && !m.data_name.contains("truth"))
            }),
            scan: first_of(&|m| m.data_type == "LaserScan"),
            grid: first_of(&|m| m.data_type == "OccupancyGrid"),
        };
        let first = messages[0].log_time_ns;
        let last = messages.last().map_or(first, |m| m.log_time_ns);
        let mut recording = Recording {
            file: file.to_path_buf(),
            duration_secs: last.saturating_sub(first) as f64 / 1e9,
            messages,
            sources,
            at_secs: 0.0,
            playing: false,
            live: LiveData::default(),
            shown_up_to: 0,
        };
        recording.seek(recording.duration_secs);
        Ok(recording)
    }

    pub fn message_count(&self) -> usize {
        self.messages.len()
    }

    /// Shows the recording as it was `at_secs` after its first message.
    pub fn seek(&mut self, at_secs: f64) {
        let at_secs = at_secs.clamp(0.0, self.duration_secs);
        if at_secs < self.at_secs || self.shown_up_to == 0 {
            self.live = LiveData::default();
            self.shown_up_to = 0;
        }
        self.at_secs = at_secs;
        let first = self.messages[0].log_time_ns;
        let until = first + (at_secs * 1e9) as u64;
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
}

//! `camera-sim`: a simulated forward-looking camera over the simulator's world, on the run
//! clock. It takes the robot's true pose (the `sim` module's `pose_truth`) and publishes, `rate_hz`
//! times per second of run time, the view [`render::Camera`] draws from it, as raw `rgb8`,
//! `mono8` or a JPEG file.

pub mod render;

use std::time::Instant;

use armor_module_api::types::{Image, ImageEncoding, Pose2D};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::sim::load_world;
use render::Camera;

pub const TYPE: &str = "camera-sim";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "A simulated camera looking along the robot's heading in the simulator's world: walls \
         and obstacles stand wall_height_m tall on a chequered floor under a sky, rendered on \
         the CPU at rate_hz frames per second of run time.",
    )
    .category(armor_module_api::Category::Sensor)
    .version(env!("CARGO_PKG_VERSION"))
    // Part of the robot, as the sim is: a mission's places never stop it.
    .not_controllable()
    .input::<Pose2D>(
        "pose",
        "the robot's true pose in the world frame (link the sim's pose_truth); until one \
         comes, the view is from the world's start pose",
    )
    .output::<Image>(
        "image",
        "the view, stamped with the run time it shows, in the encoding chosen",
    )
    .param(
        ParamSpec::new(
            "world",
            ParamType::String,
            "the world file, found as the sim finds it (give the sim's): armor run hands the \
             module the file found next to the system file, in the module path or under \
             assets/worlds/; run alone, tried as given, then under assets/worlds/ of the current \
             directory, adding `.world` if it has no extension",
        )
        .file("worlds"),
    )
    .param(
        ParamSpec::new(
            "obstacles",
            ParamType::String,
            "obstacles not in the world file, in the world file's syntax, lines separated by \
             `;` (give the sim's, so that the camera sees what the robot runs into)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new("width", ParamType::Int, "image width in pixels")
            .min(8.0)
            .max(4096.0)
            .unit("px")
            .default("320"),
    )
    .param(
        ParamSpec::new("height", ParamType::Int, "image height in pixels")
            .min(8.0)
            .max(4096.0)
            .unit("px")
            .default("240"),
    )
    .param(
        ParamSpec::new(
            "fov_deg",
            ParamType::Float,
            "horizontal field of view (pixels are square)",
        )
        .min(10.0)
        .max(170.0)
        .unit("deg")
        .default("90"),
    )
    .param(
        ParamSpec::new("rate_hz", ParamType::Float, "frames per second of run time")
            .above(0.0)
            .max(120.0)
            .unit("Hz")
            .default("15"),
    )
    .param(
        ParamSpec::new(
            "max_real_hz",
            ParamType::Float,
            "at most this many frames per second of real time, whatever the run's time scale \
             (a run ten times faster than real time would otherwise draw ten times as many \
             frames a second, which no viewer needs): the frames between are skipped",
        )
        .above(0.0)
        .max(1000.0)
        .unit("Hz")
        .default("30"),
    )
    .param(
        ParamSpec::new(
            "wall_height_m",
            ParamType::Float,
            "how tall walls and obstacles stand",
        )
        .above(0.0)
        .unit("m")
        .default("2"),
    )
    .param(
        ParamSpec::new(
            "camera_height_m",
            ParamType::Float,
            "the lens's height above the floor",
        )
        .above(0.0)
        .unit("m")
        .default("0.5"),
    )
    .param(
        ParamSpec::new(
            "max_range_m",
            ParamType::Float,
            "walls farther than this are not drawn",
        )
        .above(0.0)
        .unit("m")
        .default("100"),
    )
    .param(
        ParamSpec::new(
            "encoding",
            ParamType::String,
            "`rgb8` (raw, 3 bytes a pixel), `mono8` (raw grey) or `jpeg`",
        )
        .choices(&["rgb8", "mono8", "jpeg"])
        .default("jpeg"),
    )
    .param(
        ParamSpec::new(
            "jpeg_quality",
            ParamType::Int,
            "JPEG quality, 1 (smallest) to 100 (best)",
        )
        .min(1.0)
        .max(100.0)
        .default("80"),
    )
    .param(frame_id_param())
}

/// The `frame_id` parameter of a camera module (this one and the webcam).
pub fn frame_id_param() -> ParamSpec {
    ParamSpec::new(
        "frame_id",
        ParamType::String,
        "the frame named in each image",
    )
    .default("camera")
}

/// The camera's settings, read from its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub camera: Camera,
    pub rate_hz: f64,
    pub max_real_hz: f64,
    pub encoding: ImageEncoding,
    pub jpeg_quality: u8,
    pub frame_id: String,
}

impl Settings {
    pub fn from_node(node: &Node) -> Result<Self, BodyError> {
        let encoding: String = node.param("encoding")?;
        let encoding = ImageEncoding::from_name(&encoding)
            .ok_or_else(|| format!("parameter `encoding`: unknown `{encoding}`"))?;
        Ok(Self {
            camera: Camera {
                width: node.param("width")?,
                height: node.param("height")?,
                fov_rad: node.param::<f64>("fov_deg")?.to_radians(),
                wall_height_m: node.param("wall_height_m")?,
                camera_height_m: node.param("camera_height_m")?,
                max_range_m: node.param("max_range_m")?,
            },
            rate_hz: node.param("rate_hz")?,
            max_real_hz: node.param("max_real_hz")?,
            encoding,
            jpeg_quality: node.param("jpeg_quality")?,
            frame_id: node.param("frame_id")?,
        })
    }
}

/// Renders and encodes frames, reusing its buffers.
#[derive(Debug)]
pub struct Shooter {
    settings: Settings,
    rgb: Vec<u8>,
}

impl Shooter {
    pub fn new(settings: Settings) -> Self {
        Self {
            settings,
            rgb: Vec::new(),
        }
    }

    /// The view from `pose` at run time `stamp_ns`, in the encoding of the settings.
    pub fn shoot(
        &mut self,
        world: &armor_model::world::World,
        pose: Pose2D,
        stamp_ns: u64,
        image: &mut Image,
    ) -> Result<(), String> {
        let settings = &self.settings;
        let camera = &settings.camera;
        image.width = camera.width;
        image.height = camera.height;
        image.encoding = settings.encoding;
        image.stamp_ns = stamp_ns;
        image.frame_id.clone_from(&settings.frame_id);
        match settings.encoding {
            ImageEncoding::Rgb8 => camera.render(world, pose, image.data.as_mut_vec()),
            ImageEncoding::Mono8 => {
                camera.render(world, pose, &mut self.rgb);
                render::to_mono(&self.rgb, image.data.as_mut_vec());
            }
            ImageEncoding::Jpeg => {
                camera.render(world, pose, &mut self.rgb);
                render::to_jpeg(
                    &self.rgb,
                    camera.width,
                    camera.height,
                    settings.jpeg_quality,
                    image.data.as_mut_vec(),
                )?;
            }
        }
        Ok(())
    }
}

pub fn body(node: &mut Node) -> BodyResult {
    let settings = Settings::from_node(node)?;
    let world = load_world(node)?;
    let pose_input = node.input::<Pose2D>("pose")?;
    let output = node.output::<Image>("image")?;
    tracing::info!(
        "camera over `{}`: {}×{} {} at {} Hz, {:.0}° wide",
        world.name(),
        settings.camera.width,
        settings.camera.height,
        settings.encoding.name(),
        settings.rate_hz,
        settings.camera.fov_rad.to_degrees()
    );
    // Frames are due every `period_secs` of run time, and drawn at most every `min_gap` of
    // real time (less a tenth, so that timer jitter never skips a frame at a rate of exactly
    // max_real_hz).
    let period_secs = 1.0 / settings.rate_hz;
    let min_gap = std::time::Duration::from_secs_f64(0.9 / settings.max_real_hz);
    let mut last_drawn: Option<Instant> = None;
    let mut shooter = Shooter::new(settings);
    let mut pose = world.start();
    let mut image = Image {
        width: 0,
        height: 0,
        encoding: ImageEncoding::Rgb8,
        stamp_ns: 0,
        frame_id: String::new(),
        data: Default::default(),
    };
    let mut next_frame = node.timestamp();
    loop {
        let deadline: Instant = node.clock().instant_at(next_frame);
        match node.next_event_until(deadline)? {
            Event::Timeout => {
                let due = last_drawn.is_none_or(|at| at.elapsed() >= min_gap);
                if due {
                    last_drawn = Some(Instant::now());
                    let stamp_ns = (next_frame.max(0.0) * 1e9) as u64;
                    shooter.shoot(&world, pose, stamp_ns, &mut image)?;
                    node.send(&output, &image)?;
                }
                next_frame += period_secs;
                // A frame that could not be drawn in time is skipped, not drawn late in a burst.
                let now = node.timestamp();
                if next_frame < now {
                    let behind = ((now - next_frame) / period_secs).ceil();
                    tracing::debug!("{behind} frames late: skipped");
                    next_frame += behind * period_secs;
                }
            }
            Event::Input(port) if port == pose_input.id() => {
                if let Some(sample) = node.take(&pose_input)? {
                    let p = sample.value;
                    if p.x_m.is_finite() && p.y_m.is_finite() && p.theta_rad.is_finite() {
                        pose = p;
                    }
                }
            }
            Event::ParamsChanged(names) => tracing::warn!(
                "new values of {} are taken when the camera restarts",
                names.join(", ")
            ),
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

//! ROS `map_server` maps: a YAML file that names an image (PGM or PNG) and says how its pixels
//! become an occupancy grid, the format SLAM tools (gmapping, cartographer, slam_toolbox) save
//! and `map_server` loads. Read into an [`OccupancyGrid`] and from there into a [`World`] that
//! the simulator, the planner and the map tiles use like any other; written back from a grid
//! as `map_saver` writes one.
//!
//! The rules are those of the map_server documentation: a pixel's value `x` (the mean of its
//! colour channels) gives `p = (255 - x) / 255`, or `x / 255` with `negate: 1`; the cell is
//! occupied (100) when `p > occupied_thresh`, free (0) when `p < free_thresh`, else unknown
//! (-1) in the default `trinary` mode (`scale` gives the values between a ramp from 1 to 99,
//! `raw` the pixel's value itself). `origin` is the pose of the image's lower-left pixel in the
//! map frame; the image's first row is its top. Relative image names are relative to the YAML
//! file's folder.
//!
//! Two keys are ours, which map_server ignores as it ignores every key it does not read:
//! `geo_origin: [LATITUDE, LONGITUDE]`, the geographic point of the map frame's (0, 0)
//! (default 0, 0), and `start: [X, Y, YAW]`, the simulated robot's start pose (default: the
//! free place nearest the map frame's origin, where a SLAM run starts, with room for a robot).
//!
//! As a world, a map is its image's rectangle with every occupied or unknown cell a solid
//! obstacle (runs of cells merged into rectangles): the robot is kept out of what nobody has
//! seen, and the laser stops there as at a wall.
//!
//! The images are read here (PGM by hand: a header of four numbers and the bytes; PNG with the
//! `png` crate), from bytes the caller has read: this crate does no IO.

use std::path::{Path, PathBuf};

use armor_module_api::types::{OccupancyGrid, Pose2D};

use crate::world::{World, WorldError};

mod grid;
mod image;
mod yaml;

pub use grid::{as_saved, occupancy, to_map_files, world_of_grid};
pub use image::decode_image;
pub use yaml::parse_yaml;

/// How pixels become cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Trinary,
    Scale,
    Raw,
}

/// A `map.yaml`: what it says, with where.
#[derive(Clone, Debug, PartialEq)]
pub struct MapYaml {
    /// The image's path, relative to the YAML file's folder unless absolute.
    pub image: String,
    pub resolution_m: f64,
    /// The lower-left pixel's pose: x, y (metres), yaw (radians).
    pub origin: [f64; 3],
    pub occupied_thresh: f64,
    pub free_thresh: f64,
    pub negate: bool,
    pub mode: Mode,
    /// Latitude and longitude of the map frame's (0, 0) (ours).
    pub geo_origin: (f64, f64),
    /// The simulated robot's start pose (ours).
    pub start: Option<Pose2D>,
}

/// A decoded image: one grey value per pixel (the mean of the colour channels), and whether
/// it is transparent, rows from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub grey: Vec<u8>,
    /// Per pixel, when the image has an alpha channel: whether it is fully opaque.
    pub opaque: Option<Vec<bool>>,
}

/// Whether `path` names a map_server map rather than a `.world` file.
pub fn is_map_yaml(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|ext| ext.to_str()),
        Some("yaml" | "yml")
    )
}

fn error(file: &str, line: usize, col: usize, message: impl Into<String>) -> WorldError {
    WorldError {
        file: file.to_owned(),
        line,
        col,
        message: message.into(),
    }
}

/// Reads the map `yaml_path` names, with `read` doing the reading (of the YAML and the image).
pub fn load(
    yaml_path: &Path,
    read: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<(MapYaml, OccupancyGrid), WorldError> {
    let file = yaml_path.display().to_string();
    let cannot = |path: &Path, err: std::io::Error| {
        error(
            &path.display().to_string(),
            0,
            0,
            format!("cannot read the file: {err}"),
        )
    };
    let bytes = read(yaml_path).map_err(|err| cannot(yaml_path, err))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| error(&file, 0, 0, "the map's YAML is not UTF-8 text"))?;
    let map = parse_yaml(&text, &file)?;
    let image_path = image_path(yaml_path, &map.image);
    let image_bytes = read(&image_path).map_err(|err| {
        let (line, col) = image_at(&text);
        error(
            &file,
            line,
            col,
            format!(
                "cannot read the map's image `{}`: {err}",
                image_path.display()
            ),
        )
    })?;
    let image = decode_image(&image_bytes, &image_path.display().to_string())?;
    let grid = occupancy(&map, &image);
    Ok((map, grid))
}

/// Where `image` is: relative to the YAML file's folder, as map_server reads it.
fn image_path(yaml_path: &Path, image: &str) -> PathBuf {
    let folder = yaml_path.parent().unwrap_or_else(|| Path::new("."));
    folder.join(image.trim())
}

/// The line and column of the `image` key's value (for a message about the image file).
fn image_at(text: &str) -> (usize, usize) {
    text.lines()
        .enumerate()
        .find_map(|(index, line)| {
            line.strip_prefix("image:")
                .map(|rest| (index + 1, 7 + rest.len() - rest.trim_start().len()))
        })
        .unwrap_or((1, 1))
}

/// The world of the map `yaml_path` names (see [`world_of_grid`]).
pub fn load_world(
    yaml_path: &Path,
    read: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<World, WorldError> {
    let (map, grid) = load(yaml_path, read)?;
    let name = yaml_path.file_stem().map_or_else(
        || "map".to_owned(),
        |stem| stem.to_string_lossy().into_owned(),
    );
    world_of_grid(
        &grid,
        &name,
        &yaml_path.display().to_string(),
        map.geo_origin,
        map.start,
    )
}

#[cfg(test)]
mod tests;

//! `armor export --ros-map RECORDING -o DIR`: the last occupancy grid a recording holds (the
//! mapper's `map`, or any `OccupancyGrid` recorded) written as a ROS map_server map, `map.yaml`
//! and `map.pgm`, as `map_saver` writes them.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use armor_module_api::types::{Datum, OccupancyGrid};

use crate::replay;

/// Recordings whose messages would take more memory than this are refused.
const MAX_RECORDING_BYTES: usize = 4 << 30;

/// Writes the last grid of `recording` into `folder` (created if needed); returns the YAML's
/// path and the grid.
pub fn export(recording: &Path, folder: &Path) -> anyhow::Result<(PathBuf, OccupancyGrid)> {
    let messages = replay::read_recording_within(recording, MAX_RECORDING_BYTES)?;
    let Some(last) = messages
        .iter()
        .rev()
        .find(|message| message.data_type == OccupancyGrid::TYPE)
    else {
        bail!(
            "{} holds no occupancy grid (record the mapper's `map` output)",
            recording.display()
        );
    };
    let grid = OccupancyGrid::decode(&last.payload).with_context(|| {
        format!(
            "{}: the last `{}` message is not an occupancy grid",
            recording.display(),
            last.data_name
        )
    })?;
    let cells = grid.width as usize * grid.height as usize;
    if grid.cells.len() != cells || cells == 0 {
        bail!(
            "{}: the last `{}` grid is {} × {} but holds {} cells",
            recording.display(),
            last.data_name,
            grid.width,
            grid.height,
            grid.cells.len()
        );
    }
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let (yaml, pgm) = armor_model::ros_map::to_map_files(&grid, "map.pgm");
    let image = folder.join("map.pgm");
    crate::fs::write_atomically(&image, &pgm)
        .with_context(|| format!("cannot write {}", image.display()))?;
    let yaml_path = folder.join("map.yaml");
    crate::fs::write_atomically(&yaml_path, yaml.as_bytes())
        .with_context(|| format!("cannot write {}", yaml_path.display()))?;
    Ok((yaml_path, grid))
}

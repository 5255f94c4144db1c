//! From pixels to cells by map_server's rules, from cells to a world, and back to what
//! map_saver writes.

use armor_module_api::types::{OccupancyGrid, Pose2D};

use super::{Image, MapYaml, Mode, error};
use crate::world::{Point, World, WorldError};

/// A cell of this value or more is an obstacle of the world (as in the ROS costmap, where 100
/// is lethal; the `scale` mode's ramp is halved).
const BLOCKED_FROM: i8 = 50;
/// The room the default start keeps from every obstacle, when the map has it.
const START_CLEARANCE_M: f64 = 0.5;
/// What `map_saver` writes: a cell of at most this is free, of at least `OCCUPIED_AT` occupied.
const FREE_UP_TO: i8 = 25;
const OCCUPIED_AT: i8 = 65;

/// The occupancy grid map_server makes of an image, by its rules (see the module's docs):
/// row 0 of the grid is the image's bottom row, at `origin`.
pub fn occupancy(map: &MapYaml, image: &Image) -> OccupancyGrid {
    let mut cells = vec![-1_i8; image.width * image.height];
    for row in 0..image.height {
        for col in 0..image.width {
            let index = row * image.width + col;
            let mut x = image.grey[index] as f64;
            if map.negate {
                x = 255.0 - x;
            }
            let opaque = image.opaque.as_ref().is_none_or(|opaque| opaque[index]);
            let value = match map.mode {
                Mode::Raw => {
                    let raw = x as u8;
                    if raw <= 100 { raw as i8 } else { -1 }
                }
                _ => {
                    let p = (255.0 - x) / 255.0;
                    if p > map.occupied_thresh {
                        100
                    } else if p < map.free_thresh {
                        0
                    } else if map.mode == Mode::Trinary || !opaque {
                        -1
                    } else {
                        let ratio = (p - map.free_thresh) / (map.occupied_thresh - map.free_thresh);
                        (1.0 + 98.0 * ratio) as i8
                    }
                }
            };
            cells[(image.height - 1 - row) * image.width + col] = value;
        }
    }
    OccupancyGrid {
        resolution_m: map.resolution_m,
        width: image.width as u32,
        height: image.height as u32,
        origin_x_m: map.origin[0],
        origin_y_m: map.origin[1],
        cells,
    }
}

/// The world of a grid: its rectangle, with every occupied or unknown cell an obstacle.
pub fn world_of_grid(
    grid: &OccupancyGrid,
    name: &str,
    file: &str,
    geo_origin: (f64, f64),
    start: Option<Pose2D>,
) -> Result<World, WorldError> {
    let (width, height) = (grid.width as usize, grid.height as usize);
    let resolution = grid.resolution_m;
    let blocked = |col: usize, row: usize| {
        let value = grid.cells[row * width + col];
        !(0..BLOCKED_FROM).contains(&value)
    };
    let corner = |col: usize, row: usize| {
        Point::new(
            grid.origin_x_m + col as f64 * resolution,
            grid.origin_y_m + row as f64 * resolution,
        )
    };
    // Runs of blocked cells along each row, merged with the identical run of the row below:
    // a wall along a column is one rectangle, not one per cell.
    let mut rectangles: Vec<(usize, usize, usize, usize)> = Vec::new(); // col0, col1, row0, row1 (exclusive ends)
    let mut open: std::collections::HashMap<(usize, usize), usize> = Default::default();
    for row in 0..height {
        let mut next_open = std::collections::HashMap::new();
        let mut col = 0;
        while col < width {
            if !blocked(col, row) {
                col += 1;
                continue;
            }
            let from = col;
            while col < width && blocked(col, row) {
                col += 1;
            }
            let index = match open.get(&(from, col)) {
                Some(&index) => {
                    rectangles[index].3 = row + 1;
                    index
                }
                None => {
                    rectangles.push((from, col, row, row + 1));
                    rectangles.len() - 1
                }
            };
            next_open.insert((from, col), index);
        }
        open = next_open;
    }
    let obstacles = rectangles
        .iter()
        .map(|&(c0, c1, r0, r1)| {
            vec![
                corner(c0, r0),
                corner(c1, r0),
                corner(c1, r1),
                corner(c0, r1),
            ]
        })
        .collect();
    let boundary = vec![
        corner(0, 0),
        corner(width, 0),
        corner(width, height),
        corner(0, height),
    ];
    let start = match start {
        Some(start) => start,
        None => default_start(grid, &blocked).ok_or_else(|| {
            error(
                file,
                0,
                0,
                "the map has no free cell for the robot to start in",
            )
        })?,
    };
    World::from_shapes(name, file, geo_origin, start, boundary, obstacles)
}

/// The centre of the free cell nearest the map frame's origin that keeps
/// [`START_CLEARANCE_M`] from every blocked cell, else of the free cell farthest from them.
fn default_start(grid: &OccupancyGrid, blocked: &dyn Fn(usize, usize) -> bool) -> Option<Pose2D> {
    let (width, height) = (grid.width as usize, grid.height as usize);
    // Steps (8-connected) from the nearest blocked cell or the map's edge.
    let mut steps = vec![u32::MAX; width * height];
    let mut queue = std::collections::VecDeque::new();
    for row in 0..height {
        for col in 0..width {
            let edge = row == 0 || col == 0 || row + 1 == height || col + 1 == width;
            if blocked(col, row) || edge {
                steps[row * width + col] = if blocked(col, row) { 0 } else { 1 };
                queue.push_back((col, row));
            }
        }
    }
    while let Some((col, row)) = queue.pop_front() {
        let here = steps[row * width + col];
        for (dc, dr) in [
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let (c, r) = (col as isize + dc, row as isize + dr);
            if c < 0 || r < 0 || c as usize >= width || r as usize >= height {
                continue;
            }
            let index = r as usize * width + c as usize;
            if steps[index] > here + 1 {
                steps[index] = here + 1;
                queue.push_back((c as usize, r as usize));
            }
        }
    }
    let clearance_m = |index: usize| (steps[index] as f64 - 0.5) * grid.resolution_m;
    let centre = |index: usize| {
        Point::new(
            grid.origin_x_m + ((index % width) as f64 + 0.5) * grid.resolution_m,
            grid.origin_y_m + ((index / width) as f64 + 0.5) * grid.resolution_m,
        )
    };
    let free = (0..width * height).filter(|&index| steps[index] > 0);
    let roomy = free
        .clone()
        .filter(|&index| clearance_m(index) >= START_CLEARANCE_M)
        .min_by(|&a, &b| {
            let (pa, pb) = (centre(a), centre(b));
            (pa.x.hypot(pa.y)).total_cmp(&pb.x.hypot(pb.y))
        });
    let best = roomy.or_else(|| free.max_by_key(|&index| steps[index]))?;
    let at = centre(best);
    Some(Pose2D {
        x_m: at.x,
        y_m: at.y,
        theta_rad: 0.0,
    })
}

/// What a cell of `value` reads back as once saved by [`to_map_files`]: free (0), occupied
/// (100) or unknown (-1).
pub fn as_saved(value: i8) -> i8 {
    match value {
        0..=FREE_UP_TO => 0,
        OCCUPIED_AT.. => 100,
        _ => -1,
    }
}

/// A grid as `map_saver` saves it: the YAML (naming `image_name`) and a binary PGM, free cells
/// (at most 25) 254, occupied ones (65 or more) 0, the rest 205, with the thresholds that read
/// them back as they were.
pub fn to_map_files(grid: &OccupancyGrid, image_name: &str) -> (String, Vec<u8>) {
    let (width, height) = (grid.width as usize, grid.height as usize);
    let yaml = format!(
        "image: {image_name}\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        grid.resolution_m, grid.origin_x_m, grid.origin_y_m
    );
    let mut pgm = format!("P5\n# ArMoR map\n{width} {height}\n255\n").into_bytes();
    for row in (0..height).rev() {
        pgm.extend(
            grid.cells[row * width..(row + 1) * width]
                .iter()
                .map(|&value| match as_saved(value) {
                    0 => 254,
                    100 => 0,
                    _ => 205,
                }),
        );
    }
    (yaml, pgm)
}

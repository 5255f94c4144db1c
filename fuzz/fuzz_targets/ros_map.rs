//! ROS map_server maps: a `map.yaml` and its image, given as one input (the YAML, a zero byte,
//! then the image's bytes). Reading either, turning pixels into cells and cells into a world
//! never panics.
#![no_main]

use armor_model::ros_map;
use libfuzzer_sys::fuzz_target;

/// Larger images are decoded but not made into worlds, to keep each run short.
const MAX_WORLD_CELLS: usize = 250_000;

fuzz_target!(|data: &[u8]| {
    let (yaml, image) = match data.iter().position(|&byte| byte == 0) {
        Some(at) => (&data[..at], &data[at + 1..]),
        None => (data, &[][..]),
    };
    let Ok(map) = ros_map::parse_yaml(&String::from_utf8_lossy(yaml), "fuzz.yaml") else {
        return;
    };
    let Ok(image) = ros_map::decode_image(image, "fuzz.pgm") else {
        return;
    };
    let grid = ros_map::occupancy(&map, &image);
    if grid.cells.len() <= MAX_WORLD_CELLS {
        let _ = ros_map::world_of_grid(&grid, "fuzz", "fuzz.yaml", map.geo_origin, map.start);
    }
});

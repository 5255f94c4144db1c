//! map_server's documented rules on hand-written maps, and our own maps read back.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::*;
use crate::world::Point;

/// Files in memory, read as `load` reads them.
fn reader(files: &BTreeMap<PathBuf, Vec<u8>>) -> impl FnMut(&Path) -> std::io::Result<Vec<u8>> {
    move |path: &Path| {
        files
            .get(path)
            .cloned()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"))
    }
}

fn files(entries: &[(&str, &[u8])]) -> BTreeMap<PathBuf, Vec<u8>> {
    entries
        .iter()
        .map(|(name, bytes)| (PathBuf::from(name), bytes.to_vec()))
        .collect()
}

const YAML: &str = "image: map.pgm\nresolution: 0.5\norigin: [-1.0, 2.0, 0.0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\n";

/// A 4 × 3 plain PGM, top row first: black (p = 1), map_saver's free (254, p = 0.004) and
/// unknown (205, p = 0.196), mid grey 100 (p = 0.608), dark 60 (p = 0.765), white.
const PGM: &str = "P2\n# written by hand\n4 3\n255\n0 254 205 100\n60 255 254 254\n254 254 254 0\n";

fn grid_of(yaml: &str, image: &[u8]) -> OccupancyGrid {
    let files = files(&[("maps/map.yaml", yaml.as_bytes()), ("maps/map.pgm", image)]);
    load(Path::new("maps/map.yaml"), &mut reader(&files))
        .expect("loads")
        .1
}

/// The grid's rows from the top, as the image is written.
fn rows_from_top(grid: &OccupancyGrid) -> Vec<Vec<i8>> {
    let width = grid.width as usize;
    grid.cells.chunks(width).rev().map(<[i8]>::to_vec).collect()
}

#[test]
fn pixels_become_cells_by_map_servers_rules() {
    let grid = grid_of(YAML, PGM.as_bytes());
    assert_eq!((grid.width, grid.height, grid.resolution_m), (4, 3, 0.5));
    // The origin is the lower-left pixel: the image's last row is the grid's first.
    assert_eq!((grid.origin_x_m, grid.origin_y_m), (-1.0, 2.0));
    assert_eq!(
        rows_from_top(&grid),
        vec![vec![100, 0, -1, -1], vec![100, 0, 0, 0], vec![0, 0, 0, 100],]
    );
    // negate: p = x / 255, so white is occupied and black free.
    let negated = grid_of(&YAML.replace("negate: 0", "negate: 1"), PGM.as_bytes());
    assert_eq!(rows_from_top(&negated)[0], vec![0, 100, 100, -1]);
    assert_eq!(rows_from_top(&negated)[1], vec![-1, 100, 100, 100]);
    // scale: the values between the thresholds on a ramp from 1 to 99.
    let scaled = grid_of(&format!("{YAML}mode: scale\n"), PGM.as_bytes());
    let expected = (1.0 + 98.0 * ((155.0 / 255.0) - 0.196) / (0.65 - 0.196)) as i8;
    assert_eq!(rows_from_top(&scaled)[0], vec![100, 0, 1, expected]);
    // raw: the pixel's value itself.
    let raw = grid_of(&format!("{YAML}mode: raw\n"), PGM.as_bytes());
    assert_eq!(rows_from_top(&raw)[1], vec![60, -1, -1, -1]);
}

#[test]
fn binary_pgm_and_png_read_as_the_plain_pgm() {
    let plain = grid_of(YAML, PGM.as_bytes());
    let values: Vec<u8> = PGM
        .lines()
        .skip(4)
        .flat_map(|line| {
            line.split_whitespace()
                .map(|v| v.parse::<u8>().expect("byte"))
        })
        .collect();
    let mut binary = b"P5 4 3\n255\n".to_vec();
    binary.extend(&values);
    assert_eq!(grid_of(YAML, &binary), plain);
    // The same pixels as an RGB PNG (grey in every channel), named map.pgm all the same: the
    // image is told by its contents.
    let mut png_bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut png_bytes, 4, 3);
        encoder.set_color(png::ColorType::Rgb);
        let mut writer = encoder.write_header().expect("header");
        let rgb: Vec<u8> = values.iter().flat_map(|&v| [v, v, v]).collect();
        writer.write_image_data(&rgb).expect("pixels");
    }
    assert_eq!(grid_of(YAML, &png_bytes), plain);
}

fn load_error(yaml: &str, image: &[u8]) -> String {
    let files = files(&[("maps/map.yaml", yaml.as_bytes()), ("maps/map.pgm", image)]);
    load(Path::new("maps/map.yaml"), &mut reader(&files))
        .expect_err("refused")
        .to_string()
}

#[test]
fn bad_maps_are_refused_with_their_place() {
    let pgm = PGM.as_bytes();
    assert_eq!(
        load_error(&YAML.replace("0.5", "-2"), pgm),
        "maps/map.yaml:2:13: `resolution` (metres a pixel) must be greater than 0, not -2"
    );
    assert_eq!(
        load_error(&YAML.replace("[-1.0, 2.0, 0.0]", "[-1.0, 2.0]"), pgm),
        "maps/map.yaml:3:9: `origin` must be a list [x, y, yaw], found 2 values"
    );
    assert_eq!(
        load_error(&YAML.replace("2.0, 0.0", "north, 0.0"), pgm),
        "maps/map.yaml:3:16: `origin`'s y must be a finite number, not `north`"
    );
    assert_eq!(
        load_error(&YAML.replace("negate: 0", "negate: maybe"), pgm),
        "maps/map.yaml:6:9: `negate` is 0 or 1, not `maybe`"
    );
    assert!(
        load_error(&YAML.replace("free_thresh: 0.196\n", ""), pgm)
            .contains("the map has no `free_thresh`")
    );
    assert!(load_error("image: [unclosed\n", pgm).starts_with("maps/map.yaml:2:"));
    assert_eq!(
        load_error(&YAML.replace("map.pgm", "gone.pgm"), pgm),
        "maps/map.yaml:1:8: cannot read the map's image `maps/gone.pgm`: no such file"
    );
    assert!(load_error(YAML, b"P5 4 3\n255\n\x00\x00").contains("cut short"));
    // The file ends right after the header's last number (found by the fuzzer: it panicked).
    assert!(load_error(YAML, b"P5 4 3\n255").contains("cut short"));
    assert!(load_error(YAML, b"GIF89a").contains("not a PGM"));
}

/// A small seeded generator, so that a failing case can be replayed.
fn next(state: &mut u64) -> u64 {
    *state = state
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    *state >> 33
}

#[test]
fn our_maps_read_back_as_written_seeds_1_to_20() {
    for seed in 1..=20_u64 {
        let mut state = seed;
        let (width, height) = (1 + next(&mut state) % 40, 1 + next(&mut state) % 30);
        let cells: Vec<i8> = (0..width * height)
            .map(|_| match next(&mut state) % 4 {
                0 => -1,
                1 => 100,
                2 => 0,
                _ => (next(&mut state) % 101) as i8,
            })
            .collect();
        let grid = OccupancyGrid {
            resolution_m: 0.05 * (1 + next(&mut state) % 4) as f64,
            width: width as u32,
            height: height as u32,
            origin_x_m: (next(&mut state) % 200) as f64 / 10.0 - 10.0,
            origin_y_m: (next(&mut state) % 200) as f64 / 10.0 - 10.0,
            cells,
        };
        let (yaml, pgm) = to_map_files(&grid, "map.pgm");
        let expected = OccupancyGrid {
            cells: grid.cells.iter().map(|&value| as_saved(value)).collect(),
            ..grid.clone()
        };
        assert_eq!(grid_of(&yaml, &pgm), expected, "seed {seed}");
    }
}

#[test]
fn a_map_is_a_world_the_robot_and_its_laser_live_in() {
    // A 10 m × 6 m room at 0.5 m a cell: walls all round, a pillar, unknown beyond the east
    // wall; the map frame's origin is 1 m in from the south-west corner.
    let (width, height) = (24, 12);
    let mut rows = Vec::new();
    for row in 0..height {
        let mut line = Vec::new();
        for col in 0..width {
            let wall = row == 0 || row == height - 1 || col == 0 || col == 19;
            let pillar = (10..12).contains(&col) && (5..7).contains(&row);
            line.push(if col > 19 {
                205
            } else if wall || pillar {
                0
            } else {
                254
            });
        }
        rows.push(line);
    }
    let mut pgm = format!("P5 {width} {height} 255\n").into_bytes();
    pgm.extend(rows.iter().flatten());
    let yaml = "image: room.pgm\nresolution: 0.5\norigin: [-1.0, -1.0, 0.0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\ngeo_origin: [48.85, 2.35]\n";
    let files = files(&[("room.yaml", yaml.as_bytes()), ("room.pgm", &pgm)]);
    let world =
        crate::world_file::load(Path::new("room.yaml"), &mut reader(&files)).expect("a world");
    assert_eq!(world.name(), "room");
    assert_eq!(world.origin_lat_lon(), (48.85, 2.35));
    let bounds = world.bounds();
    assert_eq!(
        (bounds.min_x, bounds.min_y, bounds.max_x, bounds.max_y),
        (-1.0, -1.0, 11.0, 5.0)
    );
    // Image row 0 is the top: the pillar's rows 5 and 6 from the top are y 1.5 to 2.5.
    assert!(!world.is_free(Point::new(4.5, 2.0)));
    assert!(world.is_free(Point::new(4.5, 3.0)));
    // Looking east from (1, 2) the laser meets the pillar's west side at x = 4.
    let east = world.raycast(Point::new(1.0, 2.0), 0.0, 30.0);
    assert!((east - 3.0).abs() < 1e-9, "{east}");
    // North, the top wall's inner side at y = 4.5 (row 1 from the top ends there).
    let north = world.raycast(Point::new(1.0, 2.0), std::f64::consts::FRAC_PI_2, 30.0);
    assert!((north - 2.5).abs() < 1e-9, "{north}");
    // Unknown cells are no place for the robot.
    assert!(!world.is_free(Point::new(10.0, 2.0)));
    assert!(world.collides(8.5, 2.0, 0.3));
    // With no start given the robot starts on the free cell nearest (0, 0) that keeps 0.5 m
    // from every wall: (0.25, 0.25) is 0.75 m from the west and south walls.
    let start = world.start();
    assert_eq!((start.x_m, start.y_m), (0.25, 0.25));
}

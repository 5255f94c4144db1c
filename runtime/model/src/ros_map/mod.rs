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

use crate::world::{Point, World, WorldError};

/// Images larger than this many pixels are refused.
const MAX_PIXELS: usize = 50_000_000;
/// A cell of this value or more is an obstacle of the world (as in the ROS costmap, where 100
/// is lethal; the `scale` mode's ramp is halved).
const BLOCKED_FROM: i8 = 50;
/// The room the default start keeps from every obstacle, when the map has it.
const START_CLEARANCE_M: f64 = 0.5;
/// What `map_saver` writes: a cell of at most this is free, of at least `OCCUPIED_AT` occupied.
const FREE_UP_TO: i8 = 25;
const OCCUPIED_AT: i8 = 65;

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

/// A YAML value with the line and column (1-based) where it starts.
#[derive(Clone, Debug)]
enum Value {
    Scalar(String, (usize, usize)),
    List(Vec<Item>, (usize, usize)),
    Other((usize, usize)),
}

impl Value {
    fn at(&self) -> (usize, usize) {
        match self {
            Value::Scalar(_, at) | Value::List(_, at) | Value::Other(at) => *at,
        }
    }
}

/// A scalar of a YAML list and where it starts.
type Item = (String, (usize, usize));

/// The top-level keys of a YAML mapping, each with its value (scalars, and lists of scalars;
/// anything deeper is kept as `Other`).
#[derive(Default)]
struct TopLevel {
    depth: usize,
    key: Option<(String, (usize, usize))>,
    /// The list being read as the current key's value, and whether it holds more than scalars.
    list: Option<(Vec<Item>, (usize, usize), bool)>,
    entries: Vec<(String, (usize, usize), Value)>,
    not_a_mapping: Option<(usize, usize)>,
}

impl yaml_rust2::parser::MarkedEventReceiver for TopLevel {
    fn on_event(&mut self, event: yaml_rust2::Event, mark: yaml_rust2::scanner::Marker) {
        use yaml_rust2::Event;
        let at = (mark.line(), mark.col() + 1);
        match event {
            Event::MappingStart(..) | Event::SequenceStart(..) => {
                let sequence = matches!(event, Event::SequenceStart(..));
                self.depth += 1;
                match self.depth {
                    1 if sequence => self.not_a_mapping = Some(at),
                    2 if sequence => self.list = Some((Vec::new(), at, false)),
                    2 => self.value(Value::Other(at)),
                    _ => {
                        if let Some((_, _, nested)) = &mut self.list {
                            *nested = true;
                        }
                    }
                }
            }
            Event::MappingEnd | Event::SequenceEnd => {
                if self.depth == 2
                    && let Some((items, at, nested)) = self.list.take()
                {
                    self.value(if nested {
                        Value::Other(at)
                    } else {
                        Value::List(items, at)
                    });
                }
                self.depth = self.depth.saturating_sub(1);
            }
            Event::Scalar(text, ..) => match self.depth {
                0 => self.not_a_mapping = Some(at),
                1 if self.key.is_some() => self.value(Value::Scalar(text, at)),
                1 => self.key = Some((text, at)),
                2 => {
                    if let Some((items, _, _)) = &mut self.list {
                        items.push((text, at));
                    }
                }
                _ => {}
            },
            Event::Alias(_) if self.depth == 1 && self.key.is_some() => {
                self.value(Value::Other(at));
            }
            _ => {}
        }
    }
}

impl TopLevel {
    fn value(&mut self, value: Value) {
        if let Some((key, key_at)) = self.key.take() {
            self.entries.push((key, key_at, value));
        }
    }
}

/// Reads a `map.yaml`; every problem is `FILE:LINE:COL: message`.
pub fn parse_yaml(text: &str, file: &str) -> Result<MapYaml, WorldError> {
    let mut top = TopLevel::default();
    yaml_rust2::parser::Parser::new_from_str(text)
        .load(&mut top, false)
        .map_err(|err| {
            let mark = err.marker();
            error(file, mark.line(), mark.col() + 1, err.info().to_owned())
        })?;
    if let Some((line, col)) = top.not_a_mapping {
        return Err(error(
            file,
            line,
            col,
            "a map_server map is a mapping of keys (image, resolution, origin, ...)",
        ));
    }
    let find = |key: &str| top.entries.iter().find(|(name, ..)| name == key);
    let required = |key: &str| {
        find(key).map(|(_, _, value)| value).ok_or_else(|| {
            error(
                file,
                1,
                1,
                format!("the map has no `{key}` (map_server needs image, resolution, origin, occupied_thresh and free_thresh)"),
            )
        })
    };
    let scalar = |value: &Value, what: &str| -> Result<String, WorldError> {
        match value {
            Value::Scalar(text, _) => Ok(text.clone()),
            other => {
                let (line, col) = other.at();
                Err(error(
                    file,
                    line,
                    col,
                    format!("`{what}` must be a single value"),
                ))
            }
        }
    };
    let number = |text: &str, at: (usize, usize), what: &str| -> Result<f64, WorldError> {
        match text.trim().parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            _ => Err(error(
                file,
                at.0,
                at.1,
                format!("{what} must be a finite number, not `{text}`"),
            )),
        }
    };
    let numbers = |key: &str, value: &Value, names: &[&str]| -> Result<Vec<f64>, WorldError> {
        let Value::List(items, at) = value else {
            let (line, col) = value.at();
            return Err(error(
                file,
                line,
                col,
                format!("`{key}` must be a list [{}]", names.join(", ")),
            ));
        };
        if items.len() != names.len() {
            return Err(error(
                file,
                at.0,
                at.1,
                format!(
                    "`{key}` must be a list [{}], found {} values",
                    names.join(", "),
                    items.len()
                ),
            ));
        }
        items
            .iter()
            .zip(names)
            .map(|((text, at), name)| number(text, *at, &format!("`{key}`'s {name}")))
            .collect()
    };
    let threshold = |key: &str| -> Result<f64, WorldError> {
        let value = required(key)?;
        let at = value.at();
        let threshold = number(&scalar(value, key)?, at, &format!("`{key}`"))?;
        if !(0.0..=1.0).contains(&threshold) {
            return Err(error(
                file,
                at.0,
                at.1,
                format!("`{key}` is a probability between 0 and 1, not {threshold}"),
            ));
        }
        Ok(threshold)
    };

    let image_value = required("image")?;
    let image = scalar(image_value, "image")?;
    if image.trim().is_empty() {
        let (line, col) = image_value.at();
        return Err(error(file, line, col, "`image` names no file"));
    }
    let resolution_value = required("resolution")?;
    let resolution_m = number(
        &scalar(resolution_value, "resolution")?,
        resolution_value.at(),
        "`resolution`",
    )?;
    if resolution_m <= 0.0 {
        let (line, col) = resolution_value.at();
        return Err(error(
            file,
            line,
            col,
            format!("`resolution` (metres a pixel) must be greater than 0, not {resolution_m}"),
        ));
    }
    let origin_value = required("origin")?;
    let origin = numbers("origin", origin_value, &["x", "y", "yaw"])?;
    if origin[2] != 0.0 {
        let (line, col) = origin_value.at();
        return Err(error(
            file,
            line,
            col,
            format!(
                "`origin`'s yaw is {} rad: maps turned against their frame are not supported (map_server's own users mostly ignore it too)",
                origin[2]
            ),
        ));
    }
    let occupied_thresh = threshold("occupied_thresh")?;
    let free_thresh = threshold("free_thresh")?;
    if free_thresh > occupied_thresh {
        let (_, at, _) = find("free_thresh").expect("read above");
        return Err(error(
            file,
            at.0,
            at.1,
            format!("`free_thresh` ({free_thresh}) is above `occupied_thresh` ({occupied_thresh})"),
        ));
    }
    let value_of = |key: &str| find(key).map(|(_, _, value)| value);
    let negate = choose(
        file,
        "negate",
        value_of("negate"),
        false,
        &[
            (&["0", "false", "False"], false),
            (&["1", "true", "True"], true),
        ],
        "0 or 1",
    )?;
    let mode = choose(
        file,
        "mode",
        value_of("mode"),
        Mode::Trinary,
        &[
            (&["trinary"], Mode::Trinary),
            (&["scale"], Mode::Scale),
            (&["raw"], Mode::Raw),
        ],
        "trinary, scale or raw",
    )?;
    let geo_origin = match find("geo_origin") {
        None => (0.0, 0.0),
        Some((_, _, value)) => {
            let at = value.at();
            let lat_lon = numbers("geo_origin", value, &["latitude", "longitude"])?;
            if !(-90.0..=90.0).contains(&lat_lon[0]) || !(-180.0..=180.0).contains(&lat_lon[1]) {
                return Err(error(
                    file,
                    at.0,
                    at.1,
                    "`geo_origin` is [latitude, longitude] in degrees, within ±90 and ±180",
                ));
            }
            (lat_lon[0], lat_lon[1])
        }
    };
    let start = match find("start") {
        None => None,
        Some((_, _, value)) => {
            let pose = numbers("start", value, &["x", "y", "yaw"])?;
            Some(Pose2D {
                x_m: pose[0],
                y_m: pose[1],
                theta_rad: pose[2],
            })
        }
    };
    Ok(MapYaml {
        image,
        resolution_m,
        origin: [origin[0], origin[1], origin[2]],
        occupied_thresh,
        free_thresh,
        negate,
        mode,
        geo_origin,
        start,
    })
}

/// The value of `key`, one of a few words (each with its spellings), or `default` when absent.
fn choose<T: Copy>(
    file: &str,
    key: &str,
    value: Option<&Value>,
    default: T,
    words: &[(&[&str], T)],
    expected: &str,
) -> Result<T, WorldError> {
    let Some(value) = value else {
        return Ok(default);
    };
    let (line, col) = value.at();
    let Value::Scalar(text, _) = value else {
        return Err(error(
            file,
            line,
            col,
            format!("`{key}` must be a single value"),
        ));
    };
    let text = text.trim();
    words
        .iter()
        .find(|(spellings, _)| spellings.contains(&text))
        .map(|(_, chosen)| *chosen)
        .ok_or_else(|| {
            error(
                file,
                line,
                col,
                format!("`{key}` is {expected}, not `{text}`"),
            )
        })
}

/// Decodes a PGM (binary `P5` or plain `P2`) or PNG image.
pub fn decode_image(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    if bytes.starts_with(b"P5") || bytes.starts_with(b"P2") {
        decode_pgm(bytes, file)
    } else if bytes.starts_with(b"\x89PNG") {
        decode_png(bytes, file)
    } else {
        Err(error(
            file,
            0,
            0,
            "not a PGM (P5 or P2) or PNG image, the formats map_server maps are saved in",
        ))
    }
}

/// PGM is a header of whitespace-separated numbers (`#` comments allowed) and then the
/// pixels: four numbers need no library, and reading them here gives the line of a bad one.
fn decode_pgm(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    let plain = bytes.starts_with(b"P2");
    let mut at = 2;
    let mut line = 1;
    // The next number of the header (or of a plain file's pixels).
    let mut next = |what: &str| -> Result<usize, WorldError> {
        loop {
            match bytes.get(at) {
                Some(b'#') => {
                    while bytes.get(at).is_some_and(|&byte| byte != b'\n') {
                        at += 1;
                    }
                }
                Some(b'\n') => {
                    line += 1;
                    at += 1;
                }
                Some(byte) if byte.is_ascii_whitespace() => at += 1,
                _ => break,
            }
        }
        let start = at;
        while bytes.get(at).is_some_and(u8::is_ascii_digit) {
            at += 1;
        }
        std::str::from_utf8(&bytes[start..at])
            .ok()
            .and_then(|digits| digits.parse::<usize>().ok())
            .ok_or_else(|| error(file, line, 0, format!("the PGM's {what} is not a number")))
    };
    let width = next("width")?;
    let height = next("height")?;
    let max_value = next("largest value")?;
    if width == 0 || height == 0 || width.saturating_mul(height) > MAX_PIXELS {
        return Err(error(
            file,
            0,
            0,
            format!(
                "a {width} × {height} image is empty or too large (at most {MAX_PIXELS} pixels)"
            ),
        ));
    }
    if !(1..=65535).contains(&max_value) {
        return Err(error(
            file,
            0,
            0,
            format!("the PGM's largest value must be 1 to 65535, not {max_value}"),
        ));
    }
    let scale = |value: usize| ((value.min(max_value) * 255 + max_value / 2) / max_value) as u8;
    let count = width * height;
    let mut grey = Vec::with_capacity(count);
    if plain {
        for _ in 0..count {
            grey.push(scale(next("pixel")?));
        }
    } else {
        let (bytes_per_pixel, data) = (if max_value > 255 { 2 } else { 1 }, &bytes[at + 1..]);
        if at >= bytes.len() || data.len() < count * bytes_per_pixel {
            return Err(error(
                file,
                0,
                0,
                format!(
                    "the PGM is cut short: {width} × {height} pixels need {} bytes, found {}",
                    count * bytes_per_pixel,
                    bytes.len().saturating_sub(at + 1)
                ),
            ));
        }
        grey.extend(data.chunks_exact(bytes_per_pixel).take(count).map(|pixel| {
            let value = pixel
                .iter()
                .fold(0_usize, |sum, &byte| (sum << 8) | byte as usize);
            scale(value)
        }));
    }
    Ok(Image {
        width,
        height,
        grey,
        opaque: None,
    })
}

fn decode_png(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    let fail =
        |err: png::DecodingError| error(file, 0, 0, format!("the PNG does not decode: {err}"));
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(fail)?;
    let (width, height) = (reader.info().width as usize, reader.info().height as usize);
    if width.saturating_mul(height) > MAX_PIXELS {
        return Err(error(
            file,
            0,
            0,
            format!("a {width} × {height} image is too large (at most {MAX_PIXELS} pixels)"),
        ));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| error(file, 0, 0, "the PNG is too large"))?;
    let mut buffer = vec![0; size];
    let frame = reader.next_frame(&mut buffer).map_err(fail)?;
    let channels = frame.color_type.samples();
    let has_alpha = matches!(
        frame.color_type,
        png::ColorType::GrayscaleAlpha | png::ColorType::Rgba
    );
    let colours = if has_alpha { channels - 1 } else { channels };
    let mut grey = Vec::with_capacity(width * height);
    let mut opaque = Vec::with_capacity(if has_alpha { width * height } else { 0 });
    for row in buffer[..frame.buffer_size()].chunks_exact(frame.line_size) {
        for pixel in row.chunks_exact(channels).take(width) {
            let sum: usize = pixel[..colours].iter().map(|&value| value as usize).sum();
            grey.push((sum / colours) as u8);
            if has_alpha {
                opaque.push(pixel[colours] == 255);
            }
        }
    }
    Ok(Image {
        width,
        height,
        grey,
        opaque: has_alpha.then_some(opaque),
    })
}

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

#[cfg(test)]
mod tests;

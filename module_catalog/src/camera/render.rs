//! The simulated camera's picture: a pinhole camera looking along the robot's heading, over a
//! world whose walls and obstacles stand `wall_height_m` tall on a flat floor, drawn on the CPU
//! one column at a time (one ray cast per column, as in a ray-casting game engine, since the
//! world is 2-D and every wall is vertical).
//!
//! Each shape has its own colour (the boundary, walls, and each obstacle a hue of its own),
//! darkened by distance and by the angle at which the view meets its face; the floor is a
//! chequerboard of metre squares (so that motion shows when the robot turns or drives along a
//! blank wall), fading into the horizon; the sky darkens upwards.

use armor_model::world::{Point, ShapeKind, World};
use armor_module_api::types::Pose2D;

/// The optics and the scene's sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    /// Horizontal field of view; pixels are square, so the vertical one follows from the size.
    pub fov_rad: f64,
    /// How tall walls and obstacles stand.
    pub wall_height_m: f64,
    /// The lens's height above the floor.
    pub camera_height_m: f64,
    /// Nothing farther is drawn (the floor and sky go on to the horizon).
    pub max_range_m: f64,
}

impl Default for Camera {
    /// The module's defaults: 320×240, 90° wide, walls 2 m tall, the lens 0.5 m up, 100 m deep.
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            fov_rad: 90_f64.to_radians(),
            wall_height_m: 2.0,
            camera_height_m: 0.5,
            max_range_m: 100.0,
        }
    }
}

type Rgb = [f32; 3];

const SKY_HORIZON: Rgb = [200.0, 222.0, 240.0];
const SKY_ZENITH: Rgb = [70.0, 120.0, 200.0];
const FLOOR_LIGHT: Rgb = [150.0, 150.0, 135.0];
const FLOOR_DARK: Rgb = [115.0, 118.0, 100.0];
const BOUNDARY: Rgb = [205.0, 195.0, 175.0];
const WALL: Rgb = [185.0, 110.0, 80.0];
/// Distance at which a colour is half-way to the haze of the horizon.
const HAZE_HALF_M: f64 = 25.0;

/// The colour of an obstacle: hues spread round the wheel by the golden angle, so that
/// neighbouring obstacles of the file differ.
fn obstacle_colour(shape: usize) -> Rgb {
    let hue = (shape as f64 * 0.618_033_988_75).fract() * 6.0;
    let x = 1.0 - ((hue % 2.0) - 1.0).abs();
    let (r, g, b) = match hue as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    // Saturation 0.55, value 0.85.
    let channel = |c: f64| ((0.45 + 0.55 * c) * 0.85 * 255.0) as f32;
    [channel(r), channel(g), channel(b)]
}

fn mix(a: Rgb, b: Rgb, t: f32) -> Rgb {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn haze(colour: Rgb, distance_m: f64) -> Rgb {
    let t = distance_m / (distance_m + HAZE_HALF_M);
    mix(colour, SKY_HORIZON, t as f32)
}

fn put(out: &mut [u8], colour: Rgb) {
    out[0] = colour[0] as u8;
    out[1] = colour[1] as u8;
    out[2] = colour[2] as u8;
}

impl Camera {
    /// The focal length in pixels.
    pub fn focal_px(&self) -> f64 {
        f64::from(self.width) / 2.0 / (self.fov_rad / 2.0).tan()
    }

    /// The rows a wall at depth `depth_m` (along the optical axis) covers, top and bottom
    /// edges in pixels from the top of the image (fractional, not clamped).
    pub fn wall_rows(&self, depth_m: f64) -> (f64, f64) {
        let f = self.focal_px();
        let horizon = f64::from(self.height) / 2.0;
        let top = horizon + f * (self.camera_height_m - self.wall_height_m) / depth_m;
        let bottom = horizon + f * self.camera_height_m / depth_m;
        (top, bottom)
    }

    /// Draws the view from `pose` (world frame) into `rgb`: `width × height × 3` bytes, rows
    /// from the top.
    pub fn render(&self, world: &World, pose: Pose2D, rgb: &mut Vec<u8>) {
        let (width, height) = (self.width as usize, self.height as usize);
        rgb.resize(width * height * 3, 0);
        let f = self.focal_px();
        let horizon = height as f64 / 2.0;
        let eye = Point::new(pose.x_m, pose.y_m);
        // The sky and the floor's depth depend on the row only.
        let sky: Vec<Rgb> = (0..height)
            .map(|row| {
                let up = ((horizon - (row as f64 + 0.5)) / horizon).clamp(0.0, 1.0);
                mix(SKY_HORIZON, SKY_ZENITH, up.sqrt() as f32)
            })
            .collect();
        let floor_depth: Vec<f64> = (0..height)
            .map(|row| {
                let below = row as f64 + 0.5 - horizon;
                if below > 0.0 {
                    f * self.camera_height_m / below
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        for col in 0..width {
            let across = col as f64 + 0.5 - width as f64 / 2.0;
            // Left of the centre looks left: counter-clockwise of the heading.
            let offset = (-across / f).atan();
            let angle = pose.theta_rad + offset;
            let (dir_x, dir_y) = (angle.cos(), angle.sin());
            let cos_offset = offset.cos();
            let hit = world.raycast_hit(eye, angle, self.max_range_m);
            let wall = hit.map(|hit| {
                let depth = hit.distance_m * cos_offset;
                let (top, bottom) = self.wall_rows(depth);
                let base = match world.shapes()[hit.shape].kind {
                    ShapeKind::Boundary => BOUNDARY,
                    ShapeKind::Wall => WALL,
                    ShapeKind::Obstacle => obstacle_colour(hit.shape),
                };
                // A face seen square on is lit fully, one seen edge on at 55 %.
                let (a, b) = hit.edge;
                let (ex, ey) = (b.x - a.x, b.y - a.y);
                let length = ex.hypot(ey).max(1e-12);
                let facing = ((dir_x * ey - dir_y * ex) / length).abs();
                let lit = base.map(|c| c * (0.55 + 0.45 * facing) as f32);
                (top, bottom, haze(lit, hit.distance_m))
            });
            for row in 0..height {
                let centre = row as f64 + 0.5;
                let colour = match wall {
                    Some((top, bottom, colour)) if centre >= top && centre <= bottom => colour,
                    _ if centre < horizon => sky[row],
                    _ => {
                        let depth = floor_depth[row];
                        let along = depth / cos_offset;
                        let (x, y) = (eye.x + dir_x * along, eye.y + dir_y * along);
                        let square = (x.floor() as i64 + y.floor() as i64).rem_euclid(2);
                        let tile = if square == 0 { FLOOR_LIGHT } else { FLOOR_DARK };
                        haze(tile, along)
                    }
                };
                let at = (row * width + col) * 3;
                put(&mut rgb[at..at + 3], colour);
            }
        }
    }
}

/// Grey levels of an RGB picture (ITU-R BT.601 weights, in integers).
pub fn to_mono(rgb: &[u8], mono: &mut Vec<u8>) {
    mono.clear();
    mono.extend(rgb.chunks_exact(3).map(|p| {
        let y = 77 * u32::from(p[0]) + 150 * u32::from(p[1]) + 29 * u32::from(p[2]);
        (y >> 8) as u8
    }));
}

/// A JPEG file of an RGB picture, through the `image` crate's baseline encoder.
pub fn to_jpeg(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    jpeg: &mut Vec<u8>,
) -> Result<(), String> {
    use image::ImageEncoder as _;
    jpeg.clear();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut *jpeg, quality)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|err| format!("cannot encode a JPEG: {err}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROOM: &str = "\
name Room
origin 45.5 -73.6
start 5 10 0
boundary 0,0 20,0 20,20 0,20 0,0
";

    fn camera() -> Camera {
        Camera::default()
    }

    fn render(world: &str, camera: &Camera, pose: Pose2D) -> Vec<u8> {
        let world = World::parse(world, "test.world").expect("world");
        let mut rgb = Vec::new();
        camera.render(&world, pose, &mut rgb);
        assert_eq!(rgb.len(), 320 * 240 * 3);
        rgb
    }

    fn pixel(rgb: &[u8], col: usize, row: usize) -> [u8; 3] {
        let at = (row * 320 + col) * 3;
        [rgb[at], rgb[at + 1], rgb[at + 2]]
    }

    /// The rows of a column whose colour is that of its pixel at `probe_row` (a wall is one
    /// colour from top to bottom in a column), as (first, last).
    fn run_of(rgb: &[u8], col: usize, probe_row: usize) -> (usize, usize) {
        let colour = pixel(rgb, col, probe_row);
        let mut first = probe_row;
        while first > 0 && pixel(rgb, col, first - 1) == colour {
            first -= 1;
        }
        let mut last = probe_row;
        while last + 1 < 240 && pixel(rgb, col, last + 1) == colour {
            last += 1;
        }
        (first, last)
    }

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m,
            theta_rad,
        }
    }

    #[test]
    fn a_wall_straight_ahead_fills_the_centre_columns_at_its_height() {
        // The far wall is 15 m ahead; the focal length is 160 px (320 px over 90°), the lens
        // 0.5 m up and the wall 2 m tall: its top 1.5 m above the lens is 160 × 1.5 / 15 = 16
        // px above the horizon (row 120), its foot 160 × 0.5 / 15 = 5.3 px below. Pixel rows
        // whose centres lie in [104, 125.3] are wall: 104 to 124.
        let rgb = render(ROOM, &camera(), pose(5.0, 10.0, 0.0));
        for col in [150, 159, 160, 170] {
            assert_eq!(run_of(&rgb, col, 115), (104, 124), "column {col}");
        }
        let wall = pixel(&rgb, 160, 115);
        assert!(wall[0] > wall[2], "the boundary is warm grey: {wall:?}");
        let sky = pixel(&rgb, 160, 103);
        assert!(sky[2] > sky[0] + 20, "sky above the wall is blue: {sky:?}");
        let floor = pixel(&rgb, 160, 125);
        assert_ne!(floor, wall, "floor below the wall");
        assert_ne!(floor, sky);
        // The same wall from twice as near stands twice as tall (7.5 m: 32 px up, 10.7 down).
        let rgb = render(ROOM, &camera(), pose(12.5, 10.0, 0.0));
        assert_eq!(run_of(&rgb, 160, 115), (88, 130));
    }

    #[test]
    fn an_obstacle_covers_the_columns_of_its_angles_in_its_own_colour() {
        // A box 5 m ahead, from 0.5 m to 2 m left of the axis: its near face spans the angles
        // atan(0.1) and atan(0.4), columns 160 − 160 × 0.1 = 144 and 160 − 160 × 0.4 = 96.
        let world = format!("{ROOM}rect 10,10.5 11,12\n");
        let rgb = render(&world, &camera(), pose(5.0, 10.0, 0.0));
        // The box (the world's second shape) is blue, the boundary warm grey; each column's
        // shade differs with distance and angle.
        let blue = |p: [u8; 3]| i32::from(p[2]) > i32::from(p[0]) + 60;
        assert!(!blue(pixel(&rgb, 160, 115)), "the boundary behind");
        for col in 97..=143 {
            assert!(blue(pixel(&rgb, col, 110)), "column {col}");
            // 5 m away: top 160 × 1.5 / 5 = 48 px above the horizon, foot 16 px below.
            assert_eq!(run_of(&rgb, col, 110), (72, 135), "column {col}");
        }
        for col in [90, 150] {
            assert!(
                !blue(pixel(&rgb, col, 110)),
                "column {col} is beside the box"
            );
            assert_eq!(run_of(&rgb, col, 110), (104, 124), "the boundary 15 m away");
        }
        // (Columns 144 to 147 see the box's side, which faces the axis.)
        // Turned round, the camera sees the wall behind it and not the box.
        let rgb = render(&world, &camera(), pose(5.0, 10.0, std::f64::consts::PI));
        assert!((0..320).all(|col| !blue(pixel(&rgb, col, 110))));
    }

    #[test]
    fn the_centre_column_matches_a_ray_cast_from_seeded_random_poses() {
        // Poses drawn at random (seed 7) in the yard: the wall in the centre column stands as
        // tall as the distance the world's own ray cast gives says it should.
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../assets/worlds/yard.world"
        ))
        .expect("yard");
        let world = World::parse(&text, "yard.world").expect("world");
        let mut rng = crate::sim::rng::Rng::new(7, 0);
        let camera = camera();
        let bounds = world.bounds();
        let mut checked = 0;
        while checked < 40 {
            let x = bounds.min_x + rng.uniform() * bounds.width();
            let y = bounds.min_y + rng.uniform() * bounds.height();
            if !world.is_free(Point::new(x, y)) || world.collides(x, y, 0.3) {
                continue;
            }
            let theta = rng.uniform() * std::f64::consts::TAU;
            let mut rgb = Vec::new();
            camera.render(&world, pose(x, y, theta), &mut rgb);
            // Column 160's centre is 0.5 px right of the axis.
            let offset = (-0.5 / camera.focal_px()).atan();
            let distance = world.raycast(Point::new(x, y), theta + offset, 100.0);
            let (top, bottom) = camera.wall_rows(distance * offset.cos());
            let (top, bottom) = (top.max(0.0), bottom.min(239.5));
            if bottom - top < 3.0 {
                continue;
            }
            let probe = ((top + bottom) / 2.0) as usize;
            let (first, last) = run_of(&rgb, 160, probe);
            let expected_first = (top - 0.5).ceil().max(0.0) as usize;
            let expected_last = (bottom - 0.5).floor() as usize;
            assert_eq!(
                (first, last),
                (expected_first, expected_last),
                "pose ({x:.2}, {y:.2}, {theta:.2}), wall at {distance:.2} m"
            );
            checked += 1;
        }
    }

    #[test]
    fn grey_and_jpeg_forms_keep_the_picture() {
        let rgb = render(ROOM, &camera(), pose(5.0, 10.0, 0.3));
        let mut mono = Vec::new();
        to_mono(&rgb, &mut mono);
        assert_eq!(mono.len(), 320 * 240);
        let mut jpeg = Vec::new();
        to_jpeg(&rgb, 320, 240, 90, &mut jpeg).expect("jpeg");
        assert_eq!(&jpeg[..2], [0xFF, 0xD8], "a JPEG file starts with SOI");
        let decoded = image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg)
            .expect("decodes")
            .to_rgb8();
        assert_eq!(decoded.dimensions(), (320, 240));
        let error: f64 = decoded
            .as_raw()
            .iter()
            .zip(&rgb)
            .map(|(a, b)| f64::from(a.abs_diff(*b)))
            .sum::<f64>()
            / rgb.len() as f64;
        assert!(error < 4.0, "mean error {error} of a quality 90 JPEG");
    }
}

//! What the Run view takes from peers and recordings, checked before it is kept or drawn: a
//! grid, a scan or a pose comes from any node that publishes under the right name, or from any
//! file opened as a recording, so none of its sizes or numbers is taken on its word.
//!
//! The bounds ([`MAX_GRID_CELLS`], [`MAX_SCAN_RANGES`], [`MAX_PATH_POINTS`],
//! [`MAX_COORDINATE_M`], [`MAX_RECORDING_BYTES`]) are checked in
//! O(1) before anything the size of the data is allocated; what passes them is then drawn
//! without a panic whatever the values (a cell of 127, a range of NaN). A recording's times are
//! read through [`Timeline`], whose arithmetic saturates.
//!
//! This file knows nothing of egui and uses only `std` and the module API's types, so that the
//! fuzz target `studio_data` compiles it as it is (`#[path]`) without building the studio's GUI
//! stack with sanitizers.

use std::fmt;

use armor_module_api::types::{LaserScan, OccupancyGrid, Pose2D};

/// Cells of the largest grid shown: 4096 × 4096 (a 200 m square at 5 cm), 64 MiB as a picture.
pub const MAX_GRID_CELLS: u64 = 16 * 1024 * 1024;
/// Beams of the longest scan drawn: a planar laser at 0.0055° (real ones have a few thousand);
/// each is a dot painted every frame.
pub const MAX_SCAN_RANGES: usize = 65_536;
/// How far from the world's origin anything drawn may be: 10,000 km, a quarter of the Earth's
/// circumference. Beyond that, a position is a fault, and its screen coordinates would overflow.
pub const MAX_COORDINATE_M: f64 = 1e7;
/// Points of the longest path drawn (the follower's `path` output): a 5 km path at 5 cm.
pub const MAX_PATH_POINTS: usize = 100_000;

/// Bytes a recording's messages may take once read (decompressed): a file of a few megabytes can
/// hold gigabytes in compressed chunks.
pub const MAX_RECORDING_BYTES: usize = 4 * 1024 * 1024 * 1024;

/// Why a sample was not taken.
#[derive(Clone, Debug, PartialEq)]
pub enum Refused {
    /// `width × height` is zero: there is nothing to draw.
    EmptyGrid { width: u32, height: u32 },
    /// `width × height` is beyond [`MAX_GRID_CELLS`].
    GridTooLarge { width: u32, height: u32 },
    /// `width × height` is not the number of cells sent.
    GridInconsistent {
        width: u32,
        height: u32,
        cells: usize,
    },
    /// A number that must be finite (and, for a resolution, positive) is not.
    NotANumber { what: &'static str, value: f64 },
    /// A position beyond [`MAX_COORDINATE_M`].
    TooFar { what: &'static str, value: f64 },
    /// More ranges than [`MAX_SCAN_RANGES`].
    ScanTooLong { ranges: usize },
    /// More points than [`MAX_PATH_POINTS`] (counted before any is read).
    PathTooLong { points: usize },
    /// The path's `index`th point (from 1) is not `X,Y` in metres.
    PathPoint { index: usize },
}

impl fmt::Display for Refused {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refused::EmptyGrid { width, height } => {
                write!(f, "a grid of {width} × {height} cells has none to show")
            }
            Refused::GridTooLarge { width, height } => write!(
                f,
                "a grid of {width} × {height} cells is larger than the {MAX_GRID_CELLS} shown"
            ),
            Refused::GridInconsistent {
                width,
                height,
                cells,
            } => write!(
                f,
                "a grid of {width} × {height} cells came with {cells} cell values"
            ),
            Refused::NotANumber { what, value } => write!(f, "{what} is {value}"),
            Refused::TooFar { what, value } => write!(
                f,
                "{what} is {value} m, farther than {MAX_COORDINATE_M} m from the origin"
            ),
            Refused::ScanTooLong { ranges } => write!(
                f,
                "a scan of {ranges} ranges is longer than the {MAX_SCAN_RANGES} drawn"
            ),
            Refused::PathTooLong { points } => write!(
                f,
                "a path of {points} points is longer than the {MAX_PATH_POINTS} drawn"
            ),
            Refused::PathPoint { index } => {
                write!(f, "the path's point {index} is not `X,Y` in metres")
            }
        }
    }
}

fn finite(what: &'static str, value: f64) -> Result<f64, Refused> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Refused::NotANumber { what, value })
    }
}

/// A finite coordinate within [`MAX_COORDINATE_M`] of the origin.
fn coordinate(what: &'static str, value: f64) -> Result<f64, Refused> {
    if finite(what, value)?.abs() > MAX_COORDINATE_M {
        return Err(Refused::TooFar { what, value });
    }
    Ok(value)
}

/// The grid's size is within [`MAX_GRID_CELLS`] and matches its cells; its resolution is
/// positive, and its corners are within [`MAX_COORDINATE_M`].
pub fn check_grid(grid: &OccupancyGrid) -> Result<(), Refused> {
    let (width, height) = (grid.width, grid.height);
    // u32 × u32 always fits a u64; checked all the same, so that this holds if the fields grow.
    let cells = match u64::from(width).checked_mul(u64::from(height)) {
        Some(0) => return Err(Refused::EmptyGrid { width, height }),
        Some(cells) if cells <= MAX_GRID_CELLS => cells,
        _ => return Err(Refused::GridTooLarge { width, height }),
    };
    if u64::try_from(grid.cells.len()).ok() != Some(cells) {
        return Err(Refused::GridInconsistent {
            width,
            height,
            cells: grid.cells.len(),
        });
    }
    let resolution = finite("the grid's resolution", grid.resolution_m)?;
    if resolution <= 0.0 {
        return Err(Refused::NotANumber {
            what: "the grid's resolution",
            value: resolution,
        });
    }
    coordinate("the grid's origin x", grid.origin_x_m)?;
    coordinate("the grid's origin y", grid.origin_y_m)?;
    coordinate(
        "the grid's east edge",
        grid.origin_x_m + resolution * f64::from(width),
    )?;
    coordinate(
        "the grid's north edge",
        grid.origin_y_m + resolution * f64::from(height),
    )?;
    Ok(())
}

/// The scan has at most [`MAX_SCAN_RANGES`] ranges, finite angles and a maximum range that is a
/// number. Single ranges may be anything: [`scan_hits`] skips those that are no echo.
pub fn check_scan(scan: &LaserScan) -> Result<(), Refused> {
    if scan.ranges_m.len() > MAX_SCAN_RANGES {
        return Err(Refused::ScanTooLong {
            ranges: scan.ranges_m.len(),
        });
    }
    finite("the scan's first angle", scan.angle_min_rad)?;
    finite("the scan's angle increment", scan.angle_increment_rad)?;
    if scan.range_max_m.is_nan() {
        return Err(Refused::NotANumber {
            what: "the scan's maximum range",
            value: scan.range_max_m,
        });
    }
    Ok(())
}

/// The pose is within [`MAX_COORDINATE_M`] of the origin and heads somewhere.
pub fn check_pose(pose: &Pose2D) -> Result<(), Refused> {
    coordinate("the pose's x", pose.x_m)?;
    coordinate("the pose's y", pose.y_m)?;
    finite("the pose's heading", pose.theta_rad)?;
    Ok(())
}

/// A path as the follower publishes it (`X,Y X,Y …` in metres, the form of
/// `armor_model::planner::Path::format`): at most [`MAX_PATH_POINTS`] points, counted before
/// any is kept, each within [`MAX_COORDINATE_M`] of the origin. An empty text is no path.
pub fn parse_path(text: &str) -> Result<Vec<(f64, f64)>, Refused> {
    let points = text.split_whitespace().count();
    if points > MAX_PATH_POINTS {
        return Err(Refused::PathTooLong { points });
    }
    let mut path = Vec::with_capacity(points);
    for (index, pair) in text.split_whitespace().enumerate() {
        let point = pair
            .split_once(',')
            .and_then(|(x, y)| Some((x.parse::<f64>().ok()?, y.parse::<f64>().ok()?)))
            .filter(|(x, y)| {
                coordinate("the path's x", *x).is_ok() && coordinate("the path's y", *y).is_ok()
            })
            .ok_or(Refused::PathPoint { index: index + 1 })?;
        path.push(point);
    }
    Ok(path)
}

/// A grid as RGBA pixels (not premultiplied), row by row from the top (the grid's north edge).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GridPicture {
    /// Width and height in pixels.
    pub size: [usize; 2],
    /// `4 × width × height` bytes.
    pub rgba: Vec<u8>,
}

/// The pixel of a cell: unknown (any negative value) clear, free pale, occupied dark; values
/// above 100 count as 100.
fn cell_rgba(value: i8) -> [u8; 4] {
    if value < 0 {
        return [0; 4];
    }
    let occupied = f32::from(value.min(100)) / 100.0;
    let shade = (235.0 - 215.0 * occupied) as u8;
    [shade, shade, shade, 170]
}

/// The grid's picture, at most `max_side` pixels on a side (what the display can hold as one
/// texture): a larger grid is shrunk by a whole factor, each pixel showing the most occupied
/// cell of its block, so that no obstacle disappears. Checks the grid first ([`check_grid`]):
/// nothing is allocated for a grid that is refused.
pub fn grid_picture(grid: &OccupancyGrid, max_side: usize) -> Result<GridPicture, Refused> {
    check_grid(grid)?;
    // Both fit a usize: their product is at most MAX_GRID_CELLS.
    let (width, height) = (grid.width as usize, grid.height as usize);
    let step = width.max(height).div_ceil(max_side.max(1)).max(1);
    let (columns, rows) = (width.div_ceil(step), height.div_ceil(step));
    let mut rgba = Vec::with_capacity(columns * rows * 4);
    // Row 0 of the grid is its southern edge: rows are flipped for the screen.
    if step == 1 {
        for row in grid.cells.chunks_exact(width).rev() {
            for &cell in row {
                rgba.extend_from_slice(&cell_rgba(cell));
            }
        }
        return Ok(GridPicture {
            size: [columns, rows],
            rgba,
        });
    }
    for row in (0..rows).rev() {
        let grid_rows = row * step..((row + 1) * step).min(height);
        for column in 0..columns {
            let grid_columns = column * step..((column + 1) * step).min(width);
            let most = grid_rows
                .clone()
                .flat_map(|grid_row| {
                    let start = grid_row * width;
                    &grid.cells[start + grid_columns.start..start + grid_columns.end]
                })
                .copied()
                .max()
                .unwrap_or(-1);
            rgba.extend_from_slice(&cell_rgba(most));
        }
    }
    Ok(GridPicture {
        size: [columns, rows],
        rgba,
    })
}

/// Where each echo of `scan`, taken at `pose`, is in the world: beams with no echo (a range
/// that is negative, not a number, or at least the maximum) are skipped, and so is any point
/// that is not within [`MAX_COORDINATE_M`], whatever the angles.
pub fn scan_hits<'a>(
    scan: &'a LaserScan,
    pose: &'a Pose2D,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    scan.ranges_m
        .iter()
        .enumerate()
        .filter_map(move |(index, range)| {
            let range = f64::from(*range);
            if !(range >= 0.0 && range < scan.range_max_m) {
                return None;
            }
            let angle =
                pose.theta_rad + scan.angle_min_rad + scan.angle_increment_rad * index as f64;
            let (sin, cos) = angle.sin_cos();
            let hit = (pose.x_m + range * cos, pose.y_m + range * sin);
            let near = |value: f64| value.is_finite() && value.abs() <= MAX_COORDINATE_M;
            (near(hit.0) && near(hit.1)).then_some(hit)
        })
}

/// A recording's span of log times (Unix nanoseconds, as the file says them: any `u64`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timeline {
    pub first_ns: u64,
    pub last_ns: u64,
}

impl Timeline {
    /// The span of `times`, in whatever order they come; `None` for none.
    pub fn of(times: impl IntoIterator<Item = u64>) -> Option<Timeline> {
        times.into_iter().fold(None, |span, time| {
            Some(match span {
                None => Timeline {
                    first_ns: time,
                    last_ns: time,
                },
                Some(Timeline { first_ns, last_ns }) => Timeline {
                    first_ns: first_ns.min(time),
                    last_ns: last_ns.max(time),
                },
            })
        })
    }

    /// Seconds from the first message to the last (0 or more, finite).
    pub fn duration_secs(&self) -> f64 {
        self.last_ns.saturating_sub(self.first_ns) as f64 / 1e9
    }

    /// The latest log time shown `at_secs` after the first message: the first time for 0, a
    /// negative time or NaN, the last for the duration or more (even where rounding seconds to
    /// nanoseconds would fall short of it).
    pub fn until_ns(&self, at_secs: f64) -> u64 {
        if at_secs.is_nan() || at_secs <= 0.0 {
            return self.first_ns;
        }
        if at_secs >= self.duration_secs() {
            return self.last_ns;
        }
        // `as` saturates: a huge number of seconds is u64::MAX nanoseconds, never a wrap.
        let offset_ns = (at_secs * 1e9) as u64;
        self.first_ns.saturating_add(offset_ns).min(self.last_ns)
    }

    /// `at_secs` as a play head: between 0 and the duration, 0 for NaN.
    pub fn clamp_secs(&self, at_secs: f64) -> f64 {
        if at_secs.is_nan() {
            0.0
        } else {
            at_secs.clamp(0.0, self.duration_secs())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(width: u32, height: u32, cells: Vec<i8>) -> OccupancyGrid {
        OccupancyGrid {
            resolution_m: 0.5,
            width,
            height,
            origin_x_m: -1.0,
            origin_y_m: 2.0,
            cells,
        }
    }

    #[test]
    fn a_path_is_read_within_its_bounds() {
        assert_eq!(
            parse_path("0,0 2.5,-1  3,4\n"),
            Ok(vec![(0.0, 0.0), (2.5, -1.0), (3.0, 4.0)])
        );
        assert_eq!(parse_path(""), Ok(Vec::new()));
        for (text, index) in [("1,1 x", 2), ("1,NaN", 1), ("1,1e12", 1), ("1;1", 1)] {
            assert_eq!(
                parse_path(text),
                Err(Refused::PathPoint { index }),
                "{text}"
            );
        }
        let long = "0,0 ".repeat(MAX_PATH_POINTS + 1);
        assert_eq!(
            parse_path(&long),
            Err(Refused::PathTooLong {
                points: MAX_PATH_POINTS + 1
            })
        );
    }

    #[test]
    fn a_huge_grid_is_refused_before_its_picture_is_allocated() {
        // 2^64 − 2^33 + 1 cells: four bytes each would overflow any allocation, and the old
        // picture code asked for exactly that (`Vec::with_capacity(width * height)`).
        let huge = grid(u32::MAX, u32::MAX, vec![0; 4]);
        let refused = Refused::GridTooLarge {
            width: u32::MAX,
            height: u32::MAX,
        };
        assert_eq!(check_grid(&huge), Err(refused.clone()));
        assert_eq!(grid_picture(&huge, 8192), Err(refused));
        // Just over the bound, even with every cell there, is refused too.
        let over = grid(4097, 4096, vec![0; 4097 * 4096]);
        let err = grid_picture(&over, 8192).expect_err("over the bound");
        assert!(
            err.to_string().contains("4097 × 4096") && err.to_string().contains("16777216"),
            "{err}"
        );
        assert!(check_grid(&grid(4096, 4096, vec![0; 4096 * 4096])).is_ok());
    }

    #[test]
    fn a_grid_whose_size_does_not_match_its_cells_is_refused() {
        for (width, height, cells) in [(3, 3, 4), (3, 3, 10), (1, 1, 0), (2, 1, 3)] {
            let refused = grid_picture(&grid(width, height, vec![0; cells]), 64);
            assert_eq!(
                refused,
                Err(Refused::GridInconsistent {
                    width,
                    height,
                    cells
                })
            );
        }
        assert_eq!(
            check_grid(&grid(0, 5, vec![])),
            Err(Refused::EmptyGrid {
                width: 0,
                height: 5
            })
        );
    }

    #[test]
    fn a_grid_must_have_a_resolution_and_lie_near_the_origin() {
        let base = grid(2, 2, vec![0; 4]);
        assert!(check_grid(&base).is_ok());
        let with = |change: fn(&mut OccupancyGrid)| {
            let mut grid = base.clone();
            change(&mut grid);
            check_grid(&grid).expect_err("refused").to_string()
        };
        assert!(with(|g| g.resolution_m = 0.0).contains("resolution is 0"));
        assert!(with(|g| g.resolution_m = -0.5).contains("resolution is -0.5"));
        assert!(with(|g| g.resolution_m = f64::NAN).contains("resolution is NaN"));
        assert!(with(|g| g.origin_x_m = f64::INFINITY).contains("origin x is inf"));
        assert!(with(|g| g.origin_y_m = f64::NAN).contains("origin y is NaN"));
        assert!(with(|g| g.origin_y_m = -2e7).contains("farther than"));
        // Finite corners, but the far one overflows.
        assert!(with(|g| g.resolution_m = f64::MAX).contains("east edge is inf"));
    }

    #[test]
    fn the_picture_has_the_south_row_at_the_bottom() {
        let picture = grid_picture(&grid(2, 2, vec![100, 0, -1, 127]), 64).expect("shown");
        assert_eq!(picture.size, [2, 2]);
        assert_eq!(picture.rgba.len(), 16);
        let pixel = |i: usize| &picture.rgba[i * 4..i * 4 + 4];
        assert_eq!(pixel(0), [0, 0, 0, 0], "unknown, top row");
        assert_eq!(pixel(1), pixel(2), "above 100 is occupied");
        assert!(pixel(2)[0] < pixel(3)[0], "occupied darker than free");
    }

    #[test]
    fn a_grid_wider_than_a_texture_is_shrunk_keeping_obstacles() {
        // 5 × 2 cells, at most 2 pixels a side: blocks of 3 × 3 cells, 2 × 1 pixels.
        let mut cells = vec![-1; 10];
        cells[4] = 100; // row 0, column 4: in the second block
        let picture = grid_picture(&grid(5, 2, cells), 2).expect("shown");
        assert_eq!(picture.size, [2, 1]);
        assert_eq!(&picture.rgba[0..4], [0, 0, 0, 0], "all unknown");
        assert_eq!(&picture.rgba[4..8], cell_rgba(100), "the obstacle stays");
        let one_side = grid_picture(&grid(1, 4, vec![0; 4]), 0).expect("shown");
        assert_eq!(one_side.size, [1, 1], "a side of 0 counts as 1");
    }

    fn scan(ranges_m: Vec<f32>) -> LaserScan {
        LaserScan {
            angle_min_rad: 0.0,
            angle_increment_rad: std::f64::consts::FRAC_PI_2,
            range_max_m: 10.0,
            ranges_m,
        }
    }

    #[test]
    fn scans_are_bounded_and_only_echoes_are_drawn() {
        assert!(check_scan(&scan(vec![1.0; MAX_SCAN_RANGES])).is_ok());
        assert_eq!(
            check_scan(&scan(vec![1.0; MAX_SCAN_RANGES + 1])),
            Err(Refused::ScanTooLong {
                ranges: MAX_SCAN_RANGES + 1
            })
        );
        for change in [
            |s: &mut LaserScan| s.angle_increment_rad = f64::NAN,
            |s: &mut LaserScan| s.angle_min_rad = f64::NEG_INFINITY,
            |s: &mut LaserScan| s.range_max_m = f64::NAN,
        ] {
            let mut hostile = scan(vec![1.0]);
            change(&mut hostile);
            assert!(check_scan(&hostile).is_err(), "{hostile:?}");
        }
        let pose = Pose2D {
            x_m: 1.0,
            y_m: 0.0,
            theta_rad: 0.0,
        };
        let ranges = vec![2.0, f32::NAN, -1.0, 10.0, f32::INFINITY, 3e38];
        let hits: Vec<_> = scan_hits(&scan(ranges.clone()), &pose).collect();
        assert_eq!(hits, vec![(3.0, 0.0)]);
        // With no maximum, 10 m is an echo, but 3e38 m is still too far to draw.
        let mut unbounded = scan(ranges);
        unbounded.range_max_m = f64::INFINITY;
        let hits: Vec<_> = scan_hits(&unbounded, &pose).collect();
        assert_eq!(hits.len(), 2, "{hits:?}");
        assert!((hits[1].0 - 1.0).abs() < 1e-9 && (hits[1].1 + 10.0).abs() < 1e-9);
    }

    #[test]
    fn poses_must_be_finite_and_near() {
        let pose = |x_m, y_m, theta_rad| Pose2D {
            x_m,
            y_m,
            theta_rad,
        };
        assert!(check_pose(&pose(1.0, -2.0, 40.0)).is_ok());
        for hostile in [
            pose(f64::NAN, 0.0, 0.0),
            pose(0.0, f64::INFINITY, 0.0),
            pose(0.0, 0.0, f64::NAN),
            pose(1e8, 0.0, 0.0),
        ] {
            assert!(check_pose(&hostile).is_err(), "{hostile:?}");
        }
    }

    #[test]
    fn hostile_timestamps_saturate() {
        assert_eq!(Timeline::of([]), None);
        let out_of_order = Timeline::of([30, 10, u64::MAX, 0]).expect("some");
        assert_eq!(
            out_of_order,
            Timeline {
                first_ns: 0,
                last_ns: u64::MAX
            }
        );
        // first = 1, last = u64::MAX: the duration rounds up to 2^64 ns, whose sum with the
        // first would overflow; the play head stops at the last.
        let span = Timeline {
            first_ns: 1,
            last_ns: u64::MAX,
        };
        assert_eq!(span.until_ns(span.duration_secs()), u64::MAX);
        let nearly = span.until_ns(span.duration_secs() * 0.999_999);
        assert!(nearly > u64::MAX / 2 && nearly < u64::MAX, "{nearly}");
        assert_eq!(span.until_ns(f64::INFINITY), u64::MAX);
        assert_eq!(span.until_ns(f64::MAX), u64::MAX);
        assert_eq!(span.until_ns(f64::NAN), 1);
        assert_eq!(span.until_ns(-1.0), 1);
        assert_eq!(span.until_ns(f64::NEG_INFINITY), 1);
        let end = Timeline {
            first_ns: u64::MAX,
            last_ns: u64::MAX,
        };
        assert_eq!(end.duration_secs(), 0.0);
        assert_eq!(end.until_ns(5.0), u64::MAX);
        assert_eq!(end.clamp_secs(5.0), 0.0);
        assert_eq!(span.clamp_secs(f64::NAN), 0.0);
        assert_eq!(span.clamp_secs(f64::INFINITY), span.duration_secs());
        assert_eq!(span.clamp_secs(-3.0), 0.0);
        // Rounding seconds to nanoseconds never leaves the last message out at the end.
        let odd = Timeline {
            first_ns: 1_700_000_000_123_456_789,
            last_ns: 1_700_000_000_123_456_789 + (1 << 53) + 1,
        };
        assert_eq!(odd.until_ns(odd.duration_secs()), odd.last_ns);
    }
}

//! The mapper's occupancy grid: log-odds per cell, updated by ray casting, and what the scan
//! matcher needs, kept up to date cell by cell as the map changes: the mean position of the
//! echoes in each cell (walls to better than a cell), the nearest occupied cell to each cell,
//! and a likelihood field (a Gaussian of the distance to that cell's echoes).

use armor_module_api::types::{OccupancyGrid, Pose2D};

/// Log-odds added to the cell where a beam ends on an echo (p ≈ 0.7).
pub const LOG_ODDS_HIT: f32 = 0.85;
/// Log-odds added to each cell a beam crosses (p ≈ 0.4).
pub const LOG_ODDS_MISS: f32 = -0.4;
/// Log-odds are clamped to this range, so that the map can still change its mind.
pub const LOG_ODDS_MIN: f32 = -2.0;
pub const LOG_ODDS_MAX: f32 = 3.5;
/// A cell counts as occupied for the matcher above this log-odds (p > 0.5).
pub const OCCUPIED_LOG_ODDS: f32 = 0.0;
/// Standard deviation of the likelihood field around the echoes, in cells (the mapper's; a
/// localiser on a known map asks for a wider one with [`LogOddsGrid::with_field`]).
const FIELD_SIGMA_CELLS: f32 = 1.0;
/// How far the field and the nearest-echo index reach from an occupied cell, in cells (the
/// mapper's).
const REACH_CELLS: isize = 3;
/// A surface's normal is fitted to the mean echoes of the occupied cells this many cells
/// around (each way).
const NORMAL_REACH_CELLS: isize = 3;
/// A beam leaves alone the cells whose centre is this close to its echo, in cells (see
/// [`LogOddsGrid::integrate`]).
const ECHO_MARGIN_CELLS: f64 = 1.5;
/// A cell's echo sums are halved when it has this many echoes.
const MAX_ECHO_COUNT: u32 = 1024;
/// No nearest occupied cell.
const NONE: u32 = u32::MAX;
/// Grids of more cells than this are refused...
pub const MAX_CELLS: usize = MAX_SIDE_CELLS * MAX_SIDE_CELLS;
/// ... and so are grids wider or taller than this (29 bytes a cell: 464 MB at most).
pub const MAX_SIDE_CELLS: usize = 4000;

/// A square of the plane cut into cells, with the log-odds of each being occupied and the
/// matcher's view of them.
#[derive(Clone, Debug)]
pub struct LogOddsGrid {
    resolution_m: f64,
    width: usize,
    height: usize,
    origin_x_m: f64,
    origin_y_m: f64,
    log_odds: Vec<f32>,
    /// Whether a beam ever ended in or crossed the cell.
    known: Vec<bool>,
    /// The sum of the echoes that fell in each cell, in cells from its lower-left corner, and
    /// their number.
    echo_sums: Vec<[f32; 2]>,
    echo_counts: Vec<u32>,
    /// The occupied cell whose echoes' mean is nearest each cell's centre, within
    /// [`REACH_CELLS`], or [`NONE`].
    nearest: Vec<u32>,
    /// The likelihood of an echo in each cell: a Gaussian of the distance from its centre to
    /// the nearest occupied cell's mean echo, 0 when there is none within reach.
    field: Vec<f32>,
    /// The (column, row) offsets within reach of a cell.
    window: Vec<(isize, isize)>,
    /// The field's standard deviation and reach, in cells.
    field_sigma_cells: f32,
    reach_cells: isize,
    /// Which scan last touched each cell (log-odds change at most once per scan).
    touched: Vec<u32>,
    scan_id: u32,
    /// Cells that stopped being occupied during the current scan's integration.
    cleared: Vec<usize>,
    /// Occupied cells that received echoes during the current scan's integration.
    echoed: Vec<usize>,
}

impl LogOddsGrid {
    /// A grid of `width` × `height` unknown cells with its lower-left corner at the origin.
    pub fn new(
        resolution_m: f64,
        width: usize,
        height: usize,
        origin_x_m: f64,
        origin_y_m: f64,
    ) -> Result<Self, String> {
        if !(resolution_m.is_finite() && resolution_m > 0.0) {
            return Err(format!(
                "the grid resolution must be greater than 0 m, not {resolution_m}"
            ));
        }
        if width == 0 || height == 0 || width.saturating_mul(height) > MAX_CELLS {
            return Err(format!(
                "a {width} × {height} grid is refused (1 to {MAX_CELLS} cells)"
            ));
        }
        if !(origin_x_m.is_finite() && origin_y_m.is_finite()) {
            return Err(format!(
                "the grid origin must be finite, not ({origin_x_m}, {origin_y_m})"
            ));
        }
        let cells = width * height;
        Ok(Self {
            resolution_m,
            width,
            height,
            origin_x_m,
            origin_y_m,
            log_odds: vec![0.0; cells],
            known: vec![false; cells],
            echo_sums: vec![[0.0; 2]; cells],
            echo_counts: vec![0; cells],
            nearest: vec![NONE; cells],
            field: vec![0.0; cells],
            window: reach_window(REACH_CELLS),
            field_sigma_cells: FIELD_SIGMA_CELLS,
            reach_cells: REACH_CELLS,
            touched: vec![0; cells],
            scan_id: 0,
            cleared: Vec::new(),
            echoed: Vec::new(),
        })
    }

    /// A square grid of side about `size_m` centred on (`x_m`, `y_m`).
    pub fn centred(resolution_m: f64, size_m: f64, x_m: f64, y_m: f64) -> Result<Self, String> {
        if !(resolution_m.is_finite() && resolution_m > 0.0) {
            return Err(format!(
                "the grid resolution must be greater than 0 m, not {resolution_m}"
            ));
        }
        let side = (size_m / resolution_m).round();
        if !(side >= 1.0 && side * side <= MAX_CELLS as f64) {
            return Err(format!(
                "a grid of {size_m} m at {resolution_m} m is refused (1 to {MAX_CELLS} cells)"
            ));
        }
        let side = side as usize;
        let half = side as f64 * resolution_m / 2.0;
        Self::new(resolution_m, side, side, x_m - half, y_m - half)
    }

    /// The same empty grid with a likelihood field of another standard deviation and reach
    /// (in cells, at least 1): a localiser on a known map wants a field wider than the mapper's,
    /// so that a pose a few centimetres off still scores. Refused once anything is marked,
    /// since the field already computed would keep the old shape.
    pub fn with_field(mut self, sigma_cells: f32, reach_cells: isize) -> Result<Self, String> {
        if !(sigma_cells.is_finite() && sigma_cells > 0.0 && (1..=64).contains(&reach_cells)) {
            return Err(format!(
                "a likelihood field of {sigma_cells} cells reaching {reach_cells} cells is \
                 refused (more than 0 and 1 to 64 cells)"
            ));
        }
        if self.known.iter().any(|&known| known) {
            return Err("the field's shape is set before anything is marked".to_owned());
        }
        self.field_sigma_cells = sigma_cells;
        self.reach_cells = reach_cells;
        self.window = reach_window(reach_cells);
        Ok(self)
    }

    /// Marks a known map from echo positions, in metres: the cell of each echo is certainly
    /// occupied, with its echo at the mean of the echoes that fall in it, and every other cell
    /// is known and free; then brings the nearest-echo index and the field up to date, as a
    /// scan's integration does. With the echoes on a map's surfaces (not at the centres of the
    /// cells they cross) the field peaks on the surfaces themselves.
    pub fn mark_echoes(&mut self, echoes: impl IntoIterator<Item = (f64, f64)>) {
        self.known.fill(true);
        self.log_odds.fill(LOG_ODDS_MIN);
        self.echo_counts.fill(0);
        self.echo_sums.fill([0.0; 2]);
        self.cleared.clear();
        self.echoed.clear();
        for (x_m, y_m) in echoes {
            let Some((col, row)) = self.cell_of(x_m, y_m) else {
                continue;
            };
            let index = row * self.width + col;
            if self.echo_counts[index] == 0 {
                self.log_odds[index] = LOG_ODDS_MAX;
                self.echoed.push(index);
            }
            let within = [
                ((x_m - self.origin_x_m) / self.resolution_m - col as f64) as f32,
                ((y_m - self.origin_y_m) / self.resolution_m - row as f64) as f32,
            ];
            self.echo_sums[index][0] += within[0];
            self.echo_sums[index][1] += within[1];
            self.echo_counts[index] += 1;
        }
        self.refresh();
    }

    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn origin(&self) -> (f64, f64) {
        (self.origin_x_m, self.origin_y_m)
    }

    /// The likelihood field, row by row (see [`LogOddsGrid::field_at`]).
    pub fn field(&self) -> &[f32] {
        &self.field
    }

    /// The cell holding a point, if it is on the grid.
    pub fn cell_of(&self, x_m: f64, y_m: f64) -> Option<(usize, usize)> {
        let col = ((x_m - self.origin_x_m) / self.resolution_m).floor();
        let row = ((y_m - self.origin_y_m) / self.resolution_m).floor();
        (col >= 0.0 && row >= 0.0 && col < self.width as f64 && row < self.height as f64)
            .then_some((col as usize, row as usize))
    }

    pub fn log_odds(&self, col: usize, row: usize) -> Option<f32> {
        (col < self.width && row < self.height).then(|| self.log_odds[row * self.width + col])
    }

    pub fn is_known(&self, col: usize, row: usize) -> bool {
        col < self.width && row < self.height && self.known[row * self.width + col]
    }

    /// The likelihood field of a cell (0 off the grid).
    pub fn cell_field(&self, col: usize, row: usize) -> f32 {
        if col < self.width && row < self.height {
            self.field[row * self.width + col]
        } else {
            0.0
        }
    }

    /// The likelihood field at a point, interpolated bilinearly between cell centres; 0 off
    /// the grid.
    pub fn field_at(&self, x_m: f64, y_m: f64) -> f64 {
        let u = (x_m - self.origin_x_m) / self.resolution_m - 0.5;
        let v = (y_m - self.origin_y_m) / self.resolution_m - 0.5;
        if !(u >= 0.0 && v >= 0.0) {
            return 0.0;
        }
        // Truncation is the floor of a number not negative; `f64::floor` is a call into the
        // maths library on x86-64's baseline (no SSE4.1), and this runs for every beam of every
        // particle of the localiser: 60,000 times a scan, a tenth of an update (measured with
        // perf on `armor-bench localise_ms_per_scan`).
        let (u0, v0) = (u as usize, v as usize);
        if u0 >= self.width.saturating_sub(1) || v0 >= self.height.saturating_sub(1) {
            return 0.0;
        }
        let (tu, tv) = (u - u0 as f64, v - v0 as f64);
        let i = v0 * self.width + u0;
        let f = |i: usize| f64::from(self.field[i]);
        (1.0 - tv) * ((1.0 - tu) * f(i) + tu * f(i + 1))
            + tv * ((1.0 - tu) * f(i + self.width) + tu * f(i + self.width + 1))
    }

    /// The mean position of the echoes of an occupied cell, in metres.
    fn echo_mean(&self, index: usize) -> (f64, f64) {
        let [sx, sy] = self.echo_sums[index];
        let n = self.echo_counts[index].max(1) as f32;
        let (col, row) = (index % self.width, index / self.width);
        (
            self.origin_x_m + (col as f64 + f64::from(sx / n)) * self.resolution_m,
            self.origin_y_m + (row as f64 + f64::from(sy / n)) * self.resolution_m,
        )
    }

    /// The mean echo of the occupied cell nearest the point's cell (within reach), if any.
    pub fn nearest_echo(&self, x_m: f64, y_m: f64) -> Option<(usize, (f64, f64))> {
        let (col, row) = self.cell_of(x_m, y_m)?;
        let nearest = self.nearest[row * self.width + col];
        (nearest != NONE).then(|| (nearest as usize, self.echo_mean(nearest as usize)))
    }

    /// The unit normal of the surface through an occupied cell, from the mean echoes of the
    /// occupied cells around it (the direction in which they spread least); None where they do
    /// not line up (a corner, a lone cell).
    pub fn normal(&self, index: usize) -> Option<(f64, f64)> {
        let (col, row) = ((index % self.width) as isize, (index / self.width) as isize);
        let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for dr in -NORMAL_REACH_CELLS..=NORMAL_REACH_CELLS {
            for dc in -NORMAL_REACH_CELLS..=NORMAL_REACH_CELLS {
                let Some(near) = self.index(col + dc, row + dr) else {
                    continue;
                };
                if !self.is_occupied(near) {
                    continue;
                }
                let (x, y) = self.echo_mean(near);
                n += 1.0;
                sx += x;
                sy += y;
                sxx += x * x;
                sxy += x * y;
                syy += y * y;
            }
        }
        if n < 3.0 {
            return None;
        }
        let (mx, my) = (sx / n, sy / n);
        let (cxx, cxy, cyy) = (sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my);
        // Eigenvalues of the 2 × 2 covariance; the normal is the eigenvector of the smaller one.
        let half_trace = (cxx + cyy) / 2.0;
        let spread = (((cxx - cyy) / 2.0).powi(2) + cxy * cxy).sqrt();
        let (large, small) = (half_trace + spread, half_trace - spread);
        if large.is_nan() || large <= 0.0 || small > 0.1 * large {
            return None;
        }
        // Direction of the larger eigenvector (the surface), turned a quarter.
        let angle = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
        let (sin, cos) = angle.sin_cos();
        Some((-sin, cos))
    }

    /// Integrates one scan taken at `pose`: every beam clears the cells it crosses, but for
    /// those near its echo, and a beam ending on an echo adds to the echo's cell. `beams` gives
    /// each beam's angle in the sensor's frame, its length (already cut to the usable range)
    /// and whether it ends on an echo. Within one scan a cell's log-odds change once: an echo
    /// wins over a crossing.
    pub fn integrate(
        &mut self,
        pose: Pose2D,
        beams: impl Iterator<Item = (f64, f64, bool)> + Clone,
    ) {
        self.scan_id = self.scan_id.wrapping_add(1);
        if self.scan_id == 0 {
            self.touched.fill(0);
            self.scan_id = 1;
        }
        self.cleared.clear();
        self.echoed.clear();
        let (sin, cos) = pose.theta_rad.sin_cos();
        let end_of = |angle: f64, range: f64| {
            let (s, c) = angle.sin_cos();
            let (lx, ly) = (range * c, range * s);
            (
                pose.x_m + cos * lx - sin * ly,
                pose.y_m + sin * lx + cos * ly,
            )
        };
        // Echoes first, so that a neighbouring beam crossing an echo's cell leaves it alone.
        for (angle, range, echo) in beams.clone() {
            if !echo {
                continue;
            }
            let (x, y) = end_of(angle, range);
            let u = (x - self.origin_x_m) / self.resolution_m;
            let v = (y - self.origin_y_m) / self.resolution_m;
            if let Some((col, row)) = self.cell_of(x, y) {
                let index = row * self.width + col;
                let sums = &mut self.echo_sums[index];
                let count = &mut self.echo_counts[index];
                if *count >= MAX_ECHO_COUNT {
                    // Halved (exactly): the mean keeps its precision and follows a wall
                    // that moves.
                    *sums = [sums[0] / 2.0, sums[1] / 2.0];
                    *count /= 2;
                }
                sums[0] += (u - col as f64) as f32;
                sums[1] += (v - row as f64) as f32;
                *count += 1;
                if self.touched[index] != self.scan_id {
                    self.update(index, LOG_ODDS_HIT);
                    self.echoed.push(index);
                }
            }
        }
        for (angle, range, echo) in beams {
            let (x, y) = end_of(angle, range);
            self.trace_free(pose.x_m, pose.y_m, x, y, echo);
        }
        self.refresh();
    }

    /// Marks free the cells the segment from (`x0`, `y0`) to (`x1`, `y1`) crosses (a grid
    /// traversal after Amanatides and Woo). For a beam ending on an `echo`, the cells whose
    /// centre is within [`ECHO_MARGIN_CELLS`] of the echo are left alone: an echo off a wall on
    /// a cell boundary falls on either side by noise, and clearing the near side (which oblique
    /// beams cross just before their echo) would move every wall half a cell away from where
    /// it was seen from.
    fn trace_free(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, echo: bool) {
        let res = self.resolution_m;
        let (fx0, fy0) = ((x0 - self.origin_x_m) / res, (y0 - self.origin_y_m) / res);
        let (fx1, fy1) = ((x1 - self.origin_x_m) / res, (y1 - self.origin_y_m) / res);
        if !(fx0.is_finite() && fy0.is_finite() && fx1.is_finite() && fy1.is_finite()) {
            return;
        }
        let (mut col, mut row) = (fx0.floor() as i64, fy0.floor() as i64);
        let (end_col, end_row) = (fx1.floor() as i64, fy1.floor() as i64);
        let (dx, dy) = (fx1 - fx0, fy1 - fy0);
        let step_c: i64 = if dx > 0.0 { 1 } else { -1 };
        let step_r: i64 = if dy > 0.0 { 1 } else { -1 };
        // Parameter t (0 at the start, 1 at the end) of the next column and row boundaries.
        let next_boundary = |f: f64, d: f64| {
            if d > 0.0 {
                (f.floor() + 1.0 - f) / d
            } else if d < 0.0 {
                (f - f.floor()) / -d
            } else {
                f64::INFINITY
            }
        };
        let mut t_col = next_boundary(fx0, dx);
        let mut t_row = next_boundary(fy0, dy);
        let dt_col = if dx != 0.0 {
            1.0 / dx.abs()
        } else {
            f64::INFINITY
        };
        let dt_row = if dy != 0.0 {
            1.0 / dy.abs()
        } else {
            f64::INFINITY
        };
        let steps = (end_col - col).abs() + (end_row - row).abs();
        // In cells: a cell is spared if its centre is this close to the echo.
        let spared_sq = if echo {
            ECHO_MARGIN_CELLS * ECHO_MARGIN_CELLS
        } else {
            -1.0
        };
        let near_echo = |col: i64, row: i64| {
            let (cx, cy) = (col as f64 + 0.5 - fx1, row as f64 + 0.5 - fy1);
            cx * cx + cy * cy <= spared_sq
        };
        for _ in 0..steps {
            if !near_echo(col, row) {
                self.free_cell(col, row);
            }
            if t_col < t_row {
                col += step_c;
                t_col += dt_col;
            } else {
                row += step_r;
                t_row += dt_row;
            }
        }
        if !echo {
            self.free_cell(col, row);
        }
    }

    fn free_cell(&mut self, col: i64, row: i64) {
        if col >= 0 && row >= 0 && (col as usize) < self.width && (row as usize) < self.height {
            self.update(row as usize * self.width + col as usize, LOG_ODDS_MISS);
        }
    }

    /// Adds `delta` to a cell's log-odds, once per scan, and notes when it stops being
    /// occupied.
    fn update(&mut self, index: usize, delta: f32) {
        if self.touched[index] == self.scan_id {
            return;
        }
        self.touched[index] = self.scan_id;
        self.known[index] = true;
        let before = self.log_odds[index];
        let after = (before + delta).clamp(LOG_ODDS_MIN, LOG_ODDS_MAX);
        self.log_odds[index] = after;
        if before > OCCUPIED_LOG_ODDS && after <= OCCUPIED_LOG_ODDS {
            self.cleared.push(index);
            // A wall that went: if it comes back, its echoes start afresh.
            self.echo_sums[index] = [0.0; 2];
            self.echo_counts[index] = 0;
        }
    }

    fn is_occupied(&self, index: usize) -> bool {
        self.log_odds[index] > OCCUPIED_LOG_ODDS
    }

    /// The squared distance, in cells, from a cell's centre to an occupied cell's mean echo.
    fn distance_sq(&self, index: usize, occupied: usize) -> f32 {
        let [sx, sy] = self.echo_sums[occupied];
        let n = self.echo_counts[occupied].max(1) as f32;
        let dx = (occupied % self.width) as f32 + sx / n - (index % self.width) as f32 - 0.5;
        let dy = (occupied / self.width) as f32 + sy / n - (index / self.width) as f32 - 0.5;
        dx * dx + dy * dy
    }

    fn set_nearest(&mut self, index: usize, nearest: u32, distance_sq: f32) {
        self.nearest[index] = nearest;
        self.field[index] = if nearest == NONE {
            0.0
        } else {
            (-distance_sq / (2.0 * self.field_sigma_cells * self.field_sigma_cells)).exp()
        };
    }

    /// Brings the nearest-echo index and the field up to date: around cells that stopped being
    /// occupied they are recomputed; around occupied cells that got echoes (new, or with a mean
    /// that moved) those cells take over wherever they are now the nearest.
    fn refresh(&mut self) {
        let reach_sq = (self.reach_cells * self.reach_cells) as f32;
        let cleared = std::mem::take(&mut self.cleared);
        for &index in &cleared {
            if self.is_occupied(index) {
                continue;
            }
            let (col, row) = ((index % self.width) as isize, (index / self.width) as isize);
            for k in 0..self.window.len() {
                let (dc, dr) = self.window[k];
                if let Some(near) = self.index(col + dc, row + dr)
                    && self.nearest[near] != NONE
                    && self.nearest[near] as usize == index
                {
                    let (nearest, distance_sq) = self.nearest_occupied(near);
                    self.set_nearest(near, nearest, distance_sq);
                }
            }
        }
        self.cleared = cleared;
        let echoed = std::mem::take(&mut self.echoed);
        for &index in &echoed {
            if !self.is_occupied(index) {
                continue;
            }
            let (col, row) = ((index % self.width) as isize, (index / self.width) as isize);
            for k in 0..self.window.len() {
                let (dc, dr) = self.window[k];
                let Some(near) = self.index(col + dc, row + dr) else {
                    continue;
                };
                let distance_sq = self.distance_sq(near, index);
                let current = self.nearest[near];
                let closer = current == NONE
                    || current as usize == index
                    || distance_sq < self.distance_sq(near, current as usize);
                if distance_sq <= reach_sq && closer {
                    self.set_nearest(near, index as u32, distance_sq);
                } else if current as usize == index {
                    // Its mean moved out of reach: look again.
                    let (nearest, distance_sq) = self.nearest_occupied(near);
                    self.set_nearest(near, nearest, distance_sq);
                }
            }
        }
        self.echoed = echoed;
    }

    /// The occupied cell whose mean echo is nearest a cell's centre, within reach.
    fn nearest_occupied(&self, index: usize) -> (u32, f32) {
        let reach_sq = (self.reach_cells * self.reach_cells) as f32;
        let (col, row) = ((index % self.width) as isize, (index / self.width) as isize);
        let mut best = (NONE, f32::INFINITY);
        for &(dc, dr) in &self.window {
            if let Some(near) = self.index(col + dc, row + dr)
                && self.is_occupied(near)
            {
                let distance_sq = self.distance_sq(index, near);
                if distance_sq <= reach_sq && distance_sq < best.1 {
                    best = (near as u32, distance_sq);
                }
            }
        }
        best
    }

    fn index(&self, col: isize, row: isize) -> Option<usize> {
        (col >= 0 && row >= 0 && (col as usize) < self.width && (row as usize) < self.height)
            .then(|| row as usize * self.width + col as usize)
    }

    /// The map as published: -1 where no beam ever reached, else the occupancy probability in
    /// percent (0 free … 100 occupied).
    pub fn to_occupancy_grid(&self) -> OccupancyGrid {
        let cells = self
            .log_odds
            .iter()
            .zip(&self.known)
            .map(|(&l, &known)| {
                if known {
                    let p = 1.0 / (1.0 + (-l).exp());
                    (100.0 * p).round().clamp(0.0, 100.0) as i8
                } else {
                    -1
                }
            })
            .collect();
        OccupancyGrid {
            resolution_m: self.resolution_m,
            width: self.width as u32,
            height: self.height as u32,
            origin_x_m: self.origin_x_m,
            origin_y_m: self.origin_y_m,
            cells,
        }
    }
}

/// The (column, row) offsets of the cells whose centre may lie within `reach` cells of an echo
/// anywhere in the middle cell.
fn reach_window(reach: isize) -> Vec<(isize, isize)> {
    let outer = reach + 1;
    let mut window = Vec::new();
    for dr in -outer..=outer {
        for dc in -outer..=outer {
            let (near_c, near_r) = ((dc.abs() - 1).max(0), (dr.abs() - 1).max(0));
            if near_c * near_c + near_r * near_r < reach * reach {
                window.push((dc, dr));
            }
        }
    }
    window
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> LogOddsGrid {
        // 10 m × 10 m at 0.1 m, centred on (0, 0).
        LogOddsGrid::centred(0.1, 10.0, 0.0, 0.0).expect("grid")
    }

    fn at(x: f64, y: f64) -> Pose2D {
        Pose2D {
            x_m: x,
            y_m: y,
            theta_rad: 0.0,
        }
    }

    #[test]
    fn a_centred_grid_has_its_centre_on_the_point() {
        let grid = LogOddsGrid::centred(0.1, 60.0, 2.0, 9.5).expect("grid");
        assert_eq!((grid.width(), grid.height()), (600, 600));
        let (ox, oy) = grid.origin();
        assert!((ox + 28.0).abs() < 1e-9 && (oy + 20.5).abs() < 1e-9);
        assert_eq!(grid.cell_of(2.05, 9.55), Some((300, 300)));
        assert_eq!(grid.cell_of(-28.01, 0.0), None);
        assert!(LogOddsGrid::centred(0.0, 60.0, 0.0, 0.0).is_err());
        assert!(LogOddsGrid::centred(0.001, 60.0, 0.0, 0.0).is_err());
    }

    #[test]
    fn a_beam_clears_the_cells_it_crosses_and_marks_its_echo() {
        let mut grid = grid();
        // From (0.05, 0.05) east to an echo at 1.0 m: cells 50..=58 free, 60 occupied, and 59,
        // whose centre is within 1.5 cells of the echo, left alone.
        grid.integrate(at(0.05, 0.05), [(0.0, 1.0, true)].into_iter());
        let row = 50;
        for col in 50..=58 {
            assert_eq!(grid.log_odds(col, row), Some(LOG_ODDS_MISS), "col {col}");
        }
        assert!(!grid.is_known(59, row));
        assert_eq!(grid.log_odds(60, row), Some(LOG_ODDS_HIT));
        assert!(!grid.is_known(61, row) && !grid.is_known(55, row + 1));
        // A beam without an echo clears its whole length, end included.
        grid.integrate(
            at(0.05, 0.05),
            [(std::f64::consts::FRAC_PI_2, 0.5, false)].into_iter(),
        );
        for row in 50..=55 {
            assert!(
                grid.log_odds(50, row).expect("on the grid") < 0.0,
                "row {row}"
            );
        }
        assert!(!grid.is_known(50, 56));
        // A diagonal beam visits a 4-connected chain of cells.
        let mut grid = self::grid();
        grid.integrate(
            at(0.05, 0.05),
            [(std::f64::consts::FRAC_PI_4, 0.75, true)].into_iter(),
        );
        let known = (0..100)
            .flat_map(|row| (0..100).map(move |col| (col, row)))
            .filter(|&(col, row)| grid.is_known(col, row))
            .count();
        assert!((9..=11).contains(&known), "{known} cells");
    }

    #[test]
    fn log_odds_are_clamped_both_ways() {
        let mut grid = grid();
        for _ in 0..50 {
            grid.integrate(at(0.05, 0.05), [(0.0, 1.0, true)].into_iter());
        }
        assert_eq!(grid.log_odds(60, 50), Some(LOG_ODDS_MAX));
        assert_eq!(grid.log_odds(55, 50), Some(LOG_ODDS_MIN));
        // A clamped wall gives way to repeated evidence that it has gone.
        let mut cleared = 0;
        while grid.log_odds(60, 50).expect("on the grid") > 0.0 {
            grid.integrate(at(0.05, 0.05), [(0.0, 2.0, true)].into_iter());
            cleared += 1;
        }
        assert_eq!(cleared, 9, "3.5 / 0.4 rounded up");
    }

    #[test]
    fn an_echo_wins_over_a_crossing_in_the_same_scan() {
        let mut grid = grid();
        // Two beams: one ends at (1.05, 0.05), the other passes through that cell to 2 m.
        grid.integrate(
            at(0.05, 0.05),
            [(0.0, 1.0, true), (0.0, 2.0, true)].into_iter(),
        );
        assert_eq!(grid.log_odds(60, 50), Some(LOG_ODDS_HIT));
        assert_eq!(grid.log_odds(70, 50), Some(LOG_ODDS_HIT));
        assert_eq!(grid.log_odds(65, 50), Some(LOG_ODDS_MISS));
    }

    #[test]
    fn publishes_unknown_free_and_occupied_in_percent() {
        let mut grid = grid();
        grid.integrate(at(0.05, 0.05), [(0.0, 1.0, true)].into_iter());
        let map = grid.to_occupancy_grid();
        assert_eq!((map.width, map.height), (100, 100));
        assert_eq!(map.cells.len(), 10_000);
        let cell = |col: usize, row: usize| map.cells[row * 100 + col];
        assert_eq!(cell(0, 0), -1);
        assert_eq!(cell(55, 50), 40, "one miss: p = 0.40");
        assert_eq!(cell(60, 50), 70, "one hit: p = 0.70");
        for _ in 0..20 {
            grid.integrate(at(0.05, 0.05), [(0.0, 1.0, true)].into_iter());
        }
        let map = grid.to_occupancy_grid();
        let cell = |col: usize, row: usize| map.cells[row * 100 + col];
        assert_eq!(cell(60, 50), 97);
        assert_eq!(cell(55, 50), 12);
        assert!(map.cells.iter().all(|&c| (-1..=100).contains(&c)));
    }

    #[test]
    fn the_field_and_the_nearest_echo_follow_the_mean_echo() {
        let mut grid = grid();
        // Two echoes 2 and 4 cm into cell 60: their mean is 3 cm in.
        grid.integrate(at(0.05, 0.05), [(0.0, 0.97, true)].into_iter());
        grid.integrate(at(0.05, 0.05), [(0.0, 0.99, true)].into_iter());
        let (cell, (x, y)) = grid.nearest_echo(0.98, 0.05).expect("within reach");
        assert_eq!(cell, 50 * 100 + 60);
        assert!(
            (x - 1.03).abs() < 1e-6 && (y - 0.05).abs() < 1e-6,
            "{x} {y}"
        );
        // The field at cell centres is a Gaussian (σ one cell) of the distance to that mean.
        let expected = |distance_m: f64| (-(distance_m / 0.1).powi(2) / 2.0).exp();
        assert!((f64::from(grid.cell_field(60, 50)) - expected(0.02)).abs() < 1e-5);
        assert!((f64::from(grid.cell_field(58, 50)) - expected(0.18)).abs() < 1e-5);
        assert!((grid.field_at(1.05, 0.05) - expected(0.02)).abs() < 1e-5);
        assert_eq!(grid.cell_field(56, 50), 0.0, "beyond reach");
        assert_eq!(grid.nearest_echo(0.65, 0.05), None);
        // The wall goes: so do its field and its pairing, and a new wall takes over.
        while grid.log_odds(60, 50).expect("on the grid") > 0.0 {
            grid.integrate(at(0.05, 0.05), [(0.0, 1.27, true)].into_iter());
        }
        let (cell, (x, _)) = grid.nearest_echo(1.05, 0.05).expect("the new wall");
        assert_eq!(cell, 50 * 100 + 63);
        assert!((x - 1.32).abs() < 1e-6);
        assert!((f64::from(grid.cell_field(60, 50)) - expected(0.27)).abs() < 1e-5);
        assert_eq!(
            grid.nearest_echo(0.95, 0.05),
            None,
            "beyond reach of the new wall"
        );
        assert_eq!(grid.cell_field(59, 50), 0.0);
    }

    #[test]
    fn walls_have_a_normal_and_lone_echoes_none() {
        let mut grid = grid();
        // A wall along x = 1.02, seen from the origin cell's centre.
        let beams: Vec<_> = (-6..=6)
            .map(|i| {
                let (dx, dy) = (0.97, f64::from(i) * 0.05);
                (dy.atan2(dx), dx.hypot(dy), true)
            })
            .collect();
        grid.integrate(at(0.05, 0.05), beams.into_iter());
        let (cell, _) = grid.nearest_echo(1.0, 0.1).expect("the wall");
        let (nx, ny) = grid.normal(cell).expect("a straight wall");
        assert!(nx.abs() > 0.999 && ny.abs() < 0.05, "{nx} {ny}");
        grid.integrate(at(0.05, 0.05), [(2.0, 2.0, true)].into_iter());
        let lone = grid.nearest_echo(0.05 + 2.0 * 2f64.cos(), 0.05 + 2.0 * 2f64.sin());
        let (cell, _) = lone.expect("the lone echo");
        assert_eq!(grid.normal(cell), None);
    }
}

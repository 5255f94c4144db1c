//! The offline map: slippy-map tiles rendered with tiny-skia from the robot's simulated world,
//! in the look of a printed military map (paper, dark walls and obstacles, a thick boundary and
//! a labelled metric grid in the world frame).
//!
//! The studio's machines have no internet, so walkers gets its tiles from [`WorldTiles`], which
//! renders them on demand ([`render_tile`]) and keeps them as egui textures. Without a world (a
//! real robot's plan) the map shows only the metric grid around the plan's geographic origin.
//!
//! A world point goes to a tile pixel through latitude and longitude: the world's local
//! equirectangular frame first ([`LatLon::from_local`], the conversion `World::to_lat_lon` uses),
//! then web mercator. Every point is projected exactly, so that a tile and its neighbours agree
//! to the pixel, and so do tiles of the same scale from different zoom levels.

use std::collections::{BTreeSet, HashMap};
use std::f64::consts::PI;
use std::sync::{Mutex, PoisonError};

use armor_model::geo::LatLon;
use armor_model::world::{Bounds, Point, ShapeKind, World};
use egui::{ColorImage, TextureHandle, TextureOptions, pos2};
use tiny_skia::{
    Color, FillRule, LineCap, LineJoin, Paint, Path, PathBuilder, Pixmap, PremultipliedColorU8,
    Rect, Stroke, Transform,
};
use walkers::sources::Attribution;
use walkers::{Tile, TileId, TilePiece, Tiles};

/// The side of a tile, in pixels: what walkers works with internally.
const TILE_SIZE_PX: u32 = 256;
/// The deepest zoom whose tile numbers still fit walkers' `u32` (and our shifts).
const MAX_TILE_ZOOM: u8 = 31;
/// Larger pixmaps are refused: a tile is a texture, and GPUs limit their side.
const MAX_TILE_SIDE_PX: u32 = 4096;
/// Web mercator stops here; an origin further north or south cannot be drawn.
const MAX_MERCATOR_LAT_DEG: f64 = 85.051_128;

/// Rendered tiles kept as textures. A 256 px tile is 256 KiB, so this is 128 MiB at most: about
/// fifteen screens' worth, enough to pan and zoom back without rendering again.
const MAX_CACHED_TILES: usize = 512;
/// Tiles rendered in one egui pass at most; the others come in the next passes, so that a zoom
/// that uncovers a whole screen of new tiles does not stall one frame.
const MAX_RENDERS_PER_PASS: usize = 8;
/// How many zoom levels up a tile that waits for its turn looks for a cached tile to stand in.
const MAX_STAND_IN_LEVELS: u8 = 6;

/// Grid spacings, in metres, are 1, 2 or 5 times a power of ten, from 0.1 m up to this; coarser
/// grids would span more than the few kilometres over which the local frame is accurate.
const MAX_GRID_SPACING_M: f64 = 5_000.0;
/// Grid lines are at least this far apart on the tile; with 1-2-5 steps they are then at most
/// 2.5 times as far (120 px).
const MIN_GRID_CELL_PX: f64 = 48.0;
/// Every tenth grid line, counted from 0, is heavier. Labels go on every line or every second
/// one, so the heavy lines are always labelled.
const MAJOR_EVERY: i64 = 10;
/// Crossings are labelled when their lines are this far apart, else every second one is.
const MIN_LABEL_SPACING_PX: f64 = 96.0;
/// Without a world, the grid covers this much around the origin each way (a plan's area).
const GRID_HALF_EXTENT_M: f64 = 25_000.0;
/// Labels start this many pixels right of and below their crossing: clear of the boundary's
/// line (3.5 px each side at most) when the crossing is on it.
const LABEL_GAP_PX: i64 = 5;
/// The widest label the grid writes (e.g. `-12345,-12345 m`), to find crossings left of a tile
/// whose labels reach into it.
const MAX_LABEL_WIDTH_PX: f64 = 100.0;
/// Shapes are clipped to the tile grown by this margin, which is wider than half of any stroke,
/// so that the clipping edges never show while the coordinates stay small for tiny-skia's fixed
/// point arithmetic (a world a few kilometres wide is millions of pixels at zoom 26).
const CLIP_MARGIN_PX: f64 = 16.0;

/// The paper outside the world.
const PAPER: [u8; 3] = [245, 240, 225];
/// The world's free space, inside the boundary: a lighter paper.
const FREE: [u8; 3] = [253, 251, 244];
/// Walls and obstacles, and their darker outline.
const SOLID: [u8; 3] = [95, 85, 75];
const SOLID_EDGE: [u8; 3] = [50, 44, 38];
/// The boundary, the darkest line of the map.
const BOUNDARY: [u8; 3] = [40, 34, 28];
/// The grid, in a thin blue-grey; heavier and darker every tenth line.
const GRID_MINOR: [u8; 3] = [172, 184, 196];
const GRID_MAJOR: [u8; 3] = [112, 130, 150];
/// The grid's coordinates.
const LABEL_INK: [u8; 3] = [36, 48, 66];

/// What the map shows: a world, or only a metric grid around a geographic origin (a real robot's
/// plan).
///
/// Walkers asks for the tiles it draws every frame; this renders the missing ones (a few per
/// frame, see [`MAX_RENDERS_PER_PASS`]) and keeps the last [`MAX_CACHED_TILES`] as textures.
pub struct WorldTiles {
    ctx: egui::Context,
    world: Option<World>,
    /// Latitude and longitude in degrees of the world frame's (0, 0).
    origin: (f64, f64),
    attribution: &'static str,
    cache: HashMap<TileId, CachedTile>,
    /// The one texture that every tile of plain paper shows (a single pixel, stretched).
    paper: Option<TextureHandle>,
    /// Counts lookups, to find the least recently used tile.
    clock: u64,
    rendered_count: usize,
    /// The egui pass the renders below were made in.
    pass_nr: u64,
    rendered_in_pass: usize,
}

struct CachedTile {
    texture: TextureHandle,
    last_used: u64,
}

impl WorldTiles {
    /// Tiles of `world` (or of the grid alone), whose frame's (0, 0) is at `origin` (latitude,
    /// longitude in degrees; the world's own origin wins when there is a world).
    pub fn new(ctx: &egui::Context, world: Option<World>, origin: (f64, f64)) -> Self {
        WorldTiles {
            ctx: ctx.clone(),
            attribution: attribution_text(world.as_ref()),
            world,
            origin,
            cache: HashMap::new(),
            paper: None,
            clock: 0,
            rendered_count: 0,
            pass_nr: 0,
            rendered_in_pass: 0,
        }
    }

    /// Shows another world (or none), dropping every tile rendered so far.
    pub fn set_world(&mut self, world: Option<World>, origin: (f64, f64)) {
        self.attribution = attribution_text(world.as_ref());
        self.world = world;
        self.origin = origin;
        self.cache.clear();
    }

    /// How many tiles have been rendered so far. Plain paper tiles are not rendered (they share
    /// one texture), and a tile found in the cache is not rendered again.
    pub fn rendered_count(&self) -> usize {
        self.rendered_count
    }

    fn paper_texture(&mut self) -> TextureHandle {
        self.paper
            .get_or_insert_with(|| {
                let [r, g, b] = PAPER;
                let image = ColorImage::from_rgba_premultiplied([1, 1], &[r, g, b, 255]);
                self.ctx
                    .load_texture("armor-tile-paper", image, TextureOptions::LINEAR)
            })
            .clone()
    }

    /// Keeps a rendered tile as a texture, dropping the least recently used tile when the cache
    /// is full.
    fn cache_tile(&mut self, tile_id: TileId, pixmap: &Pixmap) -> TextureHandle {
        let size = [pixmap.width() as usize, pixmap.height() as usize];
        let image = ColorImage::from_rgba_premultiplied(size, pixmap.data());
        let name = format!("armor-tile-{}-{}-{}", tile_id.zoom, tile_id.x, tile_id.y);
        let texture = self.ctx.load_texture(name, image, TextureOptions::LINEAR);
        self.rendered_count += 1;
        self.rendered_in_pass += 1;
        if self.cache.len() >= MAX_CACHED_TILES
            && let Some(oldest) = self
                .cache
                .iter()
                .min_by_key(|(_, cached)| cached.last_used)
                .map(|(id, _)| *id)
        {
            self.cache.remove(&oldest);
        }
        self.cache.insert(
            tile_id,
            CachedTile {
                texture: texture.clone(),
                last_used: self.clock,
            },
        );
        texture
    }

    /// The part of a cached tile of a lower zoom that covers `tile_id`, to show while it waits
    /// for its turn (a blurred map rather than a hole).
    fn stand_in(&mut self, tile_id: TileId) -> Option<TilePiece> {
        for levels in 1..=MAX_STAND_IN_LEVELS.min(tile_id.zoom) {
            let ancestor = TileId {
                x: tile_id.x >> levels,
                y: tile_id.y >> levels,
                zoom: tile_id.zoom - levels,
            };
            if let Some(cached) = self.cache.get_mut(&ancestor) {
                cached.last_used = self.clock;
                return Some(part_of_ancestor(cached.texture.clone(), tile_id, levels));
            }
        }
        None
    }
}

/// An attribution of text alone (offline maps have no link or logo).
pub fn text_attribution(text: &'static str) -> Attribution {
    Attribution {
        text,
        url: "",
        logo_light: None,
        logo_dark: None,
    }
}

/// The part of `texture`, the tile `levels` zoom levels above `tile_id`, that covers it.
pub fn part_of_ancestor(texture: TextureHandle, tile_id: TileId, levels: u8) -> TilePiece {
    let parts = f32::from(1u16 << levels);
    let mask = (1u32 << levels) - 1;
    let (u, v) = ((tile_id.x & mask) as f32, (tile_id.y & mask) as f32);
    let uv = egui::Rect::from_min_max(
        pos2(u / parts, v / parts),
        pos2((u + 1.0) / parts, (v + 1.0) / parts),
    );
    TilePiece::new(Tile::Raster(texture), uv)
}

impl Tiles for WorldTiles {
    fn at(&mut self, tile_id: TileId) -> Option<TilePiece> {
        let whole = egui::Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        self.clock += 1;
        if let Some(cached) = self.cache.get_mut(&tile_id) {
            cached.last_used = self.clock;
            return Some(TilePiece::new(Tile::Raster(cached.texture.clone()), whole));
        }
        let scene = Scene::new(self.world.as_ref(), self.origin, tile_id, TILE_SIZE_PX)?;
        if scene.is_blank() {
            return Some(TilePiece::new(Tile::Raster(self.paper_texture()), whole));
        }
        let pass_nr = self.ctx.cumulative_pass_nr();
        if pass_nr != self.pass_nr {
            self.pass_nr = pass_nr;
            self.rendered_in_pass = 0;
        }
        if self.rendered_in_pass >= MAX_RENDERS_PER_PASS {
            self.ctx.request_repaint();
            return self.stand_in(tile_id);
        }
        let pixmap = scene.render()?;
        let texture = self.cache_tile(tile_id, &pixmap);
        Some(TilePiece::new(Tile::Raster(texture), whole))
    }

    fn attribution(&self) -> Attribution {
        text_attribution(self.attribution)
    }

    fn tile_size(&self) -> u32 {
        TILE_SIZE_PX
    }
}

/// The attribution of a world's tiles. Walkers wants a `&'static str`; each distinct text is
/// leaked once and reused, so switching worlds back and forth does not leak more.
fn attribution_text(world: Option<&World>) -> &'static str {
    static TEXTS: Mutex<BTreeSet<&'static str>> = Mutex::new(BTreeSet::new());
    let Some(world) = world else {
        return "ArMoR grid";
    };
    let text = format!("ArMoR world {}", world.name());
    let mut texts = TEXTS.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(known) = texts.get(text.as_str()) {
        return known;
    }
    let leaked: &'static str = Box::leak(text.into_boxed_str());
    texts.insert(leaked);
    leaked
}

/// Renders one web-mercator tile of `size_px` pixels: the world (if any) and the metric grid of
/// the frame whose (0, 0) is at `origin` (latitude, longitude in degrees; the world's own origin
/// wins when there is a world). `None` when the tile does not exist at its zoom or the size is 0
/// or too large for a texture.
pub fn render_tile(
    world: Option<&World>,
    origin: (f64, f64),
    tile: TileId,
    size_px: u32,
) -> Option<Pixmap> {
    Scene::new(world, origin, tile, size_px)?.render()
}

/// Where a tile lies on the web-mercator map, and how world points get onto it.
#[derive(Clone, Copy, Debug)]
struct TileFrame {
    /// The world frame's (0, 0).
    origin: LatLon,
    /// The side of the whole map at this zoom, in pixels (2^zoom tiles).
    map_px: f64,
    /// The tile's top-left corner on the whole map, in pixels (whole numbers).
    left_px: f64,
    top_px: f64,
    size_px: f64,
}

impl TileFrame {
    fn new(origin: LatLon, tile: TileId, size_px: u32) -> Self {
        let size = f64::from(size_px);
        TileFrame {
            origin,
            map_px: 2f64.powi(i32::from(tile.zoom)) * size,
            left_px: f64::from(tile.x) * size,
            top_px: f64::from(tile.y) * size,
            size_px: size,
        }
    }

    /// The tile pixel of a world point: x right, y down.
    fn to_px(self, p: Point) -> (f64, f64) {
        let at = LatLon::from_local(p, self.origin);
        let x = (at.lon_deg + 180.0) / 360.0 * self.map_px;
        let y = (1.0 - at.lat_deg.to_radians().tan().asinh() / PI) / 2.0 * self.map_px;
        (x - self.left_px, y - self.top_px)
    }

    /// The world point under a tile pixel (inverse of [`TileFrame::to_px`]).
    fn to_local(self, x_px: f64, y_px: f64) -> Point {
        let lon_deg = (self.left_px + x_px) / self.map_px * 360.0 - 180.0;
        let lat_deg = (PI * (1.0 - 2.0 * (self.top_px + y_px) / self.map_px))
            .sinh()
            .atan()
            .to_degrees();
        LatLon::new(lat_deg, lon_deg).to_local(self.origin)
    }

    /// Pixels per metre along x at the origin's latitude. Every tile of a zoom level gets the
    /// same figure, so that neighbours choose the same grid.
    fn px_per_m(self) -> f64 {
        self.to_px(Point::new(1.0, 0.0)).0 - self.to_px(Point::new(0.0, 0.0)).0
    }

    /// The part of the world frame the tile shows, in metres.
    fn area(self) -> Bounds {
        let south_west = self.to_local(0.0, self.size_px);
        let north_east = self.to_local(self.size_px, 0.0);
        Bounds {
            min_x: south_west.x,
            min_y: south_west.y,
            max_x: north_east.x,
            max_y: north_east.y,
        }
    }
}

/// The grid a zoom level shows: which lines, how far apart, which are heavier and labelled.
#[derive(Clone, Copy, Debug)]
struct GridPlan {
    spacing_m: f64,
    /// Lines x = i·spacing for i in `x_lines.0..=x_lines.1`, and the same for y.
    x_lines: (i64, i64),
    y_lines: (i64, i64),
    /// Crossings whose two indices are multiples of this are labelled.
    label_every: i64,
}

impl GridPlan {
    fn new(spacing_m: f64, px_per_m: f64, x_lines: (i64, i64), y_lines: (i64, i64)) -> Self {
        let label_every = if spacing_m * px_per_m >= MIN_LABEL_SPACING_PX {
            1
        } else {
            2
        };
        GridPlan {
            spacing_m,
            x_lines,
            y_lines,
            label_every,
        }
    }

    fn extent(&self) -> Bounds {
        let s = self.spacing_m;
        Bounds {
            min_x: self.x_lines.0 as f64 * s,
            min_y: self.y_lines.0 as f64 * s,
            max_x: self.x_lines.1 as f64 * s,
            max_y: self.y_lines.1 as f64 * s,
        }
    }
}

/// The grid spacing for a scale: the finest 1-2-5 step whose lines are at least
/// [`MIN_GRID_CELL_PX`] apart, or `None` when even [`MAX_GRID_SPACING_M`] is too fine.
fn grid_spacing_m(px_per_m: f64) -> Option<f64> {
    (-1..=4)
        .flat_map(|exponent| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(exponent)))
        .filter(|spacing_m| *spacing_m <= MAX_GRID_SPACING_M)
        .find(|spacing_m| spacing_m * px_per_m >= MIN_GRID_CELL_PX)
}

/// What one tile shows, decided before anything is drawn (so that plain paper tiles can be told
/// apart cheaply).
struct Scene<'a> {
    frame: TileFrame,
    /// The world, unless there is none or it is smaller than a pixel at this zoom.
    world: Option<&'a World>,
    grid: Option<GridPlan>,
    /// The tile's area in the world frame, in metres.
    area: Bounds,
    px_per_m: f64,
}

impl<'a> Scene<'a> {
    fn new(
        world: Option<&'a World>,
        origin: (f64, f64),
        tile: TileId,
        size_px: u32,
    ) -> Option<Scene<'a>> {
        let tiles_per_side = 1u64 << tile.zoom.min(MAX_TILE_ZOOM);
        if tile.zoom > MAX_TILE_ZOOM
            || u64::from(tile.x) >= tiles_per_side
            || u64::from(tile.y) >= tiles_per_side
            || size_px == 0
            || size_px > MAX_TILE_SIDE_PX
        {
            return None;
        }
        let (lat_deg, lon_deg) = world.map_or(origin, World::origin_lat_lon);
        let frame = TileFrame::new(LatLon::new(lat_deg, lon_deg), tile, size_px);
        let px_per_m = frame.px_per_m();
        let mut scene = Scene {
            frame,
            world: None,
            grid: None,
            area: frame.area(),
            px_per_m,
        };
        let drawable = lat_deg.abs() < MAX_MERCATOR_LAT_DEG
            && lon_deg.is_finite()
            && px_per_m.is_finite()
            && px_per_m > 0.0;
        if !drawable {
            return Some(scene);
        }
        let Some(spacing_m) = grid_spacing_m(px_per_m) else {
            return Some(scene);
        };
        let cells = |lo: f64, hi: f64| {
            (
                (lo / spacing_m).floor() as i64 - 1,
                (hi / spacing_m).ceil() as i64 + 1,
            )
        };
        match world {
            // The grid covers the world and one cell more all round, like a map sheet.
            Some(world) => {
                let bounds = world.bounds();
                if bounds.width().max(bounds.height()) * px_per_m < 1.0 {
                    return Some(scene);
                }
                scene.world = Some(world);
                scene.grid = Some(GridPlan::new(
                    spacing_m,
                    px_per_m,
                    cells(bounds.min_x, bounds.max_x),
                    cells(bounds.min_y, bounds.max_y),
                ));
            }
            None => {
                let half = (GRID_HALF_EXTENT_M / spacing_m).ceil() as i64;
                scene.grid = Some(GridPlan::new(
                    spacing_m,
                    px_per_m,
                    (-half, half),
                    (-half, half),
                ));
            }
        }
        Some(scene)
    }

    /// Whether the tile shows nothing but paper.
    fn is_blank(&self) -> bool {
        let margin_m = CLIP_MARGIN_PX / self.px_per_m;
        let meets = |b: Bounds| {
            b.min_x - margin_m <= self.area.max_x
                && b.max_x + margin_m >= self.area.min_x
                && b.min_y - margin_m <= self.area.max_y
                && b.max_y + margin_m >= self.area.min_y
        };
        !self.world.is_some_and(|world| meets(world.bounds()))
            && !self.grid.is_some_and(|grid| meets(grid.extent()))
    }

    /// Draws the tile bottom up, as a map is printed: paper, the free space, the grid, walls and
    /// obstacles over the grid (so that they stay solid), the boundary, and the labels last,
    /// over everything, so that they are never hidden.
    fn render(&self) -> Option<Pixmap> {
        let size = self.frame.size_px as u32;
        let mut pixmap = Pixmap::new(size, size)?;
        pixmap.fill(color(PAPER, 255));
        if self.is_blank() {
            return Some(pixmap);
        }
        if let Some(world) = self.world {
            self.draw_free_space(&mut pixmap, world);
        }
        if let Some(grid) = &self.grid {
            self.draw_grid_lines(&mut pixmap, grid);
        }
        if let Some(world) = self.world {
            self.draw_shapes(&mut pixmap, world);
        }
        if let Some(grid) = &self.grid {
            self.draw_labels(&mut pixmap, grid);
        }
        Some(pixmap)
    }

    /// The shape's corners in tile pixels, or `None` when it lies wholly off the tile.
    fn project(&self, points: &[Point]) -> Option<Vec<(f64, f64)>> {
        let projected: Vec<(f64, f64)> = points.iter().map(|p| self.frame.to_px(*p)).collect();
        let (lo, hi) = (-CLIP_MARGIN_PX, self.frame.size_px + CLIP_MARGIN_PX);
        let off = |axis: Axis| {
            projected.iter().all(|p| axis(p) < lo) || projected.iter().all(|p| axis(p) > hi)
        };
        let finite = projected.iter().all(|p| p.0.is_finite() && p.1.is_finite());
        (finite && !off(|p| p.0) && !off(|p| p.1)).then_some(projected)
    }

    /// The world's free space, inside its boundary, a lighter paper.
    fn draw_free_space(&self, pixmap: &mut Pixmap, world: &World) {
        let boundary = world.boundary();
        if let Some(corners) = self.project(&boundary.points) {
            let clipped = clip_polygon(
                &corners,
                -CLIP_MARGIN_PX,
                self.frame.size_px + CLIP_MARGIN_PX,
            );
            if let Some(path) = path_of(&clipped, true) {
                fill(pixmap, &path, color(FREE, 255));
            }
        }
    }

    /// The grid lines that cross the tile, cut at the grid's extent.
    fn draw_grid_lines(&self, pixmap: &mut Pixmap, grid: &GridPlan) {
        let s = grid.spacing_m;
        let size = self.frame.size_px;
        let margin_m = 4.0 / self.px_per_m;
        let visible = |lines: (i64, i64), lo_m: f64, hi_m: f64| {
            (
                lines.0.max(((lo_m - margin_m) / s).ceil() as i64),
                lines.1.min(((hi_m + margin_m) / s).floor() as i64),
            )
        };
        let extent = grid.extent();
        let (top, _) = self.y_px(extent.max_y);
        let (bottom, _) = self.y_px(extent.min_y);
        let (left, _) = self.x_px(extent.min_x);
        let (right, _) = self.x_px(extent.max_x);
        let (top, bottom) = (top.max(-4.0) as f32, bottom.min(size + 4.0) as f32);
        let (left, right) = (left.max(-4.0) as f32, right.min(size + 4.0) as f32);
        let (mut minor, mut major) = (Vec::new(), Vec::new());
        let (x0, x1) = visible(grid.x_lines, self.area.min_x, self.area.max_x);
        for i in x0..=x1 {
            let (x, _) = self.x_px(i as f64 * s);
            if i.rem_euclid(MAJOR_EVERY) == 0 {
                major.push(Rect::from_ltrb(
                    x.round() as f32 - 1.0,
                    top,
                    x.round() as f32 + 1.0,
                    bottom,
                ));
            } else {
                minor.push(Rect::from_ltrb(
                    x.floor() as f32,
                    top,
                    x.floor() as f32 + 1.0,
                    bottom,
                ));
            }
        }
        let (y0, y1) = visible(grid.y_lines, self.area.min_y, self.area.max_y);
        for j in y0..=y1 {
            let (y, _) = self.y_px(j as f64 * s);
            if j.rem_euclid(MAJOR_EVERY) == 0 {
                major.push(Rect::from_ltrb(
                    left,
                    y.round() as f32 - 1.0,
                    right,
                    y.round() as f32 + 1.0,
                ));
            } else {
                minor.push(Rect::from_ltrb(
                    left,
                    y.floor() as f32,
                    right,
                    y.floor() as f32 + 1.0,
                ));
            }
        }
        // Whole-pixel columns and rows, so that a line is crisp; filled one by one, so that
        // where two cross the pixel is not left out as an even-odd path would.
        for (rects, rgb) in [(minor, GRID_MINOR), (major, GRID_MAJOR)] {
            let paint = paint(color(rgb, 255));
            for rect in rects.into_iter().flatten() {
                pixmap.fill_rect(rect, &paint, Transform::identity(), None);
            }
        }
    }

    /// The tile column of the line x = `x_m`, and the same with the tile's left edge as a whole
    /// number on the whole map's pixels (see [`Scene::draw_labels`]).
    fn x_px(&self, x_m: f64) -> (f64, f64) {
        let (x, _) = self.frame.to_px(Point::new(x_m, 0.0));
        (x, x + self.frame.left_px)
    }

    /// The tile row of the line y = `y_m` (and on the whole map).
    fn y_px(&self, y_m: f64) -> (f64, f64) {
        let (_, y) = self.frame.to_px(Point::new(0.0, y_m));
        (y, y + self.frame.top_px)
    }

    /// Walls and obstacles filled dark with a darker outline, then the boundary as a thick line.
    fn draw_shapes(&self, pixmap: &mut Pixmap, world: &World) {
        let (lo, hi) = (-CLIP_MARGIN_PX, self.frame.size_px + CLIP_MARGIN_PX);
        let outline = Stroke {
            width: (0.03 * self.px_per_m).clamp(0.8, 2.0) as f32,
            line_join: LineJoin::Miter,
            ..Stroke::default()
        };
        let wall_width = (0.15 * self.px_per_m).clamp(1.2, 5.0);
        let wall = |width: f64| Stroke {
            width: width as f32,
            line_cap: LineCap::Square,
            line_join: LineJoin::Miter,
            ..Stroke::default()
        };
        let mut walls = Vec::new();
        for shape in world.shapes() {
            let Some(corners) = self.project(&shape.points) else {
                continue;
            };
            match shape.kind {
                ShapeKind::Boundary => {}
                ShapeKind::Obstacle => {
                    if let Some(path) = path_of(&clip_polygon(&corners, lo, hi), true) {
                        fill(pixmap, &path, color(SOLID, 255));
                        pixmap.stroke_path(
                            &path,
                            &paint(color(SOLID_EDGE, 255)),
                            &outline,
                            Transform::identity(),
                            None,
                        );
                    }
                }
                ShapeKind::Wall if shape.closed => {
                    walls.extend(path_of(&clip_polygon(&corners, lo, hi), true));
                }
                ShapeKind::Wall => {
                    walls.extend(
                        clip_polyline(&corners, lo, hi)
                            .iter()
                            .filter_map(|run| path_of(run, false)),
                    );
                }
            }
        }
        // All outlines first, so that where two walls meet neither's outline crosses the other.
        for (width, rgb) in [(wall_width + 2.0, SOLID_EDGE), (wall_width, SOLID)] {
            for path in &walls {
                pixmap.stroke_path(
                    path,
                    &paint(color(rgb, 255)),
                    &wall(width),
                    Transform::identity(),
                    None,
                );
            }
        }
        if let Some(corners) = self.project(&world.boundary().points)
            && let Some(path) = path_of(&clip_polygon(&corners, lo, hi), true)
        {
            let stroke = Stroke {
                width: (0.25 * self.px_per_m).clamp(2.0, 7.0) as f32,
                line_join: LineJoin::Miter,
                ..Stroke::default()
            };
            pixmap.stroke_path(
                &path,
                &paint(color(BOUNDARY, 255)),
                &stroke,
                Transform::identity(),
                None,
            );
        }
    }

    /// Writes the coordinates of labelled crossings, `x,y m`, just right of and below each.
    ///
    /// A label is placed from its crossing's position on the whole map's pixels, rounded down,
    /// so that every tile it overlaps draws it at the same place: a label across a tile edge is
    /// drawn half by each tile and reads whole on the map.
    fn draw_labels(&self, pixmap: &mut Pixmap, grid: &GridPlan) {
        let s = grid.spacing_m;
        let size = self.frame.size_px;
        let cell_px = s * self.px_per_m;
        let reach_cells = (MAX_LABEL_WIDTH_PX / cell_px).ceil() as i64;
        // Crossings on the extent's east or south edge would hang their label off the grid.
        let i_range = (
            grid.x_lines
                .0
                .max((self.area.min_x / s).floor() as i64 - reach_cells),
            (grid.x_lines.1 - 1).min((self.area.max_x / s).ceil() as i64),
        );
        let j_range = (
            (grid.y_lines.0 + 1).max((self.area.min_y / s).floor() as i64),
            grid.y_lines.1.min((self.area.max_y / s).ceil() as i64 + 1),
        );
        let mut lettering = Lettering::new(size as usize);
        for i in i_range.0..=i_range.1 {
            if i.rem_euclid(grid.label_every) != 0 {
                continue;
            }
            let (_, map_x) = self.x_px(i as f64 * s);
            let left = (map_x.floor() - self.frame.left_px) as i64 + LABEL_GAP_PX;
            for j in j_range.0..=j_range.1 {
                if j.rem_euclid(grid.label_every) != 0 {
                    continue;
                }
                let (_, map_y) = self.y_px(j as f64 * s);
                let top = (map_y.floor() - self.frame.top_px) as i64 + LABEL_GAP_PX;
                let text = format!(
                    "{},{} m",
                    format_metres(i as f64 * s),
                    format_metres(j as f64 * s)
                );
                lettering.write(left, top, &text);
            }
        }
        lettering.apply(pixmap);
    }
}

/// A coordinate for a label: whole metres when it is one, else to the decimetre (the finest
/// grid is 0.1 m); never `-0`.
fn format_metres(value_m: f64) -> String {
    let tenths = (value_m * 10.0).round() as i64;
    let sign = if tenths < 0 { "-" } else { "" };
    let (whole, tenth) = (tenths.abs() / 10, tenths.abs() % 10);
    if tenth == 0 {
        format!("{sign}{whole}")
    } else {
        format!("{sign}{whole}.{tenth}")
    }
}

/// A glyph of the labels' 5×7 bitmap font: its width in dots and its rows, top first, the
/// leftmost dot in the highest of `width` bits. tiny-skia draws no text, and the labels need
/// only these characters.
#[rustfmt::skip]
fn glyph(c: char) -> Option<(u8, [u8; 7])> {
    Some(match c {
        '0' => (5, [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110]),
        '1' => (5, [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
        '2' => (5, [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111]),
        '3' => (5, [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110]),
        '4' => (5, [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010]),
        '5' => (5, [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110]),
        '6' => (5, [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110]),
        '7' => (5, [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000]),
        '8' => (5, [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110]),
        '9' => (5, [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100]),
        '-' => (3, [0b000, 0b000, 0b000, 0b111, 0b000, 0b000, 0b000]),
        '.' => (2, [0b00, 0b00, 0b00, 0b00, 0b00, 0b11, 0b11]),
        ',' => (2, [0b00, 0b00, 0b00, 0b00, 0b11, 0b01, 0b10]),
        'm' => (5, [0b00000, 0b00000, 0b11010, 0b10101, 0b10101, 0b10101, 0b10101]),
        ' ' => (1, [0; 7]),
        _ => return None,
    })
}

/// The labels of a tile, as the pixels their glyphs cover. The glyphs' dots are whole pixels,
/// so they are set directly rather than drawn as paths (which took most of a tile's time).
struct Lettering {
    size: usize,
    /// The dots, and a one-pixel border round each, which keeps a label readable over grid
    /// lines and walls.
    ink: Vec<bool>,
    halo: Vec<bool>,
    written: bool,
}

impl Lettering {
    fn new(size: usize) -> Self {
        Lettering {
            size,
            ink: vec![false; size * size],
            halo: vec![false; size * size],
            written: false,
        }
    }

    /// Writes `text` with its top-left corner at tile pixel (`left`, `top`), one blank column
    /// between glyphs; what falls off the tile is dropped.
    fn write(&mut self, left: i64, top: i64, text: &str) {
        let mut x = left;
        for (width, rows) in text.chars().filter_map(glyph) {
            for (row, bits) in (0..).zip(rows) {
                for column in 0..width {
                    if bits & (1 << (width - 1 - column)) != 0 {
                        self.dot(x + i64::from(column), top + row);
                    }
                }
            }
            x += i64::from(width) + 1;
        }
    }

    fn dot(&mut self, x: i64, y: i64) {
        let index = |x: i64, y: i64| {
            let inside = (0..self.size as i64).contains(&x) && (0..self.size as i64).contains(&y);
            inside.then(|| y as usize * self.size + x as usize)
        };
        for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
            if let Some(at) = index(x + dx, y + dy) {
                self.halo[at] = true;
                self.written = true;
            }
        }
        if let Some(at) = index(x, y) {
            self.ink[at] = true;
        }
    }

    /// Puts the labels on the (opaque) tile: the halo as a veil of the free space's colour, the
    /// dots in ink.
    fn apply(&self, pixmap: &mut Pixmap) {
        if !self.written {
            return;
        }
        const HALO_ALPHA: u16 = 230;
        let mix = |under: u8, over: u8| {
            ((u16::from(over) * HALO_ALPHA + u16::from(under) * (255 - HALO_ALPHA) + 127) / 255)
                as u8
        };
        let [r, g, b] = LABEL_INK;
        let ink = PremultipliedColorU8::from_rgba(r, g, b, 255);
        for ((pixel, inked), veiled) in pixmap
            .pixels_mut()
            .iter_mut()
            .zip(&self.ink)
            .zip(&self.halo)
        {
            if *inked {
                if let Some(ink) = ink {
                    *pixel = ink;
                }
            } else if *veiled {
                let [r, g, b] = FREE;
                let veil = PremultipliedColorU8::from_rgba(
                    mix(pixel.red(), r),
                    mix(pixel.green(), g),
                    mix(pixel.blue(), b),
                    255,
                );
                if let Some(veil) = veil {
                    *pixel = veil;
                }
            }
        }
    }
}

fn color([r, g, b]: [u8; 3], alpha: u8) -> Color {
    Color::from_rgba8(r, g, b, alpha)
}

fn paint(color: Color) -> Paint<'static> {
    let mut paint = Paint::default();
    paint.set_color(color);
    paint.anti_alias = true;
    paint
}

/// Fills a path, skipping one too thin to cover anything (tiny-skia would log a warning).
fn fill(pixmap: &mut Pixmap, path: &Path, color: Color) {
    let bounds = path.bounds();
    if bounds.width() > 1e-3 && bounds.height() > 1e-3 {
        pixmap.fill_path(
            path,
            &paint(color),
            FillRule::EvenOdd,
            Transform::identity(),
            None,
        );
    }
}

fn path_of(points: &[(f64, f64)], closed: bool) -> Option<Path> {
    let (first, rest) = points.split_first()?;
    let mut builder = PathBuilder::new();
    builder.move_to(first.0 as f32, first.1 as f32);
    for p in rest {
        builder.line_to(p.0 as f32, p.1 as f32);
    }
    if closed {
        builder.close();
    }
    builder.finish()
}

/// A coordinate of a tile pixel: its x or its y.
type Axis = fn(&(f64, f64)) -> f64;

/// Clips a closed polygon to the square `lo..=hi` on both axes (Sutherland–Hodgman). A concave
/// polygon may come out with edges along the square's sides; they lie in the margin, off the
/// tile.
fn clip_polygon(points: &[(f64, f64)], lo: f64, hi: f64) -> Vec<(f64, f64)> {
    let mut out = points.to_vec();
    let sides: [(Axis, f64, bool); 4] = [
        (|p| p.0, lo, true),
        (|p| p.0, hi, false),
        (|p| p.1, lo, true),
        (|p| p.1, hi, false),
    ];
    for (axis, bound, keep_above) in sides {
        let input = std::mem::take(&mut out);
        let Some(&last) = input.last() else {
            break;
        };
        let inside = |p: &(f64, f64)| {
            if keep_above {
                axis(p) >= bound
            } else {
                axis(p) <= bound
            }
        };
        let crossing = |a: (f64, f64), b: (f64, f64)| {
            let t = (bound - axis(&a)) / (axis(&b) - axis(&a));
            (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
        };
        let mut previous = last;
        for &current in &input {
            match (inside(&previous), inside(&current)) {
                (true, true) => out.push(current),
                (true, false) => out.push(crossing(previous, current)),
                (false, true) => {
                    out.push(crossing(previous, current));
                    out.push(current);
                }
                (false, false) => {}
            }
            previous = current;
        }
    }
    out
}

/// Clips an open polyline to the square `lo..=hi` on both axes, into the runs that stay inside
/// (Liang–Barsky on each segment; a run goes on while its segments join inside the square).
fn clip_polyline(points: &[(f64, f64)], lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run: Vec<(f64, f64)> = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let Some((t0, t1)) = clip_segment(a, b, lo, hi) else {
            if !run.is_empty() {
                runs.push(std::mem::take(&mut run));
            }
            continue;
        };
        let at = |t: f64| (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        if t0 > 0.0 && !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
        if run.is_empty() {
            run.push(at(t0));
        }
        run.push(at(t1));
        if t1 < 1.0 {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

/// The part `t0..=t1` of segment `a`–`b` inside the square `lo..=hi`, if any.
fn clip_segment(a: (f64, f64), b: (f64, f64), lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let mut t0: f64 = 0.0;
    let mut t1: f64 = 1.0;
    for (p, q) in [
        (-dx, a.0 - lo),
        (dx, hi - a.0),
        (-dy, a.1 - lo),
        (dy, hi - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use std::path::Path;

    const YARD_ORIGIN: (f64, f64) = (43.5615, 1.469);

    fn world(file: &str) -> World {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/worlds")
            .join(file);
        World::parse(&std::fs::read_to_string(path).unwrap(), file).unwrap()
    }

    /// The 256 px tile at `zoom` under a point of the frame whose (0, 0) is `origin`, and the
    /// pixel of the tile, found with walkers' own projection rather than ours.
    fn locate(origin: (f64, f64), p: Point, zoom: u8) -> (TileId, (u32, u32)) {
        let at = LatLon::from_local(p, LatLon::new(origin.0, origin.1));
        let map =
            walkers::mercator::project(walkers::lat_lon(at.lat_deg, at.lon_deg), f64::from(zoom));
        let tile = TileId {
            x: (map.x() / 256.0) as u32,
            y: (map.y() / 256.0) as u32,
            zoom,
        };
        (tile, ((map.x() % 256.0) as u32, (map.y() % 256.0) as u32))
    }

    /// The colour of the pixel under a world point, rendered at `zoom`.
    fn colour_at(world: Option<&World>, origin: (f64, f64), p: Point, zoom: u8) -> [u8; 3] {
        let (tile, pixel) = locate(origin, p, zoom);
        rgb(&render_tile(world, origin, tile, 256).unwrap(), pixel)
    }

    fn rgb(pixmap: &Pixmap, (x, y): (u32, u32)) -> [u8; 3] {
        let c = pixmap.pixel(x, y).unwrap();
        [c.red(), c.green(), c.blue()]
    }

    fn is_dark(c: [u8; 3]) -> bool {
        c.iter().map(|v| u32::from(*v)).sum::<u32>() < 3 * 130
    }

    fn px_per_m(origin: (f64, f64), zoom: u8) -> f64 {
        let tile = TileId { x: 0, y: 0, zoom };
        TileFrame::new(LatLon::new(origin.0, origin.1), tile, 256).px_per_m()
    }

    #[test]
    fn walls_and_obstacles_are_dark_where_they_project_and_free_space_is_light() {
        let yard = world("yard.world");
        let at = |x, y| colour_at(Some(&yard), YARD_ORIGIN, Point::new(x, y), 22);
        for (x, y, what) in [
            (34.0, 10.0, "the low wall"),
            (24.0, 9.2, "the container"),
            (6.0, 22.0, "the shed"),
            (25.0, 22.0, "a tree"),
            (0.0, 10.5, "the boundary"),
        ] {
            assert!(is_dark(at(x, y)), "{what} at ({x}, {y}): {:?}", at(x, y));
        }
        assert_eq!(at(31.3, 11.3), FREE, "free space inside the boundary");
        assert_eq!(at(34.7, 10.3), FREE, "beside the wall");
        assert_eq!(at(-3.3, 10.7), PAPER, "outside the boundary");

        // A wall along y = 11 lands on its row: the mercator y is right.
        let building = world("building.world");
        let origin = building.origin_lat_lon();
        let at = |x, y| colour_at(Some(&building), origin, Point::new(x, y), 22);
        assert!(is_dark(at(1.3, 11.0)));
        assert_eq!(at(1.3, 11.3), FREE);
        assert_eq!(at(1.3, 10.7), FREE);
    }

    #[test]
    fn tiles_away_from_the_world_are_plain_paper() {
        let yard = world("yard.world");
        let plain = |world: Option<&World>, p: Point, zoom: u8| {
            let (tile, _) = locate(YARD_ORIGIN, p, zoom);
            let pixmap = render_tile(world, YARD_ORIGIN, tile, 256).unwrap();
            (0..256).all(|y| (0..256).all(|x| rgb(&pixmap, (x, y)) == PAPER))
        };
        assert!(
            plain(Some(&yard), Point::new(2_000.0, 500.0), 22),
            "far away"
        );
        assert!(
            plain(Some(&yard), Point::new(20.0, 15.0), 3),
            "smaller than a pixel"
        );
        assert!(
            !plain(Some(&yard), Point::new(20.0, 15.0), 15),
            "a few pixels"
        );
        assert!(
            !plain(None, Point::new(2_000.0, 500.0), 22),
            "the grid alone"
        );
        assert!(
            plain(None, Point::new(30_000.0, 0.0), 16),
            "beyond the grid"
        );
        let (tile, _) = locate(YARD_ORIGIN, Point::new(2_000.0, 500.0), 22);
        assert!(
            Scene::new(Some(&yard), YARD_ORIGIN, tile, 256)
                .unwrap()
                .is_blank()
        );
        let no_such_tile = TileId {
            x: 4,
            y: 0,
            zoom: 2,
        };
        assert!(render_tile(Some(&yard), YARD_ORIGIN, no_such_tile, 256).is_none());
    }

    #[test]
    fn grid_spacing_grows_as_zoom_shrinks() {
        let mut previous = 0.0;
        for zoom in (12..=26).rev() {
            let ppm = px_per_m(YARD_ORIGIN, zoom);
            let spacing_m = grid_spacing_m(ppm).unwrap();
            let cell_px = spacing_m * ppm;
            assert!(
                (48.0..=128.0).contains(&cell_px),
                "zoom {zoom}: {cell_px} px"
            );
            assert!(spacing_m >= previous, "zoom {zoom}: {spacing_m} m");
            previous = spacing_m;
        }
        assert_eq!(grid_spacing_m(px_per_m(YARD_ORIGIN, 22)), Some(2.0));
        assert_eq!(grid_spacing_m(px_per_m(YARD_ORIGIN, 19)), Some(20.0));
        assert_eq!(grid_spacing_m(px_per_m(YARD_ORIGIN, 8)), None, "too coarse");
    }

    #[test]
    fn grid_lines_fall_where_their_metres_project() {
        let zoom = 20;
        let spacing_m = grid_spacing_m(px_per_m(YARD_ORIGIN, zoom)).unwrap();
        // One minor and one major line of each direction, in a tile of the grid alone.
        for (k, colour) in [(3.0, GRID_MINOR), (10.0, GRID_MAJOR)] {
            let line_m = k * spacing_m;
            let (tile, (column, _)) =
                locate(YARD_ORIGIN, Point::new(line_m, 0.5 * spacing_m), zoom);
            let pixmap = render_tile(None, YARD_ORIGIN, tile, 256).unwrap();
            let count = |column: u32| {
                (0..256)
                    .filter(|y| rgb(&pixmap, (column, *y)) == colour)
                    .count()
            };
            assert!(count(column) > 200, "x = {line_m} m: {}", count(column));
            assert!(count(column + 5) < 10, "beside x = {line_m} m");
            let (tile, (_, row)) = locate(YARD_ORIGIN, Point::new(0.5 * spacing_m, line_m), zoom);
            let pixmap = render_tile(None, YARD_ORIGIN, tile, 256).unwrap();
            let count = |row: u32| {
                (0..256)
                    .filter(|x| rgb(&pixmap, (*x, row)) == colour)
                    .count()
            };
            assert!(count(row) > 200, "y = {line_m} m: {}", count(row));
            assert!(count(row + 5) < 10, "beside y = {line_m} m");
        }
    }

    #[test]
    fn labels_write_the_coordinates_right_of_and_below_a_crossing() {
        // An origin at pixel (100, 100) of a tile, so that its label "0,0 m" lies inside it.
        let (zoom, tile) = (
            20,
            TileId {
                x: 530_000,
                y: 380_000,
                zoom: 20,
            },
        );
        let (lat, lon) = lat_lon_of(tile, (100.5, 100.5));
        let pixmap = render_tile(None, (lat, lon), tile, 256).unwrap();
        assert_eq!(
            locate((lat, lon), Point::new(0.0, 0.0), zoom),
            (tile, (100, 100))
        );
        let (left, top) = (100 + LABEL_GAP_PX as u32, 100 + LABEL_GAP_PX as u32);
        let mut x = left;
        for c in "0,0 m".chars() {
            let (width, rows) = glyph(c).unwrap();
            for (row, bits) in rows.iter().enumerate() {
                for column in 0..u32::from(width) {
                    let inked = bits & (1 << (u32::from(width) - 1 - column)) != 0;
                    let pixel = rgb(&pixmap, (x + column, top + row as u32));
                    assert_eq!(
                        pixel == LABEL_INK,
                        inked,
                        "{c:?} at ({column}, {row}): {pixel:?}"
                    );
                }
            }
            x += u32::from(width) + 1;
        }
        // Nothing is written in the crossing's other corners.
        for (x0, y0) in [(80, 80), (104, 80), (80, 104)] {
            let ink = (x0..x0 + 16)
                .flat_map(|x| (y0..y0 + 16).map(move |y| (x, y)))
                .filter(|p| rgb(&pixmap, *p) == LABEL_INK)
                .count();
            assert_eq!(ink, 0, "corner at ({x0}, {y0})");
        }
    }

    /// The latitude and longitude of a pixel of a tile.
    fn lat_lon_of(tile: TileId, (x, y): (f64, f64)) -> (f64, f64) {
        let map_px = 2f64.powi(i32::from(tile.zoom)) * 256.0;
        let (x, y) = (f64::from(tile.x) * 256.0 + x, f64::from(tile.y) * 256.0 + y);
        let lat = (PI * (1.0 - 2.0 * y / map_px)).sinh().atan().to_degrees();
        (lat, x / map_px * 360.0 - 180.0)
    }

    /// The largest difference of a colour between a 512 px tile and the four 256 px tiles of
    /// the next zoom that it covers, which have the same scale.
    fn seam_difference(world: Option<&World>, origin: (f64, f64), big: TileId) -> u8 {
        let whole = render_tile(world, origin, big, 512).unwrap();
        let mut worst = 0;
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let tile = TileId {
                x: big.x * 2 + dx,
                y: big.y * 2 + dy,
                zoom: big.zoom + 1,
            };
            let part = render_tile(world, origin, tile, 256).unwrap();
            for (x, y) in (0..256).flat_map(|y| (0..256).map(move |x| (x, y))) {
                let (a, b) = (
                    rgb(&part, (x, y)),
                    rgb(&whole, (x + 256 * dx, y + 256 * dy)),
                );
                for (a, b) in a.iter().zip(b) {
                    worst = worst.max(a.abs_diff(b));
                }
            }
        }
        worst
    }

    #[test]
    fn neighbouring_tiles_join_without_seams() {
        // The yard's walls, obstacles, boundary, lines and labels.
        let yard = world("yard.world");
        let (centre, _) = locate(YARD_ORIGIN, Point::new(20.0, 15.0), 21);
        for (bx, by) in (0..3).flat_map(|by| (0..3).map(move |bx| (bx, by))) {
            let big = TileId {
                x: centre.x + bx - 1,
                y: centre.y + by - 1,
                zoom: 21,
            };
            let worst = seam_difference(Some(&yard), YARD_ORIGIN, big);
            assert!(worst <= 2, "{big:?} differs by up to {worst}");
        }
        // A label across a tile edge: the origin 10 px left of one, so "0,0 m" starts 5 px
        // before it and ends on the next tile.
        let big = TileId {
            x: 1_060_000,
            y: 760_000,
            zoom: 21,
        };
        let small = TileId {
            x: big.x * 2 + 1,
            y: big.y * 2,
            zoom: 22,
        };
        let origin = lat_lon_of(small, (-9.5, 100.5));
        let whole = render_tile(None, origin, big, 512).unwrap();
        let inked = |xs: std::ops::Range<u32>| {
            xs.flat_map(|x| (105..112).map(move |y| (x, y)))
                .any(|p| rgb(&whole, p) == LABEL_INK)
        };
        assert!(
            inked(251..256) && inked(256..270),
            "the label crosses the edge"
        );
        assert_eq!(seam_difference(None, origin, big), 0);
    }

    /// The tiles over the yard at zoom 22, all of them drawn (none plain paper).
    fn yard_tiles() -> Vec<TileId> {
        let (centre, _) = locate(YARD_ORIGIN, Point::new(20.0, 15.0), 22);
        (0..5)
            .flat_map(|dy| (0..5).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| TileId {
                x: centre.x + dx - 2,
                y: centre.y + dy - 2,
                zoom: 22,
            })
            .collect()
    }

    #[test]
    fn rendered_tiles_are_cached_until_the_world_changes() {
        let ctx = egui::Context::default();
        let mut tiles = WorldTiles::new(&ctx, Some(world("yard.world")), YARD_ORIGIN);
        assert_eq!(tiles.attribution().text, "ArMoR world Open yard");
        assert_eq!(tiles.tile_size(), 256);
        let tile = yard_tiles()[12];
        assert!(tiles.at(tile).is_some());
        assert_eq!(tiles.rendered_count(), 1);
        assert!(tiles.at(tile).is_some());
        assert_eq!(
            tiles.rendered_count(),
            1,
            "the second time comes from the cache"
        );
        // Plain paper is not rendered.
        let (far, _) = locate(YARD_ORIGIN, Point::new(2_000.0, 0.0), 22);
        assert!(tiles.at(far).is_some());
        assert_eq!(tiles.rendered_count(), 1);
        tiles.set_world(None, YARD_ORIGIN);
        assert_eq!(tiles.attribution().text, "ArMoR grid");
        assert!(tiles.at(tile).is_some());
        assert_eq!(tiles.rendered_count(), 2, "a new world renders again");
    }

    /// Runs an egui pass, as a frame would, dropping the textures it would have uploaded.
    fn next_pass(ctx: &egui::Context) {
        let mut output = ctx.run_ui(egui::RawInput::default(), |_| {});
        output.textures_delta.clear();
    }

    #[test]
    fn a_pass_renders_a_few_tiles_and_the_rest_come_next() {
        let ctx = egui::Context::default();
        let mut tiles = WorldTiles::new(&ctx, Some(world("yard.world")), YARD_ORIGIN);
        let ids = yard_tiles();
        let shown = ids.iter().filter(|id| tiles.at(**id).is_some()).count();
        assert_eq!(
            (shown, tiles.rendered_count()),
            (MAX_RENDERS_PER_PASS, MAX_RENDERS_PER_PASS)
        );
        next_pass(&ctx);
        let shown = ids.iter().filter(|id| tiles.at(**id).is_some()).count();
        assert_eq!(shown, 2 * MAX_RENDERS_PER_PASS);
        assert_eq!(tiles.rendered_count(), 2 * MAX_RENDERS_PER_PASS);

        // A tile that waits for its turn shows its part of a cached tile of a lower zoom.
        next_pass(&ctx);
        let child = ids[24];
        let parent = TileId {
            x: child.x / 2,
            y: child.y / 2,
            zoom: 21,
        };
        assert!(tiles.at(parent).is_some());
        for id in &ids[17..24] {
            assert!(tiles.at(*id).is_some());
        }
        let rendered = tiles.rendered_count();
        let piece = tiles.at(child).unwrap();
        assert_eq!(tiles.rendered_count(), rendered, "over the budget");
        let (u, v) = (child.x % 2, child.y % 2);
        let quarter =
            egui::Rect::from_min_size(pos2(u as f32 * 0.5, v as f32 * 0.5), egui::vec2(0.5, 0.5));
        assert_eq!(piece.uv, quarter);
        assert!(tiles.at(ids[16]).is_none(), "no cached tile above it");
    }
}

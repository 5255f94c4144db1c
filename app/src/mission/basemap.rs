//! A base map under the plan: the tiles of an MBTiles file or a tile folder
//! ([`armor_runtime::basemap`]) decoded and kept as egui textures, for walkers. Past the map's
//! deepest zoom, a tile is the part of its deepest ancestor that covers it, enlarged, so the
//! map stays under the plan however far one zooms in.

use std::collections::HashMap;

use armor_runtime::basemap::Basemap;
use egui::{ColorImage, TextureHandle, TextureOptions};
use walkers::sources::Attribution;
use walkers::{TileId, TilePiece, Tiles};

/// Decoded tiles kept as textures (256 KiB each).
const MAX_CACHED_TILES: usize = 512;
/// How many levels above the map's deepest one a tile is still drawn, enlarged.
const MAX_OVERZOOM_LEVELS: u8 = 10;

pub struct BaseTiles {
    ctx: egui::Context,
    map: Basemap,
    attribution: &'static str,
    /// Textures by tile, `None` for a tile the map does not have.
    cache: HashMap<TileId, Option<TextureHandle>>,
}

impl BaseTiles {
    pub fn new(ctx: &egui::Context, map: Basemap) -> BaseTiles {
        let text = if map.attribution.is_empty() {
            format!("base map: {}", map.name)
        } else {
            map.attribution.clone()
        };
        BaseTiles {
            ctx: ctx.clone(),
            // Walkers wants a `&'static str`; a base map is opened when a plan is.
            attribution: Box::leak(text.into_boxed_str()),
            map,
            cache: HashMap::new(),
        }
    }

    pub fn name(&self) -> &str {
        &self.map.name
    }

    /// The tile's pixels, when the map has it and it decodes.
    pub fn image(&self, tile_id: TileId) -> Option<ColorImage> {
        let bytes = match self.map.tile(tile_id.zoom, tile_id.x, tile_id.y) {
            Ok(bytes) => bytes?,
            Err(err) => {
                tracing::warn!("base map: {err}");
                return None;
            }
        };
        let decoded = image::load_from_memory(&bytes)
            .map_err(|err| {
                tracing::warn!(
                    "base map tile {}/{}/{} does not decode: {err}",
                    tile_id.zoom,
                    tile_id.x,
                    tile_id.y
                );
            })
            .ok()?
            .to_rgba8();
        let size = [decoded.width() as usize, decoded.height() as usize];
        Some(ColorImage::from_rgba_unmultiplied(size, decoded.as_raw()))
    }

    fn texture(&mut self, tile_id: TileId) -> Option<TextureHandle> {
        if let Some(cached) = self.cache.get(&tile_id) {
            return cached.clone();
        }
        if self.cache.len() >= MAX_CACHED_TILES {
            self.cache.clear();
        }
        let texture = self.image(tile_id).map(|image| {
            let name = format!("armor-base-{}-{}-{}", tile_id.zoom, tile_id.x, tile_id.y);
            self.ctx.load_texture(name, image, TextureOptions::LINEAR)
        });
        self.cache.insert(tile_id, texture.clone());
        texture
    }
}

impl Tiles for BaseTiles {
    fn at(&mut self, tile_id: TileId) -> Option<TilePiece> {
        let deepest = self.map.max_zoom.unwrap_or(tile_id.zoom);
        let first = tile_id.zoom.saturating_sub(deepest);
        for levels in first..=MAX_OVERZOOM_LEVELS.min(tile_id.zoom) {
            let ancestor = TileId {
                x: tile_id.x >> levels,
                y: tile_id.y >> levels,
                zoom: tile_id.zoom - levels,
            };
            if let Some(texture) = self.texture(ancestor) {
                return Some(super::tiles::part_of_ancestor(texture, tile_id, levels));
            }
        }
        None
    }

    fn attribution(&self) -> Attribution {
        super::tiles::text_attribution(self.attribution)
    }

    fn tile_size(&self) -> u32 {
        256
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 256-pixel PNG tile of one colour.
    fn tile_png(rgb: [u8; 3]) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, 256, 256);
        encoder.set_color(png::ColorType::Rgb);
        let mut writer = encoder.write_header().expect("header");
        let pixels: Vec<u8> = (0..256 * 256).flat_map(|_| rgb).collect();
        writer.write_image_data(&pixels).expect("pixels");
        drop(writer);
        bytes
    }

    /// The XYZ tile that holds a latitude and longitude at `zoom` (the slippy-map formula).
    fn tile_of(lat_deg: f64, lon_deg: f64, zoom: u8) -> (u32, u32) {
        let n = f64::from(1u32 << zoom);
        let x = ((lon_deg + 180.0) / 360.0 * n).floor() as u32;
        let lat = lat_deg.to_radians();
        let y = ((1.0 - lat.tan().asinh() / std::f64::consts::PI) / 2.0 * n).floor() as u32;
        (x, y)
    }

    /// The yard's gate (plan-yard.xml) and its tile at zoom 18, the one north of it, red
    /// and blue.
    const GATE: (f64, f64) = (43.561_536, 1.469_198_6);
    const RED: [u8; 3] = [200, 30, 40];
    const BLUE: [u8; 3] = [20, 60, 210];

    fn colour_at(tiles: &BaseTiles, zoom: u8, x: u32, y: u32) -> Option<[u8; 3]> {
        let image = tiles.image(TileId { x, y, zoom })?;
        let pixel = image.pixels[128 * 256 + 128];
        Some([pixel.r(), pixel.g(), pixel.b()])
    }

    fn check(tiles: &mut BaseTiles) {
        let (x, y) = tile_of(GATE.0, GATE.1, 18);
        assert_eq!(colour_at(tiles, 18, x, y), Some(RED));
        // North is the row above in XYZ numbering.
        assert_eq!(colour_at(tiles, 18, x, y - 1), Some(BLUE));
        assert_eq!(colour_at(tiles, 18, x + 1, y), None);
        // Zoomed in past the deepest level: a quarter of the red tile, enlarged.
        let deeper = TileId {
            x: 2 * x + 1,
            y: 2 * y,
            zoom: 19,
        };
        let piece = tiles.at(deeper).expect("drawn from its parent");
        assert_eq!(
            piece.uv,
            egui::Rect::from_min_max(egui::pos2(0.5, 0.0), egui::pos2(1.0, 0.5))
        );
    }

    #[test]
    fn an_mbtiles_file_shows_its_tiles_where_the_spec_puts_them() {
        let dir = tempfile::tempdir().expect("temporary folder");
        let file = dir.path().join("yard.mbtiles");
        let db = rusqlite::Connection::open(&file).expect("sqlite");
        db.execute_batch(
            "CREATE TABLE metadata (name TEXT, value TEXT);
             CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
             INSERT INTO metadata VALUES ('name', 'Yard survey'), ('format', 'png'), ('maxzoom', '18'), ('attribution', 'survey 2026');",
        )
        .expect("schema");
        let (x, y) = tile_of(GATE.0, GATE.1, 18);
        // MBTiles numbers rows from the south (TMS): row = 2^z - 1 - y.
        let tms = |y: u32| (1u32 << 18) - 1 - y;
        for (row, colour) in [(tms(y), RED), (tms(y - 1), BLUE)] {
            db.execute(
                "INSERT INTO tiles VALUES (18, ?1, ?2, ?3)",
                rusqlite::params![x, row, tile_png(colour)],
            )
            .expect("tile");
        }
        drop(db);
        let map = Basemap::open(&file).expect("opens");
        assert_eq!(map.name, "Yard survey");
        let mut tiles = BaseTiles::new(&egui::Context::default(), map);
        assert_eq!(tiles.attribution().text, "survey 2026");
        check(&mut tiles);
    }

    #[test]
    fn a_tile_folder_shows_its_tiles_where_their_names_put_them() {
        let dir = tempfile::tempdir().expect("temporary folder");
        let (x, y) = tile_of(GATE.0, GATE.1, 18);
        for (row, colour) in [(y, RED), (y - 1, BLUE)] {
            let folder = dir.path().join(format!("18/{x}"));
            std::fs::create_dir_all(&folder).expect("folder");
            std::fs::write(folder.join(format!("{row}.png")), tile_png(colour)).expect("tile");
        }
        let map = Basemap::open(dir.path()).expect("opens");
        assert_eq!(map.max_zoom, Some(18));
        check(&mut BaseTiles::new(&egui::Context::default(), map));
    }

    #[test]
    fn what_is_not_a_base_map_is_refused_in_words() {
        let dir = tempfile::tempdir().expect("temporary folder");
        let text = dir.path().join("notes.mbtiles");
        std::fs::write(&text, "not a database").expect("write");
        let err = Basemap::open(&text).expect_err("refused");
        assert!(err.contains("not an MBTiles file"), "{err}");
        let err = Basemap::open(dir.path()).expect_err("refused");
        assert!(err.contains("holds no tiles"), "{err}");
    }
}

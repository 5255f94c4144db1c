//! Offline base maps: raster tiles from an MBTiles file (SQLite, the format QGroundControl
//! caches and most GIS tools write) or from a folder of `{z}/{x}/{y}.png` tiles (what tile
//! downloaders and `gdal2tiles --xyz` write). Tiles are numbered as on the web (XYZ: row 0 at
//! the north); MBTiles stores rows from the south (TMS), so a row is flipped on the way in, as
//! the MBTiles 1.3 specification says.
//!
//! This reads tiles' encoded bytes (PNG or JPEG); decoding and drawing are the studio's.

use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags, OptionalExtension};

/// Where a base map's tiles come from.
#[derive(Debug)]
enum Source {
    MbTiles(Connection),
    Folder(PathBuf),
}

/// An opened base map.
#[derive(Debug)]
pub struct Basemap {
    source: Source,
    path: PathBuf,
    /// The MBTiles `name`, else the file or folder's name.
    pub name: String,
    /// The deepest zoom level that has tiles (`maxzoom`, else found from the tiles).
    pub max_zoom: Option<u8>,
    /// The attribution to show (MBTiles `attribution`).
    pub attribution: String,
}

impl Basemap {
    /// Opens an MBTiles file (read only) or a folder of tiles; the error says why in words.
    pub fn open(path: &Path) -> Result<Basemap, String> {
        let shown = path.display();
        let file_name = path
            .file_name()
            .map_or_else(String::new, |name| name.to_string_lossy().into_owned());
        if path.is_dir() {
            let max_zoom = (0..=30u8)
                .rev()
                .find(|zoom| path.join(zoom.to_string()).is_dir());
            if max_zoom.is_none() {
                return Err(format!(
                    "{shown} holds no tiles: a tile folder has one folder per zoom level, {{z}}/{{x}}/{{y}}.png"
                ));
            }
            return Ok(Basemap {
                source: Source::Folder(path.to_path_buf()),
                path: path.to_path_buf(),
                name: file_name,
                max_zoom,
                attribution: String::new(),
            });
        }
        let connection = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY)
            .map_err(|err| format!("cannot open {shown} as an MBTiles file: {err}"))?;
        let metadata = |key: &str| -> Result<Option<String>, String> {
            connection
                .query_row("SELECT value FROM metadata WHERE name = ?1", [key], |row| {
                    row.get::<_, String>(0)
                })
                .optional()
                .map_err(|err| {
                    format!("{shown} is not an MBTiles file (its metadata table: {err})")
                })
        };
        let name = metadata("name")?.unwrap_or(file_name);
        let format = metadata("format")?.unwrap_or_else(|| "png".to_owned());
        if !matches!(format.as_str(), "png" | "jpg" | "jpeg") {
            return Err(format!(
                "{shown} holds `{format}` tiles: only raster tiles (png, jpg) are drawn"
            ));
        }
        let attribution = metadata("attribution")?.unwrap_or_default();
        let max_zoom = match metadata("maxzoom")?.and_then(|zoom| zoom.trim().parse().ok()) {
            Some(zoom) => Some(zoom),
            None => connection
                .query_row("SELECT MAX(zoom_level) FROM tiles", [], |row| {
                    row.get::<_, Option<u8>>(0)
                })
                .map_err(|err| {
                    format!("{shown} is not an MBTiles file (its tiles table: {err})")
                })?,
        };
        Ok(Basemap {
            source: Source::MbTiles(connection),
            path: path.to_path_buf(),
            name,
            max_zoom,
            attribution,
        })
    }

    /// The file or folder it was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The encoded image of tile `x`, `y` (XYZ numbering) at `zoom`, `None` when the map has
    /// no such tile.
    pub fn tile(&self, zoom: u8, x: u32, y: u32) -> Result<Option<Vec<u8>>, String> {
        if zoom > 30 || x >= 1 << zoom || y >= 1 << zoom {
            return Ok(None);
        }
        match &self.source {
            Source::MbTiles(connection) => {
                let tms_row = (1_u32 << zoom) - 1 - y;
                connection
                    .query_row(
                        "SELECT tile_data FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                        [u32::from(zoom), x, tms_row],
                        |row| row.get::<_, Vec<u8>>(0),
                    )
                    .optional()
                    .map_err(|err| format!("{}: tile {zoom}/{x}/{y}: {err}", self.path.display()))
            }
            Source::Folder(folder) => {
                let base = folder.join(zoom.to_string()).join(x.to_string());
                for extension in ["png", "jpg", "jpeg"] {
                    let file = base.join(format!("{y}.{extension}"));
                    match std::fs::read(&file) {
                        Ok(bytes) => return Ok(Some(bytes)),
                        Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
                        Err(err) => return Err(format!("{}: {err}", file.display())),
                    }
                }
                Ok(None)
            }
        }
    }
}

//! A world read from its file, whatever its format: a `.world` file ([`World::parse`]) or a ROS
//! map_server map ([`ros_map`]). Apart from both, so that neither format's module imports the
//! other's.

use crate::ros_map;
use crate::world::{World, WorldError};

/// Reads the world file at `path`: a `.world` file, or a ROS map_server map (`.yaml`, see
/// [`ros_map`]) and its image; `read` does the reading, so that this crate does none.
pub fn load(
    path: &std::path::Path,
    read: &mut dyn FnMut(&std::path::Path) -> std::io::Result<Vec<u8>>,
) -> Result<World, WorldError> {
    if ros_map::is_map_yaml(path) {
        return ros_map::load_world(path, read);
    }
    let file_name = path.display().to_string();
    let fail = |message: String| WorldError {
        file: file_name.clone(),
        line: 0,
        col: 0,
        message,
    };
    let bytes = read(path).map_err(|err| fail(format!("cannot read the world file: {err}")))?;
    let text =
        String::from_utf8(bytes).map_err(|_| fail("the world file is not UTF-8 text".into()))?;
    World::parse(&text, &file_name)
}

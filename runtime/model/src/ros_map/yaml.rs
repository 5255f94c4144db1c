//! `map.yaml`: read with yaml-rust2's event parser, which gives every value its line and
//! column, so that a bad value is reported where it is written.

use armor_module_api::types::Pose2D;

use super::{MapYaml, Mode, error};
use crate::world::WorldError;

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
        // `threshold` found the key just above, or returned its error: it is there.
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

//! Unit symbols in the APP-6 / MIL-STD-2525 style, read from SIDC codes and drawn with
//! tiny-skia: a frame whose shape and colour say the affiliation (friend rectangle, hostile
//! diamond, neutral square, unknown quatrefoil), a function icon inside it, the echelon above
//! it, and a dashed frame for a planned (anticipated) unit. No maintained Rust crate renders
//! these symbols, so this is the small subset a mission map needs: ground units.
//!
//! Both code forms are read: 15 characters (APP-6 B / 2525 C: affiliation 2nd, status 4th,
//! function 5th–10th, echelon 12th) and 20 digits (APP-6 D / 2525 D: identity 4th, symbol set
//! 5th–6th, status 7th, echelon 9th–10th, entity 11th–16th).

use std::collections::HashMap;

use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect, Stroke, StrokeDash, Transform};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Affiliation {
    Friend,
    Hostile,
    Neutral,
    Unknown,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    /// A frame without an icon: a unit of a function this subset does not draw.
    Unspecified,
    Infantry,
    MechanizedInfantry,
    Armour,
    AntiArmour,
    Reconnaissance,
    Artillery,
    Engineer,
    AirDefence,
    Medical,
    Signal,
    Supply,
    Maintenance,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Echelon {
    Team,
    Squad,
    Section,
    Platoon,
    Company,
    Battalion,
    Regiment,
    Brigade,
    Division,
    Corps,
    Army,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Symbol {
    pub affiliation: Affiliation,
    pub function: Function,
    pub echelon: Option<Echelon>,
    /// Status "anticipated / planned": the frame is dashed.
    pub planned: bool,
}

/// 2525 C function codes (5th to 10th characters, the longest prefix wins) and 2525 D entity
/// codes (11th to 16th digits).
const FUNCTIONS: &[(&str, &str, Function)] = &[
    ("UCIZ", "121104", Function::MechanizedInfantry),
    ("UCI", "121100", Function::Infantry),
    ("UCAA", "120400", Function::AntiArmour),
    ("UCA", "120500", Function::Armour),
    ("UCR", "121300", Function::Reconnaissance),
    ("UCF", "130300", Function::Artillery),
    ("UCE", "140700", Function::Engineer),
    ("UCD", "130100", Function::AirDefence),
    ("USM", "161300", Function::Medical),
    ("UUS", "111000", Function::Signal),
    ("USS", "163400", Function::Supply),
    ("USX", "161100", Function::Maintenance),
];

/// Reads a SIDC; a function outside the subset is [`Function::Unspecified`] (still a valid
/// symbol), a malformed code an error in words.
pub fn parse(sidc: &str) -> Result<Symbol, String> {
    armor_model::plan::check_sidc(sidc)?;
    let chars: Vec<char> = sidc.chars().map(|c| c.to_ascii_uppercase()).collect();
    if chars.len() == 20 {
        return parse_d(&chars);
    }
    let affiliation = match chars[1] {
        'F' | 'A' | 'D' | 'M' => Affiliation::Friend,
        'H' | 'S' | 'J' | 'K' => Affiliation::Hostile,
        'N' | 'L' => Affiliation::Neutral,
        _ => Affiliation::Unknown,
    };
    let code: String = chars[4..10].iter().collect();
    let function = FUNCTIONS
        .iter()
        .find(|(prefix, _, _)| chars[2] == 'G' && code.starts_with(prefix))
        .map_or(Function::Unspecified, |(_, _, function)| *function);
    let echelon = match chars[11] {
        'A' => Some(Echelon::Team),
        'B' => Some(Echelon::Squad),
        'C' => Some(Echelon::Section),
        'D' => Some(Echelon::Platoon),
        'E' => Some(Echelon::Company),
        'F' => Some(Echelon::Battalion),
        'G' => Some(Echelon::Regiment),
        'H' => Some(Echelon::Brigade),
        'I' => Some(Echelon::Division),
        'J' => Some(Echelon::Corps),
        'K' | 'L' | 'M' => Some(Echelon::Army),
        _ => None,
    };
    Ok(Symbol {
        affiliation,
        function,
        echelon,
        planned: chars[3] == 'A',
    })
}

fn parse_d(digits: &[char]) -> Result<Symbol, String> {
    let affiliation = match digits[3] {
        '2' | '3' => Affiliation::Friend,
        '5' | '6' => Affiliation::Hostile,
        '4' => Affiliation::Neutral,
        _ => Affiliation::Unknown,
    };
    let text = |from: usize, to: usize| digits[from..to].iter().collect::<String>();
    let land_unit = text(4, 6) == "10";
    let entity = text(10, 16);
    let function = FUNCTIONS
        .iter()
        .find(|(_, code, _)| land_unit && *code == entity)
        .map_or(Function::Unspecified, |(_, _, function)| *function);
    let echelon = match text(8, 10).as_str() {
        "11" => Some(Echelon::Team),
        "12" => Some(Echelon::Squad),
        "13" => Some(Echelon::Section),
        "14" => Some(Echelon::Platoon),
        "15" => Some(Echelon::Company),
        "16" => Some(Echelon::Battalion),
        "17" => Some(Echelon::Regiment),
        "18" => Some(Echelon::Brigade),
        "21" => Some(Echelon::Division),
        "22" => Some(Echelon::Corps),
        "23" | "24" | "25" => Some(Echelon::Army),
        _ => None,
    };
    Ok(Symbol {
        affiliation,
        function,
        echelon,
        planned: digits[6] == '1',
    })
}

impl Symbol {
    /// Words for a tooltip: "friendly reconnaissance, platoon (planned)".
    pub fn describe(&self) -> String {
        let affiliation = match self.affiliation {
            Affiliation::Friend => "friendly",
            Affiliation::Hostile => "hostile",
            Affiliation::Neutral => "neutral",
            Affiliation::Unknown => "unknown",
        };
        let function = match self.function {
            Function::Unspecified => "unit",
            Function::Infantry => "infantry",
            Function::MechanizedInfantry => "mechanized infantry",
            Function::Armour => "armour",
            Function::AntiArmour => "anti-armour",
            Function::Reconnaissance => "reconnaissance",
            Function::Artillery => "artillery",
            Function::Engineer => "engineer",
            Function::AirDefence => "air defence",
            Function::Medical => "medical",
            Function::Signal => "signal",
            Function::Supply => "supply",
            Function::Maintenance => "maintenance",
        };
        let mut text = format!("{affiliation} {function}");
        if let Some(echelon) = self.echelon {
            text += &format!(", {}", format!("{echelon:?}").to_lowercase());
        }
        if self.planned {
            text += " (planned)";
        }
        text
    }

    fn fill(&self) -> Color {
        let (r, g, b) = match self.affiliation {
            Affiliation::Friend => (128, 224, 255),
            Affiliation::Hostile => (255, 128, 128),
            Affiliation::Neutral => (170, 255, 170),
            Affiliation::Unknown => (255, 255, 128),
        };
        Color::from_rgba8(r, g, b, 255)
    }
}

/// The frame's box and the box the icon is drawn in, in pixels of a `size` square.
fn boxes(affiliation: Affiliation, size: f32) -> Option<(Rect, Rect)> {
    let centre = (size / 2.0, size * 0.6);
    let rect = |w: f32, h: f32| Rect::from_xywh(centre.0 - w / 2.0, centre.1 - h / 2.0, w, h);
    let (frame, icon) = match affiliation {
        Affiliation::Friend => ((0.84, 0.56), (0.84, 0.56)),
        Affiliation::Hostile => ((0.76, 0.76), (0.38, 0.38)),
        Affiliation::Neutral => ((0.6, 0.6), (0.6, 0.6)),
        Affiliation::Unknown => ((0.76, 0.76), (0.44, 0.44)),
    };
    Some((
        rect(size * frame.0, size * frame.1)?,
        rect(size * icon.0, size * icon.1)?,
    ))
}

/// Draws the symbol on a transparent `size_px` square; `None` for a size tiny-skia refuses.
pub fn render(symbol: &Symbol, size_px: u32) -> Option<Pixmap> {
    let mut pixmap = Pixmap::new(size_px, size_px)?;
    let size = size_px as f32;
    let width = (size / 32.0).max(1.0);
    let (frame, icon) = boxes(symbol.affiliation, size)?;
    let mut fill = Paint::default();
    fill.set_color(symbol.fill());
    fill.anti_alias = true;
    let mut ink = Paint::default();
    ink.set_color(Color::BLACK);
    ink.anti_alias = true;
    let mut outline = Stroke {
        width,
        ..Stroke::default()
    };
    if symbol.planned {
        outline.dash = StrokeDash::new(vec![width * 3.0, width * 2.5], 0.0);
    }
    let identity = Transform::identity();
    let (cx, cy) = (
        frame.x() + frame.width() / 2.0,
        frame.y() + frame.height() / 2.0,
    );
    if symbol.affiliation == Affiliation::Unknown {
        // Four lobes: each circle's outline, then the fill over the inner parts of them.
        let r = frame.width() / 4.0;
        let lobes = [(cx - r, cy), (cx + r, cy), (cx, cy - r), (cx, cy + r)];
        for (x, y) in lobes {
            if let Some(circle) = PathBuilder::from_circle(x, y, r) {
                pixmap.stroke_path(&circle, &ink, &outline, identity, None);
            }
        }
        for (x, y) in lobes {
            if let Some(circle) = PathBuilder::from_circle(x, y, r - width / 2.0) {
                pixmap.fill_path(&circle, &fill, FillRule::Winding, identity, None);
            }
        }
        pixmap.fill_rect(icon, &fill, identity, None);
    } else {
        let path = match symbol.affiliation {
            Affiliation::Hostile => {
                let mut path = PathBuilder::new();
                path.move_to(cx, frame.top());
                path.line_to(frame.right(), cy);
                path.line_to(cx, frame.bottom());
                path.line_to(frame.left(), cy);
                path.close();
                path.finish()
            }
            _ => Some(PathBuilder::from_rect(frame)),
        };
        if let Some(path) = path {
            pixmap.fill_path(&path, &fill, FillRule::Winding, identity, None);
            pixmap.stroke_path(&path, &ink, &outline, identity, None);
        }
    }
    draw_icon(&mut pixmap, symbol.function, icon, width, &ink);
    if let Some(echelon) = symbol.echelon {
        draw_echelon(
            &mut pixmap,
            echelon,
            cx,
            frame.top() - size * 0.09,
            size,
            width,
            &ink,
        );
    }
    Some(pixmap)
}

fn line(path: &mut PathBuilder, a: (f32, f32), b: (f32, f32)) {
    path.move_to(a.0, a.1);
    path.line_to(b.0, b.1);
}

fn draw_icon(pixmap: &mut Pixmap, function: Function, area: Rect, width: f32, ink: &Paint) {
    let (l, t, r, b) = (area.left(), area.top(), area.right(), area.bottom());
    let (w, h) = (area.width(), area.height());
    let (cx, cy) = (l + w / 2.0, t + h / 2.0);
    let mut path = PathBuilder::new();
    let mut dot = None;
    match function {
        Function::Unspecified => {}
        Function::Infantry => {
            line(&mut path, (l, t), (r, b));
            line(&mut path, (l, b), (r, t));
        }
        Function::MechanizedInfantry => {
            line(&mut path, (l, t), (r, b));
            line(&mut path, (l, b), (r, t));
            path.push_oval(
                Rect::from_xywh(l + w * 0.2, t + h * 0.3, w * 0.6, h * 0.4).unwrap_or(area),
            );
        }
        Function::Armour => {
            path.push_oval(
                Rect::from_xywh(l + w * 0.2, t + h * 0.3, w * 0.6, h * 0.4).unwrap_or(area),
            );
        }
        Function::AntiArmour => {
            line(&mut path, (l, b), (cx, t));
            line(&mut path, (cx, t), (r, b));
        }
        Function::Reconnaissance => line(&mut path, (l, b), (r, t)),
        Function::Artillery => dot = Some((cx, cy, w.min(h) * 0.12)),
        Function::Engineer => {
            let (el, er, et, eb) = (l + w * 0.25, r - w * 0.25, t + h * 0.35, b - h * 0.3);
            line(&mut path, (el, et), (er, et));
            for x in [el, cx, er] {
                line(&mut path, (x, et), (x, eb));
            }
        }
        Function::AirDefence => {
            path.move_to(l, b - h * 0.2);
            path.quad_to(cx, b - h * 0.55, r, b - h * 0.2);
        }
        Function::Medical => {
            line(&mut path, (cx, t), (cx, b));
            line(&mut path, (l, cy), (r, cy));
        }
        Function::Signal => {
            path.move_to(l + w * 0.15, t + h * 0.2);
            path.line_to(cx, b - h * 0.25);
            path.line_to(cx, t + h * 0.25);
            path.line_to(r - w * 0.15, b - h * 0.2);
        }
        Function::Supply => line(&mut path, (l, b - h * 0.25), (r, b - h * 0.25)),
        Function::Maintenance => {
            line(&mut path, (l + w * 0.2, cy), (r - w * 0.2, cy));
            path.push_circle(l + w * 0.2, cy, h * 0.1);
            path.push_circle(r - w * 0.2, cy, h * 0.1);
        }
    }
    let stroke = Stroke {
        width,
        ..Stroke::default()
    };
    if let Some(path) = path.finish() {
        pixmap.stroke_path(&path, ink, &stroke, Transform::identity(), None);
    }
    if let Some((x, y, radius)) = dot
        && let Some(circle) = PathBuilder::from_circle(x, y, radius)
    {
        pixmap.fill_path(&circle, ink, FillRule::Winding, Transform::identity(), None);
    }
}

/// The echelon above the frame: dots for team to platoon (Ø for a team), bars for company to
/// regiment, crosses for brigade and above.
fn draw_echelon(
    pixmap: &mut Pixmap,
    echelon: Echelon,
    cx: f32,
    y: f32,
    size: f32,
    width: f32,
    ink: &Paint,
) {
    let step = size * 0.09;
    let half = size * 0.035;
    let (count, mark) = match echelon {
        Echelon::Team => (1, 'o'),
        Echelon::Squad => (1, '.'),
        Echelon::Section => (2, '.'),
        Echelon::Platoon => (3, '.'),
        Echelon::Company => (1, '|'),
        Echelon::Battalion => (2, '|'),
        Echelon::Regiment => (3, '|'),
        Echelon::Brigade => (1, 'x'),
        Echelon::Division => (2, 'x'),
        Echelon::Corps => (3, 'x'),
        Echelon::Army => (4, 'x'),
    };
    let mut path = PathBuilder::new();
    let mut dots = PathBuilder::new();
    for k in 0..count {
        let x = cx + (k as f32 - (count - 1) as f32 / 2.0) * step;
        match mark {
            '.' => dots.push_circle(x, y, half),
            '|' => line(&mut path, (x, y - half * 1.6), (x, y + half * 1.6)),
            'x' => {
                line(
                    &mut path,
                    (x - half, y - half * 1.4),
                    (x + half, y + half * 1.4),
                );
                line(
                    &mut path,
                    (x - half, y + half * 1.4),
                    (x + half, y - half * 1.4),
                );
            }
            _ => {
                path.push_circle(x, y, half * 1.2);
                line(
                    &mut path,
                    (x - half * 1.8, y + half * 1.8),
                    (x + half * 1.8, y - half * 1.8),
                );
            }
        }
    }
    let stroke = Stroke {
        width,
        ..Stroke::default()
    };
    if let Some(path) = path.finish() {
        pixmap.stroke_path(&path, ink, &stroke, Transform::identity(), None);
    }
    if let Some(dots) = dots.finish() {
        pixmap.fill_path(&dots, ink, FillRule::Winding, Transform::identity(), None);
    }
}

/// Rendered symbols as egui textures, by code and size; a code that does not read is kept as
/// its error, so that it is not read again every frame.
#[derive(Default)]
pub struct SymbolCache {
    textures: HashMap<(String, u32), Result<egui::TextureHandle, String>>,
}

impl SymbolCache {
    pub fn texture(
        &mut self,
        ctx: &egui::Context,
        sidc: &str,
        size_px: u32,
    ) -> Result<egui::TextureHandle, String> {
        self.textures
            .entry((sidc.to_owned(), size_px))
            .or_insert_with(|| {
                let symbol = parse(sidc)?;
                let pixmap = render(&symbol, size_px)
                    .ok_or_else(|| format!("cannot draw at {size_px} px"))?;
                let image = egui::ColorImage::from_rgba_premultiplied(
                    [size_px as usize, size_px as usize],
                    pixmap.data(),
                );
                Ok(ctx.load_texture(format!("sidc {sidc}"), image, egui::TextureOptions::LINEAR))
            })
            .clone()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[track_caller]
    fn check(
        sidc: &str,
        affiliation: Affiliation,
        function: Function,
        echelon: Option<Echelon>,
        planned: bool,
    ) {
        let symbol = parse(sidc).unwrap();
        assert_eq!(
            symbol,
            Symbol {
                affiliation,
                function,
                echelon,
                planned
            },
            "{sidc}"
        );
    }

    #[test]
    fn both_code_forms_read() {
        use Affiliation::*;
        check(
            "SFGPUCR----K---",
            Friend,
            Function::Reconnaissance,
            Some(Echelon::Army),
            false,
        );
        check(
            "SHGPUCI----D---",
            Hostile,
            Function::Infantry,
            Some(Echelon::Platoon),
            false,
        );
        check("SNGAUCA--------", Neutral, Function::Armour, None, true);
        check(
            "SUGPUCIZ---E---",
            Unknown,
            Function::MechanizedInfantry,
            Some(Echelon::Company),
            false,
        );
        check("SJGPUCF--------", Hostile, Function::Artillery, None, false);
        check("SPGPUCE--------", Unknown, Function::Engineer, None, false);
        check(
            "SAGPXXXXXX-----",
            Friend,
            Function::Unspecified,
            None,
            false,
        );
        check(
            "10031000141211000000",
            Friend,
            Function::Infantry,
            Some(Echelon::Platoon),
            false,
        );
        check(
            "10061010161213000000",
            Hostile,
            Function::Reconnaissance,
            Some(Echelon::Battalion),
            true,
        );
        check(
            "10041000001205000000",
            Neutral,
            Function::Armour,
            None,
            false,
        );
    }

    #[test]
    fn bad_codes_say_what_is_wrong() {
        assert!(parse("SFG").unwrap_err().contains("15 characters"));
        assert!(
            parse("SXGPUCI----D---")
                .unwrap_err()
                .contains("affiliation")
        );
        assert!(
            parse("1003100014121100000X")
                .unwrap_err()
                .contains("digits")
        );
    }

    #[test]
    fn descriptions_in_words() {
        assert_eq!(
            parse("SFGPUCR----D---").unwrap().describe(),
            "friendly reconnaissance, platoon"
        );
        assert_eq!(
            parse("SHGAUCI--------").unwrap().describe(),
            "hostile infantry (planned)"
        );
    }

    fn pixel(pixmap: &Pixmap, x: f32, y: f32) -> [u8; 4] {
        let p = pixmap.pixel(x as u32, y as u32).unwrap();
        [p.red(), p.green(), p.blue(), p.alpha()]
    }

    #[test]
    fn frames_icons_and_echelons_are_drawn() {
        let size = 96.0;
        let friend = render(&parse("SFGPUCI----D---").unwrap(), 96).unwrap();
        let hostile = render(&parse("SHGPUCI--------").unwrap(), 96).unwrap();
        let (frame, _) = boxes(Affiliation::Friend, size).unwrap();
        // Inside the frame, left of the centre and off the X's arms: the affiliation's fill.
        let (cx, cy) = (
            frame.x() + frame.width() / 2.0,
            frame.y() + frame.height() / 2.0,
        );
        assert_eq!(pixel(&friend, frame.left() + 6.0, cy), [128, 224, 255, 255]);
        assert_eq!(pixel(&hostile, size * 0.2, cy), [255, 128, 128, 255]);
        // The frame box's corner: filled for a rectangle, left transparent by a diamond.
        let corner = (frame.left() + 4.0, frame.top() + 10.0);
        assert_eq!(pixel(&friend, corner.0, corner.1)[3], 255);
        assert_eq!(pixel(&hostile, corner.0, corner.1)[3], 0);
        // Infantry: black on the diagonal.
        let on_diagonal = pixel(
            &friend,
            cx + frame.width() * 0.25,
            cy + frame.height() * 0.25,
        );
        assert!(
            on_diagonal[0] < 60 && on_diagonal[3] == 255,
            "{on_diagonal:?}"
        );
        // A platoon's three dots above the frame; nothing there without an echelon.
        let above = |pixmap: &Pixmap, frame: Rect| {
            (0..96)
                .filter(|x| pixel(pixmap, *x as f32, frame.top() - size * 0.09)[3] > 128)
                .count()
        };
        assert!(above(&friend, frame) >= 6, "{}", above(&friend, frame));
        let (diamond, _) = boxes(Affiliation::Hostile, size).unwrap();
        assert_eq!(above(&hostile, diamond), 0);
    }

    #[test]
    fn a_planned_unit_has_gaps_in_its_outline() {
        let present = render(&parse("SNGPUCA--------").unwrap(), 96).unwrap();
        let planned = render(&parse("SNGAUCA--------").unwrap(), 96).unwrap();
        let (frame, _) = boxes(Affiliation::Neutral, 96.0).unwrap();
        let dark_on_top = |pixmap: &Pixmap| {
            (frame.left() as u32..frame.right() as u32)
                .filter(|x| {
                    let [red, _, _, alpha] = pixel(pixmap, *x as f32, frame.top());
                    red < 90 && alpha > 128
                })
                .count()
        };
        assert!(
            dark_on_top(&planned) < dark_on_top(&present) * 3 / 4,
            "{} vs {}",
            dark_on_top(&planned),
            dark_on_top(&present)
        );
    }
}

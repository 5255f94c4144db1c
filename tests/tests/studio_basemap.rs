//! A base map chosen in the studio's View menu shows under the plan, in the Mission and Run
//! views: an MBTiles file whose tiles are all one colour tints the map where the yard is, and
//! Undo takes it away.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use armor_studio::app::View;
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::{Options, StudioApp};
use armor_tests::workspace_root;
use egui::{Key, Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

/// A 256-pixel PNG tile of one colour.
fn tile_png(rgb: [u8; 3]) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 256, 256);
    encoder.set_color(png::ColorType::Rgb);
    let mut writer = encoder.write_header().unwrap();
    let pixels: Vec<u8> = (0..256 * 256).flat_map(|_| rgb).collect();
    writer.write_image_data(&pixels).unwrap();
    drop(writer);
    bytes
}

/// An MBTiles file of red tiles over the yard at zoom 17 and 18 (rows from the south, as the
/// format numbers them).
fn red_yard(file: &Path) {
    let db = rusqlite::Connection::open(file).unwrap();
    db.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
         INSERT INTO metadata VALUES ('name', 'Red yard'), ('format', 'png');",
    )
    .unwrap();
    let (lat, lon) = (43.561_55_f64, 1.469_25_f64);
    for zoom in [17_u8, 18] {
        let n = f64::from(1u32 << zoom);
        let x = ((lon + 180.0) / 360.0 * n).floor() as u32;
        let y = ((1.0 - lat.to_radians().tan().asinh() / std::f64::consts::PI) / 2.0 * n).floor()
            as u32;
        for dx in 0..3 {
            for dy in 0..3 {
                db.execute(
                    "INSERT INTO tiles VALUES (?1, ?2, ?3, ?4)",
                    rusqlite::params![
                        zoom,
                        x + dx - 1,
                        (1u32 << zoom) - 1 - (y + dy - 1),
                        tile_png([220, 20, 20])
                    ],
                )
                .unwrap();
            }
        }
    }
}

#[test]
fn a_base_map_chosen_in_the_view_menu_shows_under_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plan.xml");
    let text = std::fs::read_to_string(workspace_root().join("missions/robot/plan-yard.xml"))
        .unwrap()
        .replace(
            "system=\"system.xml\"",
            &format!(
                "system=\"{}\"",
                workspace_root().join("missions/robot/system.xml").display()
            ),
        );
    std::fs::write(&plan, text).unwrap();
    red_yard(&dir.path().join("red.mbtiles"));

    let mut options = Options::new(Home::new(dir.path().join("home")));
    options.palette = Some(Palette::from_descriptions(Vec::new()));
    let mut harness = Harness::builder()
        .with_size([1280.0, 800.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(120)
        .wgpu()
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        );
    harness.run();
    harness.state_mut().set_view(View::Mission);
    harness.run();
    harness.state_mut().open_plan(&plan);
    harness.run();

    // An open part of the yard: north of the first leg, south of the buildings.
    let redness = |harness: &mut Harness<'_, StudioApp>| {
        // The map frames the yard once it has been laid out: a few frames at most.
        let mut at = None;
        for _ in 0..30 {
            harness.run();
            let mission = harness.state().mission().unwrap();
            at = mission
                .screen_pos_of_local(10.0, 8.0)
                .filter(|at| mission.map_rect().contains(*at));
            if at.is_some() {
                break;
            }
        }
        let at: Pos2 = at.expect("the yard is on the map");
        let image = harness.render().unwrap();
        let scale = harness.ctx.pixels_per_point();
        let p = image.get_pixel((at.x * scale) as u32, (at.y * scale) as u32);
        i16::from(p[0]) - i16::from(p[1])
    };
    let before = redness(&mut harness);
    assert!(
        before.abs() < 20,
        "the world's own tiles are not red: {before}"
    );

    harness.get_by_label("View").click();
    harness.run();
    harness.get_by_label("Base map…").click();
    harness.run();
    harness
        .get_by_label("Path:")
        .type_text(&dir.path().join("red.mbtiles").display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    harness.get_by_label_contains("base map `Red yard`");
    let mission = harness.state().mission().unwrap();
    assert_eq!(mission.basemap_href().as_deref(), Some("red.mbtiles"));
    let after = redness(&mut harness);
    assert!(
        after > 60,
        "the red base map shows through the world: {after}"
    );

    // The Run view draws the same map, base map and all.
    harness.state_mut().set_view(View::Run);
    let in_run_view = redness(&mut harness);
    assert!(
        in_run_view > 60,
        "the Run view shows the base map: {in_run_view}"
    );
    harness.state_mut().set_view(View::Mission);

    // Undo takes the base map away again.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    let undone = redness(&mut harness);
    assert!(undone.abs() < 20, "{undone}");
    assert_eq!(harness.state().mission().unwrap().basemap_href(), None);
}

//! Files named in other files are found from the file that names them, whatever the current
//! folder; worlds may be ROS map_server maps; `armor export --ros-map` writes one that reads
//! back as the mapper's grid.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use armor_model::ros_map;
use armor_model::world::World;
use armor_module_api::types::{Datum, OccupancyGrid};
use armor_tests::check::{armor, assert_refused, line_of, output_text};
use armor_tests::mcap::recorded;
use armor_tests::{Proc, bin, bin_dir, workspace_root};

fn robot_file(name: &str) -> PathBuf {
    workspace_root().join("missions/robot").join(name)
}

/// `armor ARGS` run from `cwd`, with the workspace's modules.
fn armor_in(cwd: &Path, args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(bin("armor"))
        .args(args)
        .env("ARMOR_MODULE_PATH", bin_dir())
        .current_dir(cwd)
        .output()
        .expect("armor runs")
}

fn os(text: &str) -> &std::ffi::OsStr {
    std::ffi::OsStr::new(text)
}

#[test]
fn every_bundled_plan_checks_and_compiles_from_another_folder() {
    let elsewhere = tempfile::tempdir().expect("temporary folder");
    let mut plans: Vec<PathBuf> = std::fs::read_dir(workspace_root().join("missions/robot"))
        .expect("missions/robot")
        .map(|entry| entry.expect("entry").path())
        .filter(|path| {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            name.starts_with("plan-") && name.ends_with(".xml")
        })
        .collect();
    plans.sort();
    assert!(plans.len() >= 5, "{plans:?}");
    for plan in &plans {
        let checked = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
        assert!(checked.status.success(), "{}", output_text(&checked));
        let net = elsewhere.path().join("net.xml");
        let compiled = armor_in(
            elsewhere.path(),
            &[os("compile"), plan.as_os_str(), os("-o"), net.as_os_str()],
        );
        assert!(compiled.status.success(), "{}", output_text(&compiled));
    }
}

#[test]
fn the_yard_plan_run_from_another_folder_gives_the_sim_its_world() {
    let elsewhere = tempfile::tempdir().expect("temporary folder");
    let run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(robot_file("plan-yard.xml"))
            .args(["--time-scale", "10"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(elsewhere.path()),
    );
    let yard = workspace_root().join("assets/worlds/yard.world");
    let loaded = run.wait_for(
        "from the sim saying its world",
        Duration::from_secs(60),
        |line| line.contains("shapes, start at"),
    );
    assert!(loaded.contains(&yard.display().to_string()), "{loaded}");
    // The robot drove the first leg to its end, its sim started once.
    run.wait_for(
        "saying the robot arrived at the end of the first leg",
        Duration::from_secs(120),
        |line| line.contains("fired `advance_arrived`"),
    );
    let lines = run.lines().join("\n");
    assert!(!lines.contains("not found"), "{lines}");
    assert_eq!(
        lines.matches("module started module=\"sim\"").count(),
        1,
        "{lines}"
    );
}

#[test]
fn a_system_naming_a_missing_world_fails_the_check_where_it_is_named() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let text = std::fs::read_to_string(robot_file("system.xml"))
        .expect("system")
        .replacen("value=\"yard.world\"", "value=\"nowhere.world\"", 1);
    let system = dir.path().join("system.xml");
    std::fs::write(&system, &text).expect("write");
    let output = armor(&[os("check"), system.as_os_str()]);
    assert_refused(
        &output,
        &system,
        line_of(&text, "nowhere.world"),
        &[
            "module `sim`",
            "parameter `world`",
            "cannot find `nowhere.world`",
        ],
    );
    // A world beside the system file is found there, not in the current folder.
    std::fs::copy(
        workspace_root().join("assets/worlds/field.world"),
        dir.path().join("nowhere.world"),
    )
    .expect("copy");
    let output = armor(&[os("check"), system.as_os_str()]);
    assert!(output.status.success(), "{}", output_text(&output));
}

/// The yard as a ROS map at 10 cm, as map_saver writes one, with our keys for its geographic
/// origin and start: (map.yaml, map.pgm).
fn yard_as_ros_map() -> (String, Vec<u8>) {
    let yard =
        std::fs::read_to_string(workspace_root().join("assets/worlds/yard.world")).expect("yard");
    let world = World::parse(&yard, "yard.world").expect("the yard");
    let grid = world.occupancy_grid(0.1).expect("grid");
    let (yaml, pgm) = ros_map::to_map_files(&grid, "yard-map.pgm");
    let (lat, lon) = world.origin_lat_lon();
    let start = world.start();
    let yaml = format!(
        "# The yard (yard.world) as a ROS map_server map, rasterised at 10 cm.\n{yaml}geo_origin: [{lat}, {lon}]\nstart: [{}, {}, {}]\n",
        start.x_m, start.y_m, start.theta_rad
    );
    (yaml, pgm)
}

#[test]
fn the_bundled_yard_map_is_the_yard_rasterised() {
    let (yaml, pgm) = yard_as_ros_map();
    let worlds = workspace_root().join("assets/worlds");
    if std::env::var_os("ARMOR_WRITE_YARD_MAP").is_some() {
        std::fs::write(worlds.join("yard-map.yaml"), &yaml).expect("write");
        std::fs::write(worlds.join("yard-map.pgm"), &pgm).expect("write");
    }
    assert_eq!(
        std::fs::read_to_string(worlds.join("yard-map.yaml")).expect("yard-map.yaml"),
        yaml,
        "ARMOR_WRITE_YARD_MAP=1 writes it anew"
    );
    assert!(std::fs::read(worlds.join("yard-map.pgm")).expect("yard-map.pgm") == pgm);
}

/// The yard's system and plan in `dir`, on `world` (named relative to `dir`).
fn yard_plan_on(dir: &Path, world: &str) -> PathBuf {
    let system = std::fs::read_to_string(robot_file("system.xml"))
        .expect("system")
        .replace("value=\"yard.world\"", &format!("value=\"{world}\""));
    std::fs::write(dir.join("system.xml"), system).expect("write");
    let plan = std::fs::read_to_string(robot_file("plan-yard.xml")).expect("plan");
    let file = dir.join("plan.xml");
    std::fs::write(&file, plan).expect("write");
    file
}

#[test]
fn the_yard_plan_runs_on_the_yard_as_a_ros_map() {
    let plan = robot_file("plan-yard-map.xml");
    let elsewhere = tempfile::tempdir().expect("temporary folder");
    let checked = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    assert!(checked.status.success(), "{}", output_text(&checked));
    let report = elsewhere.path().join("report.json");
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&plan)
            .args(["--time-scale", "20", "--report"])
            .arg(&report)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(elsewhere.path()),
    );
    let status = run.wait_exit(Duration::from_secs(240));
    let lines = run.lines().join("\n");
    assert!(status.success(), "{status}\n{lines}");
    assert!(
        lines.contains("yard-map.yaml") && lines.contains("shapes, start at"),
        "{lines}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    assert_eq!(report["outcome"], "complete", "{report:#}");
    assert!(lines.contains(" 0 collisions"), "{lines}");
}

#[test]
fn a_waypoint_on_a_hand_written_maps_wall_is_refused_where_it_is_written() {
    let dir = tempfile::tempdir().expect("temporary folder");
    // A 20 m × 20 m square room at 0.5 m a pixel, walls all round and a solid block from
    // x 8 to 12, y 8 to 12, written as a plain PGM with map_server's usual values.
    let mut pgm = String::from("P2\n40 40\n255\n");
    for row in 0..40 {
        for col in 0..40 {
            let y_from_bottom = 39 - row;
            let wall = row == 0 || col == 0 || row == 39 || col == 39;
            let block = (16..24).contains(&col) && (16..24).contains(&y_from_bottom);
            pgm.push_str(if wall || block { "0 " } else { "254 " });
        }
        pgm.push('\n');
    }
    std::fs::write(dir.path().join("room.pgm"), pgm).expect("write");
    std::fs::write(
        dir.path().join("room.yaml"),
        "image: room.pgm\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\ngeo_origin: [43.56, 1.469]\nstart: [3.0, 3.0, 0.0]\n",
    )
    .expect("write");
    let plan = yard_plan_on(dir.path(), "room.yaml");
    // Waypoints in the room: one in the open, one inside the block.
    let origin = armor_model::geo::LatLon::new(43.56, 1.469);
    let at = |x: f64, y: f64| {
        armor_model::geo::LatLon::from_local(armor_model::geo::Point::new(x, y), origin)
    };
    let (open, inside) = (at(4.0, 4.0), at(10.0, 10.0));
    let text = format!(
        "<plan name=\"room\" system=\"system.xml\">\n  <navigation speed_mps=\"0.5\"/>\n  <waypoint name=\"home\" lat=\"{}\" lon=\"{}\"/>\n  <waypoint name=\"block\" lat=\"{}\" lon=\"{}\"/>\n  <leg name=\"go\" from=\"home\" to=\"block\"/>\n</plan>\n",
        open.lat_deg, open.lon_deg, inside.lat_deg, inside.lon_deg
    );
    std::fs::write(&plan, &text).expect("write");
    let output = armor(&[os("check"), plan.as_os_str()]);
    assert_refused(&output, &plan, line_of(&text, "name=\"block\""), &["block"]);
}

#[test]
fn the_mappers_last_grid_is_exported_as_a_ros_map_that_reads_back_as_it() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let recording = dir.path().join("map.mcap");
    let system = dir.path().join("system.xml");
    std::fs::write(
        &system,
        format!(
            r#"<system name="mapping">
  <module name="sim" type="sim">
    <param name="world" value="yard.world"/>
  </module>
  <module name="mapper" type="mapper"/>
  <module name="recorder" type="recorder">
    <param name="record" value="mapper.map"/>
    <param name="file" value="{}"/>
    <param name="compression" value="none"/>
    <param name="report_secs" value="0.2"/>
  </module>
  <link from="sim.scan" to="mapper.scan"/>
  <link from="sim.odometry" to="mapper.odometry"/>
</system>
"#,
            recording.display()
        ),
    )
    .expect("write");
    // A lease longer than the default 2 s: on a loaded machine (stress --cpu 2 beside the
    // suite) the recorder, writing 60 m grids as JSON, was seen to miss the default lease and
    // be killed and restarted, which this test of the export is not about (the health suite
    // tests the lease).
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&system)
            .args(["--lease-secs", "10"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(dir.path()),
    );
    let addr = armor_tests::control_address(&run);
    // Conditions, not a run of fixed length: a few grids recorded, then the recorder stopped
    // by hand and seen to save its file, before the run ends (a busy machine could otherwise
    // end the run before the first grid, or kill a recorder still writing at shutdown).
    run.wait_for(
        "saying a few grids were recorded",
        Duration::from_secs(60),
        |line| line.starts_with("[recorder]") && recorded(line).is_some_and(|count| count >= 3),
    );
    let (stopped, said) = armor_tests::ctl(&addr, &["stop", "recorder"]);
    assert!(stopped, "{said}");
    run.wait_for(
        "saying the recording was saved",
        Duration::from_secs(60),
        |line| line.starts_with("[recorder]") && line.contains("saved "),
    );
    run.signal(libc::SIGINT);
    let status = run.wait_exit(Duration::from_secs(60));
    assert!(status.success(), "{status}\n{}", run.lines().join("\n"));
    let messages = armor_runtime::replay::read_recording(&recording).expect("recording");
    let last = messages
        .iter()
        .rev()
        .find(|message| message.data_type == OccupancyGrid::TYPE)
        .expect("a grid was recorded");
    let grid = OccupancyGrid::decode(&last.payload).expect("grid");
    let out = dir.path().join("exported");
    let output = armor(&[
        os("export"),
        os("--ros-map"),
        recording.as_os_str(),
        os("-o"),
        out.as_os_str(),
    ]);
    assert!(output.status.success(), "{}", output_text(&output));
    let yaml = std::fs::read_to_string(out.join("map.yaml")).expect("map.yaml");
    assert!(yaml.contains("image: map.pgm"), "{yaml}");
    assert!(
        std::fs::read(out.join("map.pgm"))
            .expect("map.pgm")
            .starts_with(b"P5")
    );
    let (_, read) = ros_map::load(&out.join("map.yaml"), &mut |path| std::fs::read(path))
        .expect("the map loads");
    let expected = OccupancyGrid {
        cells: grid
            .cells
            .iter()
            .map(|&value| ros_map::as_saved(value))
            .collect(),
        ..grid.clone()
    };
    assert_eq!(read, expected);
    assert!(
        expected.cells.contains(&100) && expected.cells.contains(&0),
        "the mapper saw walls and floor"
    );
    // A recording with no grid is refused in words.
    let empty = dir.path().join("none.mcap");
    std::fs::write(&empty, b"not a recording").expect("write");
    let output = armor(&[
        os("export"),
        os("--ros-map"),
        empty.as_os_str(),
        os("-o"),
        out.as_os_str(),
    ]);
    assert!(!output.status.success());
    assert!(
        output_text(&output).contains("not an MCAP file"),
        "{}",
        output_text(&output)
    );
}

#[test]
fn a_plans_base_map_is_found_beside_it_and_one_missing_fails_the_check_where_it_is_named() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let plan = yard_plan_on(dir.path(), "yard.world");
    let original = std::fs::read_to_string(&plan).expect("plan");
    let with_map = |href: &str| {
        let text = original.replacen(
            "  <navigation",
            &format!("  <basemap href=\"{href}\"/>\n  <navigation"),
            1,
        );
        std::fs::write(&plan, &text).expect("write");
        text
    };
    let text = with_map("survey.mbtiles");
    let elsewhere = tempfile::tempdir().expect("temporary folder");
    let output = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    assert_refused(
        &output,
        &plan,
        line_of(&text, "<basemap"),
        &["the base map", "cannot find `survey.mbtiles`"],
    );
    // A folder of tiles beside the plan opens, from any current folder.
    std::fs::create_dir_all(dir.path().join("tiles/18/0")).expect("folder");
    std::fs::write(dir.path().join("tiles/18/0/0.png"), b"png").expect("tile");
    with_map("tiles");
    let output = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    assert!(output.status.success(), "{}", output_text(&output));
    // A file that is not an MBTiles database is refused in words.
    std::fs::write(dir.path().join("notes.mbtiles"), "notes").expect("write");
    let text = with_map("notes.mbtiles");
    let output = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    assert_refused(
        &output,
        &plan,
        line_of(&text, "<basemap"),
        &["not an MBTiles file"],
    );
}

#[test]
fn a_plans_world_is_found_beside_it_and_a_broken_map_is_refused_with_its_place() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let plan = yard_plan_on(dir.path(), "yard.world");
    let text = std::fs::read_to_string(&plan).expect("plan").replacen(
        "<plan name=",
        "<plan world=\"room.yaml\" name=",
        1,
    );
    std::fs::write(&plan, &text).expect("write");
    let elsewhere = tempfile::tempdir().expect("temporary folder");
    let output = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    assert_refused(
        &output,
        &plan,
        line_of(&text, "<plan "),
        &["the world", "cannot find `room.yaml`"],
    );
    // Beside the plan, a map whose resolution is negative: the YAML's own place is given.
    std::fs::write(dir.path().join("room.pgm"), "P2 2 2 255 254 254 254 254\n").expect("write");
    let yaml = dir.path().join("room.yaml");
    std::fs::write(
        &yaml,
        "image: room.pgm\nresolution: -0.5\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .expect("write");
    let output = armor_in(elsewhere.path(), &[os("check"), plan.as_os_str()]);
    let all = output_text(&output);
    assert!(!output.status.success(), "{all}");
    assert!(
        all.contains(&format!("{}:2:13: `resolution`", yaml.display())),
        "{all}"
    );
}

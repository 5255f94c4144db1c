//! Plans whose rehearsal the suites judge (`tests/tests/rehearsal.rs` from the command line,
//! `tests/tests/studio_run.rs` in the studio's Run view): a leg across the yard whose robot's
//! odometry lies by a metre, or tells the truth.

use std::path::{Path, PathBuf};

use armor_model::geo::LatLon;
use armor_model::world::{Point, World};

use crate::workspace_root;

/// `points` in the world frame of `world`, as a plan writes them (latitude, longitude).
pub fn lat_lon(world: &World, point: Point) -> String {
    let (lat, lon) = world.origin_lat_lon();
    let at = LatLon::from_local(point, LatLon::new(lat, lon));
    format!("lat=\"{:.9}\" lon=\"{:.9}\"", at.lat_deg, at.lon_deg)
}

pub fn world_file(name: &str) -> PathBuf {
    workspace_root().join("assets/worlds").join(name)
}

pub fn load_world(file: &Path) -> World {
    World::parse(
        &std::fs::read_to_string(file).unwrap(),
        &file.display().to_string(),
    )
    .unwrap()
}

/// A plan of one leg across the yard, 12 m east from (4, 4) to (16, 4), with a no-go area whose
/// north side runs 1 m south of the leg (margin 0.2 m, so that the leg is planned straight), and
/// its system, written into `dir`. With `lie`, the follower drives by a second simulator's
/// odometry, which starts where the plan starts while the true robot starts a metre south of
/// it: both get the same commands, so the robot believes it drives the leg while in truth it
/// drives a metre south of it, its footprint over the area's edge. Without, the follower drives
/// by the true robot's own exact odometry. Returns the plan's file.
pub fn yard_leg(dir: &Path, lie: bool) -> PathBuf {
    let yard = world_file("yard.world");
    let world = load_world(&yard);
    let true_world = if lie {
        let text = std::fs::read_to_string(&yard).unwrap();
        assert!(
            text.contains("start    4 4 0 "),
            "the yard starts at (4, 4)"
        );
        let shifted = dir.join("yard-a-metre-south.world");
        std::fs::write(&shifted, text.replace("start    4 4 0 ", "start    4 3 0 ")).unwrap();
        shifted
    } else {
        yard.clone()
    };
    let exact = r#"<param name="odom_noise_dist" value="0"/>
        <param name="odom_noise_rot" value="0"/>
        <param name="odom_noise_drift" value="0"/>"#;
    let (odometer, links) = if lie {
        (
            format!(
                r#"<module name="odometer" type="sim">
                     <param name="world" value="{}"/>{exact}
                   </module>"#,
                yard.display()
            ),
            r#"<link from="odometer.odometry" to="follower.odometry"/>
               <link from="follower.cmd_desired" to="odometer.cmd_vel"/>"#,
        )
    } else {
        (
            String::new(),
            r#"<link from="sim.odometry" to="follower.odometry"/>"#,
        )
    };
    let system = format!(
        r#"<system name="yard-leg">
  <module name="sim" type="sim">
    <param name="world" value="{true_world}"/>{exact}
  </module>
  {odometer}
  <module name="follower" type="follower">
    <param name="world" value="{yard}"/>
    <param name="goal_x_m" value="16"/>
    <param name="goal_y_m" value="4"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="sim.cmd_vel"/>
  {links}
</system>
"#,
        true_world = true_world.display(),
        yard = yard.display(),
    );
    let system_file = dir.join("system.xml");
    std::fs::write(&system_file, system).unwrap();
    let corners = [(9.0, 1.5), (11.0, 1.5), (11.0, 3.0), (9.0, 3.0)]
        .map(|(x, y)| format!("    <point {}/>\n", lat_lon(&world, Point::new(x, y))))
        .concat();
    let plan = format!(
        r#"<plan name="yard-leg" system="{}">
  <navigation speed_mps="0.5"/>
  <waypoint name="home" {}/>
  <waypoint name="gate" {}/>
  <leg name="advance" from="home" to="gate"/>
  <area name="ditch" kind="no-go" margin_m="0.2">
{corners}  </area>
</plan>
"#,
        system_file.display(),
        lat_lon(&world, Point::new(4.0, 4.0)),
        lat_lon(&world, Point::new(16.0, 4.0)),
    );
    let plan_file = dir.join("plan.xml");
    std::fs::write(&plan_file, plan).unwrap();
    plan_file
}

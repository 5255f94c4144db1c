//! What a simulated plan run is judged by and against: the simulator's true pose (the output
//! `pose_truth` of a module of the system, the bundled `sim`), the plan's no-go areas and the
//! robot's radius as the plan was compiled, and the navigation module's tolerance. The judging
//! itself is `armor_model::rehearsal`'s, fed by the run's node (`progress.rs`); this file finds
//! its inputs in the loaded system and plan, and writes its verdict for the report.

use std::collections::BTreeMap;

use armor_model::SystemConfig;
use armor_model::plan::{Compiled, Plan};
use armor_model::rehearsal::{Judge, NoGoArea, Rules, Verdict};
use armor_module_api::ModuleDescription;
use serde_json::json;

/// The output a simulator publishes its true pose on.
pub const TRUTH_OUTPUT: &str = "pose_truth";
/// The navigation module's parameter that says how close to the goal is arrived.
pub const TOLERANCE_PARAM: &str = "tolerance_m";
/// The tolerance assumed when the navigation module has none: the follower's default.
pub const DEFAULT_TOLERANCE_M: f64 = 0.3;

/// The data name of the simulator's true pose (`sim.pose_truth`): the first module of the
/// system whose description has a `pose_truth` output of type `Pose2D`. `None`: not a simulated
/// run, and nothing to judge by.
pub fn truth_source(
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> Option<String> {
    system.modules.iter().find_map(|module| {
        let description = descriptions.get(&module.module_type)?;
        description
            .outputs
            .iter()
            .any(|port| port.name == TRUTH_OUTPUT && port.data_type == "Pose2D")
            .then(|| format!("{}.{TRUTH_OUTPUT}", module.name))
    })
}

/// The navigation module's tolerance: the value the system file gives it, else its module's
/// default, else [`DEFAULT_TOLERANCE_M`].
pub fn tolerance_m(
    plan: &Plan,
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> f64 {
    let module = system.module(&plan.navigation.module);
    let given = module
        .and_then(|module| module.param(TOLERANCE_PARAM))
        .map(|param| param.value.clone());
    let default = || {
        descriptions
            .get(&module?.module_type)?
            .params
            .iter()
            .find(|param| param.name == TOLERANCE_PARAM)?
            .default
            .clone()
    };
    given
        .or_else(default)
        .and_then(|value| value.trim().parse::<f64>().ok())
        .filter(|tolerance| tolerance.is_finite() && *tolerance > 0.0)
        .unwrap_or(DEFAULT_TOLERANCE_M)
}

/// The judge of a run of `plan` as `compiled`: its no-go areas, the robot's radius the legs
/// were planned for, the navigation module's tolerance.
pub fn judge(
    plan: &Plan,
    compiled: &Compiled,
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> Judge {
    Judge::new(
        areas(compiled),
        Rules {
            radius_m: compiled.robot.radius_m,
            tolerance_m: tolerance_m(plan, system, descriptions),
        },
    )
}

/// The no-go areas of `compiled` as the truth judges them: their outlines, not their margins.
pub fn areas(compiled: &Compiled) -> Vec<NoGoArea> {
    compiled
        .keepouts
        .iter()
        .map(|keepout| NoGoArea {
            name: keepout.name.clone(),
            polygon: keepout.polygon.clone(),
        })
        .collect()
}

/// The verdict as the report's `rehearsal` section, saying what it was judged by.
pub fn report(verdict: &Verdict, source: &str) -> serde_json::Value {
    json!({
        "judged_by": format!("the simulator's truth ({source})"),
        "verdict": if verdict.passed { "passed" } else { "failed" },
        "passed": verdict.passed,
        "failures": verdict.failures,
        "true_poses": verdict.true_poses,
        "robot_radius_m": verdict.robot_radius_m,
        "tolerance_m": verdict.tolerance_m,
        "allowed_m": verdict.allowed_m,
        "arrivals": verdict.arrivals,
        "no_go_areas": verdict.areas,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::describe::PortSpec;
    use armor_module_api::{ParamSpec, ParamType};

    fn descriptions() -> BTreeMap<String, ModuleDescription> {
        let mut sim = ModuleDescription::new("sim", "the simulator");
        sim.outputs.push(PortSpec {
            name: "pose_truth".to_owned(),
            data_type: "Pose2D".to_owned(),
            doc: String::new(),
        });
        let mut follower = ModuleDescription::new("follower", "drives");
        follower
            .params
            .push(ParamSpec::new("tolerance_m", ParamType::Float, "tolerance").default("0.25"));
        let mut other = ModuleDescription::new("other", "a pose of another type");
        other.outputs.push(PortSpec {
            name: "pose_truth".to_owned(),
            data_type: "Odometry".to_owned(),
            doc: String::new(),
        });
        [sim, follower, other]
            .into_iter()
            .map(|description| (description.module_type.clone(), description))
            .collect()
    }

    fn system(modules: &str) -> SystemConfig {
        SystemConfig::parse(&format!(r#"<system name="s">{modules}</system>"#)).expect("valid")
    }

    #[test]
    fn the_truth_comes_from_the_module_that_publishes_a_pose_truth() {
        let descriptions = descriptions();
        let simulated = system(
            r#"<module name="other" type="other"/><module name="world" type="sim"/>
               <module name="follower" type="follower"/>"#,
        );
        assert_eq!(
            truth_source(&simulated, &descriptions).as_deref(),
            Some("world.pose_truth")
        );
        let real = system(r#"<module name="other" type="other"/>"#);
        assert_eq!(truth_source(&real, &descriptions), None);
    }

    #[test]
    fn the_tolerance_is_the_system_s_else_the_module_s_default_else_the_follower_s() {
        let descriptions = descriptions();
        let plan = Plan::default();
        let given = system(
            r#"<module name="follower" type="follower"><param name="tolerance_m" value="0.05"/></module>"#,
        );
        assert_eq!(tolerance_m(&plan, &given, &descriptions), 0.05);
        let default = system(r#"<module name="follower" type="follower"/>"#);
        assert_eq!(tolerance_m(&plan, &default, &descriptions), 0.25);
        let unknown = system(r#"<module name="follower" type="mystery"/>"#);
        assert_eq!(
            tolerance_m(&plan, &unknown, &descriptions),
            DEFAULT_TOLERANCE_M
        );
    }
}

//! `stop`: the behaviour of last resort (JDE's `stop` schema): it always applies while active
//! and proposes zero, `rate_hz` times a second of run time, so that an arbiter given it at the
//! lowest priority holds the robot still when no other behaviour applies.

use armor_module_api::types::Twist;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

pub const TYPE: &str = "stop";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "The behaviour of last resort: always applicable while active, it proposes zero at a \
         fixed rate.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .output::<Twist>(
        "cmd_vel",
        "zero, rate_hz times per second of run time while active",
    )
    .param(
        ParamSpec::new(
            "rate_hz",
            ParamType::Float,
            "proposals per second of run time (greater than 0, at most 1000; tunable live)",
        )
        .above(0.0)
        .max(1000.0)
        .unit("Hz")
        .default("10"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let output = node.output::<Twist>("cmd_vel")?;
    let mut rate_hz = node.param::<f64>("rate_hz")?;
    let mut next_tick = node.timestamp();
    loop {
        let event = if node.is_active() {
            node.set_applicable(true);
            let deadline = node.clock().instant_at(next_tick);
            node.next_event_until(deadline)?
        } else {
            node.next_event(None)?
        };
        match event {
            Event::Timeout if node.is_active() => {
                next_tick = node.timestamp() + 1.0 / rate_hz;
                node.send(&output, &Twist::default())?;
            }
            Event::Start => next_tick = node.timestamp(),
            Event::ParamsChanged(_) => match node.param::<f64>("rate_hz") {
                Ok(new) => rate_hz = new,
                Err(err) => tracing::error!("{err}; keeping the previous rate"),
            },
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    #[test]
    fn always_applies_while_active_and_proposes_zero() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        bench.script([
            Step::Timeouts(3),
            Step::Active(false),
            Step::Active(true),
            Step::Timeouts(1),
        ]);
        body(bench.node()).expect("body");
        assert_eq!(
            bench.sent::<Twist>("cmd_vel").expect("sent"),
            [Twist::default(); 4]
        );
        assert_eq!(bench.behaviour(), ["applicable"]);
    }
}

//! Conditions on a parameter that its declared range cannot state (greater than another
//! parameter), refused in the words the module API uses for ranges: "parameter `influence_m`
//! must be greater than stop_m (0.35 m), not 0.2".
//!
//! A parameter's range, `nonzero` and choices are declared once in its `ParamSpec`
//! (`.above(0.0).max(1000.0)`), written in the describe format, checked by `armor check`, the
//! studio and the plan compiler, and enforced by `Node::param` where the module reads the value.
//! Only what depends on other values goes through [`float_where`]. NaN and infinities are always
//! refused.

use armor_module_api::Node;

use crate::BodyError;

/// Reads a float parameter that must be finite and `accept`ed; `meaning` says what is accepted
/// ("non-zero", "greater than stop_m (0.35 m)").
pub fn float_where(
    node: &Node,
    name: &str,
    accept: impl Fn(f64) -> bool,
    meaning: &str,
) -> Result<f64, BodyError> {
    let value: f64 = node.param(name)?;
    if value.is_finite() && accept(value) {
        Ok(value)
    } else {
        Err(refusal(name, meaning, value))
    }
}

fn refusal(name: &str, meaning: &str, value: impl std::fmt::Display) -> BodyError {
    format!("parameter `{name}` must be {meaning}, not {value}").into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::{ModuleSpec, ParamSpec, ParamType};

    fn node_with(value: &str) -> armor_module_api::testing::TestBench {
        let spec = ModuleSpec::new("t", "test").param(
            ParamSpec::new("x", ParamType::Float, "x")
                .unit("m")
                .above(0.0),
        );
        armor_module_api::testing::TestBench::new(&spec, &[("x", value)]).expect("bench")
    }

    #[test]
    fn conditions_beyond_the_declared_range_are_refused_in_words() {
        let mut bench = node_with("0.5");
        let err = float_where(bench.node(), "x", |v| v > 1.0, "greater than stop_m (1 m)")
            .expect_err("too small");
        assert_eq!(
            err.to_string(),
            "parameter `x` must be greater than stop_m (1 m), not 0.5"
        );
        let mut bench = node_with("2");
        assert_eq!(
            float_where(bench.node(), "x", |v| v > 1.0, "greater than stop_m (1 m)").ok(),
            Some(2.0)
        );
    }

    #[test]
    fn the_declared_range_is_enforced_where_the_value_is_read() {
        let mut bench = node_with("0");
        let refused = bench
            .node()
            .param::<f64>("x")
            .map_err(|err| err.to_string());
        assert_eq!(
            refused,
            Err("parameter `x` must be greater than 0 m, not 0".to_owned())
        );
        let mut bench = node_with("0.25");
        assert_eq!(bench.node().param::<f64>("x").ok(), Some(0.25));
    }
}

//! Reading numeric parameters with their allowed range, refused in the same words by every
//! module: "parameter `rate_hz` must be greater than 0 Hz and at most 1000 Hz, not 0".
//!
//! A module states the range once ([`FloatRange`]) and reads the value with [`float_in`]; a
//! condition that is no range (non-zero, greater than another parameter) goes through
//! [`float_where`] with its own words. NaN and infinities are always refused.

use armor_module_api::Node;

use crate::BodyError;

/// The lower end of a [`FloatRange`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Lower {
    None,
    Above(f64),
    AtLeast(f64),
}

/// The finite values a float parameter accepts, with the unit to name its bounds in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatRange {
    lower: Lower,
    upper: Option<f64>,
    unit: &'static str,
}

impl FloatRange {
    /// Any finite number.
    pub const fn any(unit: &'static str) -> Self {
        Self {
            lower: Lower::None,
            upper: None,
            unit,
        }
    }

    /// Strictly greater than `lower`.
    pub const fn above(lower: f64, unit: &'static str) -> Self {
        Self {
            lower: Lower::Above(lower),
            upper: None,
            unit,
        }
    }

    /// `lower` or more.
    pub const fn at_least(lower: f64, unit: &'static str) -> Self {
        Self {
            lower: Lower::AtLeast(lower),
            upper: None,
            unit,
        }
    }

    /// The same range, also at most `upper`.
    pub const fn at_most(self, upper: f64) -> Self {
        Self {
            upper: Some(upper),
            ..self
        }
    }

    pub fn contains(&self, value: f64) -> bool {
        let above = match self.lower {
            Lower::None => true,
            Lower::Above(lower) => value > lower,
            Lower::AtLeast(lower) => value >= lower,
        };
        value.is_finite() && above && self.upper.is_none_or(|upper| value <= upper)
    }

    /// The range in words: `greater than 0 Hz and at most 1000 Hz`, `between 0° and 45°`.
    pub fn describe(&self) -> String {
        let quantity = |value: f64| match self.unit {
            "" | "°" => format!("{value}{}", self.unit),
            unit => format!("{value} {unit}"),
        };
        match (self.lower, self.upper) {
            (Lower::None, None) => "a finite number".to_owned(),
            (Lower::None, Some(upper)) => format!("at most {}", quantity(upper)),
            (Lower::Above(lower), None) => format!("greater than {}", quantity(lower)),
            (Lower::Above(lower), Some(upper)) => format!(
                "greater than {} and at most {}",
                quantity(lower),
                quantity(upper)
            ),
            (Lower::AtLeast(lower), None) => format!("{} or more", quantity(lower)),
            (Lower::AtLeast(lower), Some(upper)) => {
                format!("between {} and {}", quantity(lower), quantity(upper))
            }
        }
    }
}

/// Reads a float parameter that must lie in `range`.
pub fn float_in(node: &Node, name: &str, range: FloatRange) -> Result<f64, BodyError> {
    let value: f64 = node.param(name)?;
    if range.contains(value) {
        Ok(value)
    } else {
        Err(refusal(name, &range.describe(), value))
    }
}

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

/// Reads an integer parameter that must be at least `min` (which is not negative).
pub fn int_at_least(node: &Node, name: &str, min: u64, meaning: &str) -> Result<u64, BodyError> {
    let value: i64 = node.param(name)?;
    match u64::try_from(value) {
        Ok(value) if value >= min => Ok(value),
        _ => Err(refusal(name, meaning, value)),
    }
}

/// Reads an integer parameter that must lie in `range`.
pub fn int_in(
    node: &Node,
    name: &str,
    range: std::ops::RangeInclusive<i64>,
) -> Result<i64, BodyError> {
    let value: i64 = node.param(name)?;
    if range.contains(&value) {
        Ok(value)
    } else {
        let meaning = format!("between {} and {}", range.start(), range.end());
        Err(refusal(name, &meaning, value))
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
        let spec = ModuleSpec::new("t", "test").param(ParamSpec::new("x", ParamType::Float, "x"));
        armor_module_api::testing::TestBench::new(&spec, &[("x", value)]).expect("bench")
    }

    #[test]
    fn ranges_accept_and_refuse_in_words() {
        let check = |range: FloatRange, value: &str, expected: Result<f64, &str>| {
            let mut bench = node_with(value);
            let got = float_in(bench.node(), "x", range).map_err(|err| err.to_string());
            assert_eq!(got, expected.map_err(str::to_owned), "{range:?} {value}");
        };
        let rate = FloatRange::above(0.0, "Hz").at_most(1000.0);
        check(rate, "1000", Ok(1000.0));
        check(
            rate,
            "0",
            Err("parameter `x` must be greater than 0 Hz and at most 1000 Hz, not 0"),
        );
        check(
            FloatRange::at_least(0.0, "°").at_most(45.0),
            "46",
            Err("parameter `x` must be between 0° and 45°, not 46"),
        );
        check(
            FloatRange::at_least(0.0, ""),
            "-1",
            Err("parameter `x` must be 0 or more, not -1"),
        );
        // NaN and infinities never get this far: the bench refuses them as not finite.
        check(
            FloatRange::above(0.0, "s"),
            "0",
            Err("parameter `x` must be greater than 0 s, not 0"),
        );
        check(
            FloatRange::any("").at_most(2.0),
            "2.5",
            Err("parameter `x` must be at most 2, not 2.5"),
        );
        check(FloatRange::any("m"), "-3.5", Ok(-3.5));
        let mut bench = node_with("0");
        let err = float_where(bench.node(), "x", |v| v != 0.0, "non-zero").expect_err("zero");
        assert_eq!(err.to_string(), "parameter `x` must be non-zero, not 0");
    }
}

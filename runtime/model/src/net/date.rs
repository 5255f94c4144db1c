//! Dates as RFC 3339 writes them (`2026-11-22T20:00:00Z`, `2026-11-22T21:00:00.5+01:00`), to and
//! from seconds since 1970-01-01T00:00:00Z. Only the form that XSD's `xs:dateTime` also accepts
//! (see `assets/schema/mission.xsd`): four-digit year from 0001, upper-case `T` and `Z`, seconds
//! 00 to 59, offsets up to ±14:00.

const FORM: &str =
    "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm";

/// Days from 1970-01-01 to the given day of the proleptic Gregorian calendar.
fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let year = if month <= 2 { year - 1 } else { year };
    let era = if year >= 0 { year } else { year - 399 } / 400;
    let year_of_era = year - era * 400;
    let month_from_march = (month + 9) % 12;
    let day_of_year = (153 * month_from_march + 2) / 5 + day - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

/// The day of the proleptic Gregorian calendar `days` after 1970-01-01: (year, month, day).
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let days = days + 719_468;
    let era = if days >= 0 { days } else { days - 146_096 } / 146_097;
    let day_of_era = days - era * 146_097;
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_from_march = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_from_march + 2) / 5 + 1;
    let month = if month_from_march < 10 {
        month_from_march + 3
    } else {
        month_from_march - 9
    };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

fn is_leap(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i64, month: i64) -> i64 {
    match month {
        2 if is_leap(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// The number written with exactly `len` ASCII digits at `at`, if there is one.
fn digits(text: &str, at: usize, len: usize) -> Option<i64> {
    let part = text.get(at..at + len)?;
    if part.bytes().all(|b| b.is_ascii_digit()) {
        part.parse().ok()
    } else {
        None
    }
}

/// Seconds since 1970-01-01T00:00:00Z, or why the text is not a date.
pub fn parse_rfc3339(text: &str) -> Result<f64, String> {
    let separators = [(4, b'-'), (7, b'-'), (10, b'T'), (13, b':'), (16, b':')];
    let bytes = text.as_bytes();
    if separators
        .iter()
        .any(|&(at, separator)| bytes.get(at) != Some(&separator))
    {
        return Err(FORM.to_owned());
    }
    let (Some(year), Some(month), Some(day), Some(hour), Some(minute), Some(second)) = (
        digits(text, 0, 4),
        digits(text, 5, 2),
        digits(text, 8, 2),
        digits(text, 11, 2),
        digits(text, 14, 2),
        digits(text, 17, 2),
    ) else {
        return Err(FORM.to_owned());
    };
    let mut rest = text.get(19..).unwrap_or_default();
    let mut fraction = 0.0;
    if let Some(after_dot) = rest.strip_prefix('.') {
        let len = after_dot.bytes().take_while(u8::is_ascii_digit).count();
        if len == 0 {
            return Err(format!("{FORM} (a `.` must be followed by digits)"));
        }
        let (fraction_digits, after) = after_dot.split_at(len);
        fraction = format!("0.{fraction_digits}")
            .parse::<f64>()
            .map_err(|_| FORM.to_owned())?;
        rest = after;
    }
    let offset_minutes = match rest {
        "Z" => 0,
        _ => {
            let sign = match rest.as_bytes().first() {
                Some(b'+') => 1,
                Some(b'-') => -1,
                _ => return Err(format!("{FORM} (the time zone is missing or malformed)")),
            };
            let (Some(hours), true, Some(minutes), 6) = (
                digits(rest, 1, 2),
                rest.as_bytes().get(3) == Some(&b':'),
                digits(rest, 4, 2),
                rest.len(),
            ) else {
                return Err(format!("{FORM} (the time zone is malformed)"));
            };
            if minutes > 59 || hours * 60 + minutes > 14 * 60 {
                return Err(format!(
                    "the offset {rest} does not exist (offsets go from -14:00 to +14:00)"
                ));
            }
            sign * (hours * 60 + minutes)
        }
    };
    if year == 0 {
        return Err("there is no year 0000 (years go from 0001)".to_owned());
    }
    if !(1..=12).contains(&month) {
        return Err(format!("there is no month {month:02}"));
    }
    if day < 1 || day > days_in_month(year, month) {
        return Err(format!(
            "there is no day {day:02} in {year:04}-{month:02} ({} days)",
            days_in_month(year, month)
        ));
    }
    if hour > 23 || minute > 59 || second > 59 {
        return Err(format!(
            "there is no time {hour:02}:{minute:02}:{second:02} (from 00:00:00 to 23:59:59)"
        ));
    }
    let seconds = days_from_civil(year, month, day) * 86_400 + hour * 3600 + minute * 60 + second
        - offset_minutes * 60;
    Ok(seconds as f64 + fraction)
}

/// The date of `unix_secs` in UTC, in the form [`parse_rfc3339`] reads back to the same value.
/// Values outside the years 0001 to 9999 (or not finite) are written as plain numbers, which
/// are not dates.
pub fn format_rfc3339(unix_secs: f64) -> String {
    let first = days_from_civil(1, 1, 1) * 86_400;
    let end = days_from_civil(10_000, 1, 1) * 86_400;
    if !unix_secs.is_finite() || unix_secs < first as f64 || unix_secs >= end as f64 {
        return format!("{unix_secs}");
    }
    let whole = unix_secs.floor();
    // Exact: `whole` and `unix_secs` are within a factor of two or share their exponent range.
    let fraction = unix_secs - whole;
    let seconds = whole as i64;
    let (year, month, day) = civil_from_days(seconds.div_euclid(86_400));
    let in_day = seconds.rem_euclid(86_400);
    let fraction = if fraction > 0.0 {
        // `{}` of a number in (0, 1) is `0.` and its shortest exact digits, never an exponent.
        format!("{fraction}").trim_start_matches('0').to_owned()
    } else {
        String::new()
    };
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}{fraction}Z",
        in_day / 3600,
        in_day / 60 % 60,
        in_day % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str, expected: Result<f64, &str>) {
        assert_eq!(
            parse_rfc3339(text),
            expected.map_err(str::to_owned),
            "{text}"
        );
    }

    #[test]
    fn dates_read() {
        check("1970-01-01T00:00:00Z", Ok(0.0));
        check("2026-11-22T20:00:00Z", Ok(1_795_377_600.0));
        check("2026-11-22T21:00:00+01:00", Ok(1_795_377_600.0));
        check("2026-11-22T18:30:00-01:30", Ok(1_795_377_600.0));
        check("2026-11-22T20:00:00.25Z", Ok(1_795_377_600.25));
        check("2000-02-29T00:00:00Z", Ok(951_782_400.0));
        check("1969-12-31T23:59:59.5Z", Ok(-0.5));
        check("0001-01-01T00:00:00Z", Ok(-62_135_596_800.0));
        check("9999-12-31T23:59:59Z", Ok(253_402_300_799.0));
        check("2026-11-22T20:00:00+14:00", Ok(1_795_327_200.0));
    }

    #[test]
    fn malformed_dates_say_why() {
        let form = Err(FORM);
        check("", form);
        check("yesterday", form);
        check("2026-11-22 20:00:00Z", form);
        check("2026-11-22t20:00:00Z", form);
        check("26-11-22T20:00:00Z", form);
        check("2026-1-22T20:00:00Z", form);
        check("+2026-11-22T20:00:00Z", form);
        check(
            "2026-11-22T20:00:00",
            Err(
                "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (the time zone is missing or malformed)",
            ),
        );
        check(
            "2026-11-22T20:00:00z",
            Err(
                "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (the time zone is missing or malformed)",
            ),
        );
        check(
            "2026-11-22T20:00:00+0100",
            Err(
                "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (the time zone is malformed)",
            ),
        );
        check(
            "2026-11-22T20:00:00.Z",
            Err(
                "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (a `.` must be followed by digits)",
            ),
        );
        check(
            "2026-11-22T20:00:00+14:30",
            Err("the offset +14:30 does not exist (offsets go from -14:00 to +14:00)"),
        );
        check("2026-13-01T00:00:00Z", Err("there is no month 13"));
        check(
            "2026-02-29T00:00:00Z",
            Err("there is no day 29 in 2026-02 (28 days)"),
        );
        check(
            "2026-11-22T24:00:00Z",
            Err("there is no time 24:00:00 (from 00:00:00 to 23:59:59)"),
        );
        check(
            "2016-12-31T23:59:60Z",
            Err("there is no time 23:59:60 (from 00:00:00 to 23:59:59)"),
        );
        check(
            "0000-01-01T00:00:00Z",
            Err("there is no year 0000 (years go from 0001)"),
        );
        check(
            "2026-11-22T20:00:00Zulu",
            Err(
                "expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (the time zone is missing or malformed)",
            ),
        );
    }

    #[test]
    fn dates_written_read_back_exactly() {
        assert_eq!(format_rfc3339(1_795_377_600.0), "2026-11-22T20:00:00Z");
        assert_eq!(format_rfc3339(1_795_377_600.25), "2026-11-22T20:00:00.25Z");
        assert_eq!(format_rfc3339(-0.5), "1969-12-31T23:59:59.5Z");
        for value in [
            0.0,
            1.0e-7,
            1_795_377_600.123_456_7,
            -62_135_596_800.0,
            253_402_300_799.999,
            951_782_399.999_999_9,
        ] {
            let text = format_rfc3339(value);
            assert_eq!(parse_rfc3339(&text), Ok(value), "{text}");
        }
        for not_a_date in [f64::NAN, f64::INFINITY, -1e20, 1e20] {
            assert!(parse_rfc3339(&format_rfc3339(not_a_date)).is_err());
        }
    }

    #[test]
    fn every_day_of_four_centuries_round_trips() {
        let start = days_from_civil(1900, 1, 1);
        let mut expected = (1900, 1, 1);
        for days in start..start + 146_097 {
            assert_eq!(civil_from_days(days), expected);
            assert_eq!(days_from_civil(expected.0, expected.1, expected.2), days);
            let (year, month, day) = expected;
            expected = if day < days_in_month(year, month) {
                (year, month, day + 1)
            } else if month < 12 {
                (year, month + 1, 1)
            } else {
                (year + 1, 1, 1)
            };
        }
    }
}

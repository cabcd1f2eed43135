//! UTC epochs: parsing, formatting and evenly stepped ranges.
//!
//! Epoch strings given by users are **UTC** (not TDB: reading a UTC string as TDB moves the Sun by
//! about 35 arcsec, since TDB − UTC ≈ 69 s and the Sun moves 0.5 arcsec/s across the lunar sky).
//! Accepted forms: `YYYY-MM-DD`, `YYYY-MM-DDTHH:MM`, `YYYY-MM-DDTHH:MM:SS[.fff]`, a space instead of
//! the `T`, and an optional trailing `Z` or ` UTC`; day-of-year dates (`2024-032T12:00`); SPICE's
//! month names (`2024 FEB 01 12:00:00`, `2024-FEB-01`); a UTC offset (`2024-02-01T14:00+02:00`);
//! another time scale by name (`2024-02-01T12:01:09.184 TDB`, `ET` = `TDB`, `TT`, `TAI`). Case does
//! not matter. Leap seconds (`23:59:60` on a real one) come from hifitime's table, which equals
//! NAIF's `naif0012.tls`. Outputs write UTC as ISO 8601 with `Z` ([`format_iso`]).

use hifitime::{Duration, Epoch, TimeScale, Unit};

use super::EphemError;

/// Parses an epoch string (see the module docs for the accepted forms): UTC unless it ends in a
/// time scale (`TDB`, `ET`, `TT`, `TAI`) or carries a UTC offset (`+02:00`).
pub fn parse_utc(text: &str) -> Result<Epoch, EphemError> {
    let bad = |why: &str| EphemError::BadEpoch {
        text: text.to_string(),
        why: why.to_string(),
    };
    // Every accepted form is ASCII; refusing the rest here keeps the byte slicing below on
    // character boundaries.
    if let Some(c) = text.chars().find(|c| !c.is_ascii()) {
        return Err(bad(&format!(
            "'{c}' is not part of any epoch format (ASCII only)"
        )));
    }
    let upper = text.trim().to_ascii_uppercase();
    let mut s = upper.as_str();
    let mut scale = TimeScale::UTC;
    for (suffix, sc) in [
        (" UTC", TimeScale::UTC),
        ("UTC", TimeScale::UTC),
        ("Z", TimeScale::UTC),
        (" TDB", TimeScale::TDB),
        (" ET", TimeScale::TDB),
        (" TT", TimeScale::TT),
        (" TAI", TimeScale::TAI),
    ] {
        if let Some(stripped) = s.strip_suffix(suffix) {
            s = stripped.trim_end();
            scale = sc;
            break;
        }
    }
    let normalised = normalise_date(s).map_err(|why| bad(&why))?;
    let (s, offset_s) = split_offset(&normalised).map_err(|why| bad(&why))?;
    if offset_s != 0 && scale != TimeScale::UTC {
        return Err(bad("give either a UTC offset or a time scale, not both"));
    }
    let epoch = parse_calendar(s, scale, &bad)?;
    Ok(epoch - Unit::Second * f64::from(offset_s))
}

/// The three-letter month names SPICE writes (`2024 JAN 01`).
const MONTHS: [&str; 12] = [
    "JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC",
];

/// Rewrites a SPICE-style date (`2024 JAN 01 12:00`, `2024-JAN-01`, `JAN 01 2024` is not taken)
/// or a day-of-year date (`2024-032T12:00`, `2024-032`) as `YYYY-MM-DD…` (uppercase input).
fn normalise_date(s: &str) -> Result<String, String> {
    let b = s.as_bytes();
    let year_first = b.len() >= 5 && b[..4].iter().all(u8::is_ascii_digit);
    if !year_first {
        return Ok(s.to_string());
    }
    let year = &s[..4];
    let rest = &s[5..];
    // Month name: YYYY[ -]MON[THNAME][ -]DD[ rest]
    if matches!(b[4], b' ' | b'-')
        && rest.len() >= 3
        && rest.as_bytes()[..3].iter().all(u8::is_ascii_alphabetic)
    {
        let name_len = rest.bytes().take_while(u8::is_ascii_alphabetic).count();
        let name = &rest[..name_len];
        let month = MONTHS
            .iter()
            .position(|m| name.starts_with(m))
            .ok_or_else(|| format!("unknown month '{name}'"))?;
        let after = rest[name_len..].trim_start_matches([' ', '-']);
        let day_len = after.bytes().take_while(u8::is_ascii_digit).count();
        if day_len == 0 || day_len > 2 {
            return Err("expected a day after the month".into());
        }
        let tail = after[day_len..].trim_start_matches(',');
        return Ok(format!(
            "{year}-{:02}-{:0>2}{tail}",
            month + 1,
            &after[..day_len]
        ));
    }
    // Day of year: YYYY-DDD followed by nothing, 'T' or ' '.
    let doy_len = rest.bytes().take_while(u8::is_ascii_digit).count();
    if b[4] == b'-' && doy_len == 3 && !rest[3..].starts_with('-') {
        let doy: u32 = rest[..3].parse().map_err(|_| "bad day of year")?;
        let y: i32 = year.parse().map_err(|_| "bad year")?;
        let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
        let lengths = [
            31,
            if leap { 29 } else { 28 },
            31,
            30,
            31,
            30,
            31,
            31,
            30,
            31,
            30,
            31,
        ];
        if doy == 0 || doy > lengths.iter().sum::<u32>() {
            return Err(format!("day of year {doy} is out of range"));
        }
        let (mut month, mut day) = (0, doy);
        while day > lengths[month] {
            day -= lengths[month];
            month += 1;
        }
        return Ok(format!("{year}-{:02}-{day:02}{}", month + 1, &rest[3..]));
    }
    Ok(s.to_string())
}

/// Splits a trailing UTC offset (`+02:00`, `-0530`, `+02`) off the time of day: the text without
/// it and the offset in seconds.
fn split_offset(s: &str) -> Result<(&str, i32), String> {
    let Some(t) = s.find(['T', ' ']) else {
        return Ok((s, 0));
    };
    let clock = &s[t + 1..];
    let Some(i) = clock.rfind(['+', '-']) else {
        return Ok((s, 0));
    };
    let off = &clock[i + 1..];
    let digits: String = off.chars().filter(|c| *c != ':').collect();
    if digits.is_empty()
        || !digits.bytes().all(|c| c.is_ascii_digit())
        || !matches!(digits.len(), 2 | 4)
    {
        return Err(format!("UTC offset '{}' is not ±HH:MM", &clock[i..]));
    }
    let h: i32 = digits[..2].parse().map_err(|_| "bad offset")?;
    let m: i32 = if digits.len() == 4 {
        digits[2..].parse().map_err(|_| "bad offset")?
    } else {
        0
    };
    if h > 14 || m > 59 {
        return Err(format!("UTC offset '{}' is out of range", &clock[i..]));
    }
    let sign = if clock.as_bytes()[i] == b'-' { -1 } else { 1 };
    Ok((s[..t + 1 + i].trim_end(), sign * (h * 3600 + m * 60)))
}

/// Parses `YYYY-MM-DD[(T| )HH:MM[:SS[.f]]]` in `scale`.
fn parse_calendar(
    s: &str,
    scale: TimeScale,
    bad: &dyn Fn(&str) -> EphemError,
) -> Result<Epoch, EphemError> {
    let (date, clock) = match s.find(['T', ' ']) {
        Some(i) => (&s[..i], &s[i + 1..]),
        None => (s, ""),
    };
    let mut date_parts = date.split('-');
    let (Some(y), Some(mo), Some(d), None) = (
        date_parts.next(),
        date_parts.next(),
        date_parts.next(),
        date_parts.next(),
    ) else {
        return Err(bad("expected YYYY-MM-DD[THH:MM[:SS]]"));
    };
    let num = |p: &str, what: &str| -> Result<u32, EphemError> {
        if p.is_empty() || !p.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad(&format!("{what} '{p}' is not a number")));
        }
        p.parse::<u32>()
            .map_err(|_| bad(&format!("{what} '{p}' is out of range")))
    };
    let year = num(y, "year")?;
    let month = num(mo, "month")?;
    let day = num(d, "day")?;
    let (mut hour, mut minute, mut second, mut nanos) = (0u32, 0u32, 0u32, 0u32);
    if !clock.is_empty() {
        let mut parts = clock.split(':');
        hour = num(parts.next().unwrap_or(""), "hour")?;
        minute = num(parts.next().ok_or_else(|| bad("expected HH:MM"))?, "minute")?;
        if let Some(sec) = parts.next() {
            let (whole, frac) = match sec.split_once('.') {
                Some((w, f)) => (w, Some(f)),
                None => (sec, None),
            };
            second = num(whole, "second")?;
            if let Some(frac) = frac {
                if frac.is_empty() || frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
                    return Err(bad("fractional seconds must have 1 to 9 digits"));
                }
                nanos = num(frac, "fraction")? * 10u32.pow(9 - frac.len() as u32);
            }
        }
        if parts.next().is_some() {
            return Err(bad("too many ':' fields"));
        }
    }
    if !(1..=12).contains(&month) || day == 0 || day > 31 || hour > 23 || minute > 59 || second > 60
    {
        return Err(bad("a field is out of range"));
    }
    let year = i32::try_from(year).map_err(|_| bad("year out of range"))?;
    if second == 60 && scale != TimeScale::UTC {
        return Err(bad("second 60 exists in UTC only"));
    }
    let at_second = |second: u32| {
        Epoch::maybe_from_gregorian(
            year,
            month as u8,
            day as u8,
            hour as u8,
            minute as u8,
            second as u8,
            nanos,
            scale,
        )
        .map_err(|e| bad(&e.to_string()))
    };
    let epoch = at_second(second)?;
    if second == 60 {
        // hifitime accepts a real leap second (and refuses others) but puts it on 23:59:59;
        // the leap second is the SI second after 23:59:59.
        let before = at_second(59)?;
        return Ok(before.to_time_scale(hifitime::TimeScale::TAI) + Unit::Second * 1);
    }
    Ok(epoch)
}

/// The UTC calendar fields of `epoch`, with a leap second written as second 60. hifitime's own
/// conversion is one second off around a leap second for epochs not stored in UTC, and has no
/// second 60, so the last two seconds of a day are placed here from TAI seconds.
fn leap_aware_gregorian(epoch: Epoch) -> (i32, u8, u8, u8, u8, u8, u32) {
    let g = epoch.to_gregorian_utc();
    let (_, _, _, h, mi, s, _) = g;
    let near_day_end = h == 23 && mi == 59 && s >= 58;
    let near_day_start = h == 0 && mi == 0 && s == 0;
    if !(near_day_end || near_day_start) {
        return g;
    }
    let tai = |e: Epoch| e.to_time_scale(hifitime::TimeScale::TAI).to_tai_seconds();
    let x = tai(epoch);
    // The day whose end may hold a leap second: this one, or the previous one at 00:00:00.
    let day_end = |e: Epoch| {
        let (y, mo, d, ..) = e.to_gregorian_utc();
        Epoch::maybe_from_gregorian_utc(y, mo, d, 23, 59, 59, 0).ok()
    };
    let candidate = if near_day_end {
        day_end(epoch)
    } else {
        day_end(epoch - Unit::Second * 2)
    };
    let Some(last) = candidate else {
        return g;
    };
    let midnight = last + Unit::Second * 1; // UTC-scale arithmetic: the next day's 00:00:00
    let (t_last, t_mid) = (tai(last), tai(midnight));
    if x < t_last || x >= t_mid {
        return g;
    }
    let (ly, lmo, ld, ..) = last.to_gregorian_utc();
    let into = x - t_last;
    let (sec, frac) = if into < 1.0 {
        (59, into)
    } else {
        (60, into - 1.0)
    };
    let ns = ((frac * 1e9).round() as u32).min(999_999_999);
    (ly, lmo, ld, 23, 59, sec, ns)
}

/// Formats an epoch as ISO 8601 UTC, `YYYY-MM-DDTHH:MM:SS` (with `.fff` when not whole seconds).
pub fn format_utc(epoch: Epoch) -> String {
    let (y, mo, d, h, mi, s, ns) = leap_aware_gregorian(epoch);
    if ns == 0 {
        format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}")
    } else {
        format!(
            "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:03}",
            ns / 1_000_000
        )
    }
}

/// Formats an epoch as ISO 8601 UTC with the zone, `YYYY-MM-DDTHH:MM:SS[.fff]Z`: what every
/// output file writes.
pub fn format_iso(epoch: Epoch) -> String {
    format!("{}Z", format_utc(epoch))
}

/// Parses a time step such as `30s`, `10m`, `1h`, `6h`, `1d` (a positive number followed by one of
/// `s`, `m`, `h`, `d`).
pub fn parse_step(text: &str) -> Result<Duration, EphemError> {
    let bad = |why: &str| EphemError::BadStep {
        text: text.to_string(),
        why: why.to_string(),
    };
    let s = text.trim();
    let split = s
        .find(|c: char| c.is_ascii_alphabetic())
        .ok_or_else(|| bad("missing unit (use s, m, h or d, e.g. 1h)"))?;
    let (value, unit) = s.split_at(split);
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| bad("expected a number followed by s, m, h or d"))?;
    let unit = match unit {
        "s" => Unit::Second,
        "m" | "min" => Unit::Minute,
        "h" => Unit::Hour,
        "d" => Unit::Day,
        other => return Err(bad(&format!("unknown unit '{other}' (use s, m, h or d)"))),
    };
    if !(value.is_finite() && value > 0.0) {
        return Err(bad("the step must be positive"));
    }
    let step = value * unit;
    if step < 1.0 * Unit::Second {
        return Err(bad("the step must be at least 1 s"));
    }
    Ok(step)
}

/// Upper bound on the number of epochs in one range, to catch typos such as a `1s` step over
/// decades before they exhaust memory.
pub const MAX_EPOCHS: usize = 20_000_000;

/// Evenly spaced UTC epochs from `start` to `stop` inclusive (when `stop` falls on the grid).
pub fn epoch_range(start: Epoch, stop: Epoch, step: Duration) -> Result<Vec<Epoch>, EphemError> {
    let n = epoch_count(start, stop, step)?;
    Ok((0..n).map(|i| start + step * (i as i64)).collect())
}

/// How many epochs [`epoch_range`] gives: the stop must not be before the start, and the count
/// must not exceed [`MAX_EPOCHS`].
pub fn epoch_count(start: Epoch, stop: Epoch, step: Duration) -> Result<usize, EphemError> {
    if stop < start {
        return Err(EphemError::BadRange {
            why: format!(
                "stop {} is before start {}",
                format_utc(stop),
                format_utc(start)
            ),
        });
    }
    let span_s = (stop - start).to_seconds();
    let step_s = step.to_seconds();
    let n = (span_s / step_s + 1e-9).floor() + 1.0;
    if n > MAX_EPOCHS as f64 {
        return Err(EphemError::BadRange {
            why: format!("{n:.0} epochs exceed the limit of {MAX_EPOCHS}; use a larger --step"),
        });
    }
    #[expect(
        clippy::cast_possible_truncation,
        reason = "n is bounded by MAX_EPOCHS above"
    )]
    Ok(n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_utc_forms() {
        let a = parse_utc("2024-01-03T00:00:00").unwrap();
        assert_eq!(a, parse_utc("2024-01-03").unwrap());
        assert_eq!(a, parse_utc("2024-01-03 00:00Z").unwrap());
        assert_eq!(a, parse_utc("2024-01-03T00:00:00 UTC").unwrap());
        let b = parse_utc("2024-01-03T12:34:56.5").unwrap();
        assert!(((b - a).to_seconds() - (12.0 * 3600.0 + 34.0 * 60.0 + 56.5)).abs() < 1e-9);
        assert_eq!(format_utc(b), "2024-01-03T12:34:56.500");
        assert_eq!(format_utc(a), "2024-01-03T00:00:00");
    }

    #[test]
    fn utc_is_not_tdb() {
        // TDB - UTC at 2024 = 37 leap seconds + 32.184 s (+ periodic terms below 2 ms).
        let e = parse_utc("2024-01-03T00:00:00").unwrap();
        let tdb_as_if_utc = Epoch::from_gregorian(2024, 1, 3, 0, 0, 0, 0, hifitime::TimeScale::TDB);
        let diff_s = (e - tdb_as_if_utc).to_seconds();
        assert!((diff_s - 69.184).abs() < 0.002, "TDB - UTC = {diff_s} s");
    }

    #[test]
    fn parses_the_forms_spice_users_type() {
        let a = parse_utc("2024-02-01T12:00:00").unwrap();
        for s in [
            "2024-032T12:00",
            "2024-032 12:00:00Z",
            "2024 FEB 01 12:00:00",
            "2024-feb-01 12:00",
            "2024 FEBRUARY 1 12:00 UTC",
            "2024-02-01T14:00+02:00",
            "2024-02-01T07:30:00-0430",
            "2024-02-01t12:00z",
        ] {
            assert_eq!(parse_utc(s).unwrap(), a, "{s}");
        }
        // Day 366 of a leap year; TDB = UTC + 32.184 s + 37 s (leap seconds of 2024) ± 1.7 ms.
        assert_eq!(
            parse_utc("2024-366").unwrap(),
            parse_utc("2024-12-31").unwrap()
        );
        let tdb = parse_utc("2024-02-01T12:01:09.184 TDB").unwrap();
        assert!(
            (tdb - a).to_seconds().abs() < 2e-3,
            "{}",
            (tdb - a).to_seconds()
        );
        assert_eq!(tdb, parse_utc("2024-02-01T12:01:09.184 ET").unwrap());
        let tt = parse_utc("2024-02-01T12:01:09.184 TT").unwrap();
        assert!((tt - a).to_seconds().abs() < 1e-6);
        assert_eq!(format_iso(a), "2024-02-01T12:00:00Z");
        for s in [
            "2023-366",
            "2024-000",
            "2024 FOO 01",
            "2024-02-01T12:00+25:00",
            "2024-02-01T12:00+02:00 TDB",
            "2016-12-31T23:59:60 TDB",
            "2024-02-01T12:00+2",
        ] {
            assert!(parse_utc(s).is_err(), "{s} should not parse");
        }
    }

    #[test]
    fn rejects_malformed_epochs() {
        for s in [
            "2024-13-01",
            "2024-01-32",
            "yesterday",
            "2024-01-03T25:00",
            "2024/01/03",
            "",
            // Multi-byte characters where the parser slices bytes (found by the fuzzer).
            "2025\u{201}-02T00:00:00",
            "2024-0\u{e9}2",
            "2024 F\u{c9}B 01",
        ] {
            assert!(parse_utc(s).is_err(), "{s} should not parse");
        }
    }

    #[test]
    fn steps_and_ranges() {
        assert_eq!(parse_step("1h").unwrap().to_seconds(), 3600.0);
        assert_eq!(parse_step("10m").unwrap().to_seconds(), 600.0);
        assert_eq!(parse_step("1d").unwrap().to_seconds(), 86400.0);
        assert!(parse_step("0h").is_err());
        assert!(parse_step("-1h").is_err());
        assert!(parse_step("5").is_err());
        assert!(parse_step("3y").is_err());
        let s = parse_utc("2024-01-01").unwrap();
        let r = epoch_range(
            s,
            parse_utc("2024-01-02").unwrap(),
            parse_step("6h").unwrap(),
        )
        .unwrap();
        assert_eq!(r.len(), 5);
        assert!(
            epoch_range(
                parse_utc("2024-01-02").unwrap(),
                s,
                parse_step("1h").unwrap()
            )
            .is_err()
        );
    }
}

#[cfg(test)]
mod leap_second_tests {
    use super::*;

    #[test]
    fn a_leap_second_is_its_own_instant() {
        let before = parse_utc("2016-12-31T23:59:59").unwrap();
        let leap = parse_utc("2016-12-31T23:59:60").unwrap();
        let after = parse_utc("2017-01-01T00:00:00").unwrap();
        let tai = |e: Epoch| e.to_time_scale(hifitime::TimeScale::TAI).to_tai_seconds();
        assert!((tai(leap) - tai(before) - 1.0).abs() < 1e-9, "{leap:?}");
        assert!((tai(after) - tai(leap) - 1.0).abs() < 1e-9);
        assert_eq!(format_utc(leap), "2016-12-31T23:59:60");
        assert_eq!(format_utc(before), "2016-12-31T23:59:59");
        assert_eq!(format_utc(after), "2017-01-01T00:00:00");
        assert_eq!(
            format_utc(parse_utc("2016-12-31T23:59:60.25").unwrap()),
            "2016-12-31T23:59:60.250"
        );
        let tai_leap = leap.to_time_scale(hifitime::TimeScale::TAI);
        assert_eq!(
            format_utc(tai_leap - Unit::Second * 1),
            "2016-12-31T23:59:59"
        );
        assert_eq!(
            format_utc(tai_leap + Unit::Second * 1),
            "2017-01-01T00:00:00"
        );
        assert_eq!(
            format_utc(parse_utc("2016-06-30T23:59:59").unwrap()),
            "2016-06-30T23:59:59"
        );
        assert!(
            parse_utc("2016-12-30T23:59:60").is_err(),
            "not a leap second"
        );
    }
}

//! `timestamps.txt` files: one `YYYY-MM-DD HH:MM:SS.nnnnnnnnn` line per frame (line k is
//! frame k), the KITTI raw-data convention KITTI-360 keeps for images and scans. Times are
//! read as UTC and held as nanoseconds since the Unix epoch.

use std::path::Path;

use super::error::Kitti360Error;
use super::text::{read_text, write_text};

const NS_PER_SEC: i64 = 1_000_000_000;
const SECS_PER_DAY: i64 = 86_400;

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date of a day count since 1970-01-01 (inverse of [`days_from_civil`]).
fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

fn days_in_month(y: i64, m: i64) -> i64 {
    days_from_civil(y + i64::from(m == 12), m % 12 + 1, 1) - days_from_civil(y, m, 1)
}

/// One timestamp line as nanoseconds since the epoch; `None` when it is malformed. The
/// fraction may have 0 to 9 digits.
pub fn parse_timestamp(line: &str) -> Option<i64> {
    let (date, time) = line.trim().split_once(' ')?;
    let mut d = date.split('-');
    let (y, mo, da) = (d.next()?, d.next()?, d.next()?);
    if d.next().is_some() || y.len() != 4 || mo.len() != 2 || da.len() != 2 {
        return None;
    }
    let num = |s: &str| -> Option<i64> {
        match s.bytes().all(|b| b.is_ascii_digit()) && !s.is_empty() {
            true => s.parse().ok(),
            false => None,
        }
    };
    let (y, mo, da) = (num(y)?, num(mo)?, num(da)?);
    let (hms, frac) = time.trim().split_once('.').unwrap_or((time.trim(), ""));
    let mut t = hms.split(':');
    let (h, mi, s) = (t.next()?, t.next()?, t.next()?);
    if t.next().is_some() || h.len() != 2 || mi.len() != 2 || s.len() != 2 || frac.len() > 9 {
        return None;
    }
    let (h, mi, s) = (num(h)?, num(mi)?, num(s)?);
    let ns = match frac.is_empty() {
        true => 0,
        false => num(frac)? * 10i64.pow(9 - frac.len() as u32),
    };
    let valid = (1..=12).contains(&mo)
        && (1..=days_in_month(y, mo)).contains(&da)
        && h < 24
        && mi < 60
        && s < 61;
    if !valid {
        return None;
    }
    let secs = days_from_civil(y, mo, da) * SECS_PER_DAY + h * 3600 + mi * 60 + s;
    // Nanoseconds in an i64 reach 2262-04-11: a later (or pre-1677) date is malformed too.
    secs.checked_mul(NS_PER_SEC)?.checked_add(ns)
}

/// Nanoseconds since the epoch as a KITTI timestamp line (no newline), nine fraction digits.
pub fn format_timestamp(ns: i64) -> String {
    let secs = ns.div_euclid(NS_PER_SEC);
    let frac = ns.rem_euclid(NS_PER_SEC);
    let (y, m, d) = civil_from_days(secs.div_euclid(SECS_PER_DAY));
    let sod = secs.rem_euclid(SECS_PER_DAY);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{frac:09}",
        sod / 3600,
        sod / 60 % 60,
        sod % 60
    )
}

/// Reads a timestamps file: entry k is frame k. A missing file is `Ok(None)` (the
/// timestamps are optional); trailing blank lines are ignored, any other bad line is a
/// parse error naming it.
pub fn read_timestamps(path: &Path) -> Result<Option<Vec<i64>>, Kitti360Error> {
    let text = match read_text(path) {
        Ok(text) => text,
        Err(Kitti360Error::MissingFile { .. }) => return Ok(None),
        Err(e) => return Err(e),
    };
    text.trim_end()
        .lines()
        .enumerate()
        .map(|(i, line)| {
            parse_timestamp(line).ok_or_else(|| {
                Kitti360Error::parse(path, i + 1, format!("`{line}` is not a timestamp"))
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// Writes one line per entry (entry k for frame k).
pub fn write_timestamps(path: &Path, stamps: &[i64]) -> Result<(), Kitti360Error> {
    let text: String = stamps
        .iter()
        .map(|&ns| format_timestamp(ns) + "\n")
        .collect();
    write_text(path, &text)
}

/// One timestamp per frame `0..=last` from the frames that have one: missing entries are
/// linearly interpolated between their neighbours (held constant past either end), so line
/// k stays frame k. Empty when `known` is.
pub fn fill_timestamps(known: &std::collections::BTreeMap<u32, i64>) -> Vec<i64> {
    let Some((&last, _)) = known.iter().next_back() else {
        return Vec::new();
    };
    (0..=last)
        .map(|k| {
            let before = known.range(..=k).next_back();
            let after = known.range(k..).next();
            match (before, after) {
                (Some((&a, &ta)), Some((&b, &tb))) if a != b => {
                    let f = (k - a) as f64 / (b - a) as f64;
                    ta + ((tb - ta) as f64 * f).round() as i64
                }
                (Some((_, &t)), _) | (None, Some((_, &t))) => t,
                (None, None) => 0,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kitti_timestamp_round_trips() {
        let line = "2013-05-28 08:46:02.482785814";
        let ns = parse_timestamp(line).unwrap();
        assert_eq!(ns, 1_369_730_762_482_785_814);
        assert_eq!(format_timestamp(ns), line);
        assert_eq!(format_timestamp(-1), "1969-12-31 23:59:59.999999999");
        assert_eq!(
            parse_timestamp("2013-05-28 08:46:02.5"),
            Some(ns - 482_785_814 + 500_000_000)
        );
        assert_eq!(parse_timestamp("2013-02-29 08:46:02.5"), None);
        assert_eq!(parse_timestamp("2013-05-28T08:46:02"), None);
    }

    /// Found by the `kitti_timestamps` fuzz target: a year past 2262 overflowed the i64
    /// nanoseconds (a panic with overflow checks, a wrapped stamp without).
    #[test]
    fn dates_beyond_i64_nanoseconds_are_malformed() {
        assert_eq!(parse_timestamp("3938-12-14 22:13:20.350"), None);
        assert_eq!(parse_timestamp("0001-01-01 00:00:00"), None);
        let last = parse_timestamp("2262-04-11 23:47:16.854775807");
        assert_eq!(last, Some(i64::MAX));
        assert_eq!(parse_timestamp("2262-04-11 23:47:16.854775808"), None);
        assert_eq!(parse_timestamp("1600-01-01 00:00:00"), None);
    }
}

//! Flag values in the node's units: a replay rate, seconds as nanoseconds.

use anyhow::Result;

use crate::bag::Rate;

/// The replay rate of a `--rate` value: 0 = as fast as possible, 1 = recorded, else a factor.
pub fn rate_of(rate: f64) -> Result<Rate> {
    Ok(match rate {
        0.0 => Rate::AsFastAsPossible,
        1.0 => Rate::Recorded,
        r if r.is_finite() && r > 0.0 => Rate::Factor(r),
        r => anyhow::bail!("--rate must be 0 (as fast as possible) or positive, not {r}"),
    })
}

/// `seconds` of a duration flag as nanoseconds: finite, from 0 to about 292 years, else an
/// error naming `flag`.
pub fn seconds_ns(seconds: f64, flag: &str) -> Result<i64> {
    anyhow::ensure!(
        seconds.is_finite() && (0.0..9.2e9).contains(&seconds),
        "{flag} must be a number of seconds from 0, not {seconds}"
    );
    Ok((seconds * 1e9) as i64)
}

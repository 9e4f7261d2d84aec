//! Snapshot queries for a part of the map: the selector parameters of a query on the
//! snapshot key, so a subscriber of a large map fetches the ground it needs in bounded
//! replies instead of the whole map.
//!
//! Parameters (zenoh selector syntax, `;` between them):
//! - `box=x0,y0,x1,y1`: the Gaussians whose centres lie in that world x-y box (metres, any
//!   height; `x0 <= x1`, `y0 <= y1`);
//! - or `around=x,y;radius=r`: the square of half side `r` around the point;
//! - `page_size=n` (optional): at most `n` Gaussians per reply (default and cap
//!   [`MAX_PAGE`]).
//!
//! The answer is one reply per page, each a `MapUpdate` snapshot message of that page's
//! Gaussians (in id order across pages) at the map's current sequence number, with a JSON
//! attachment `{"region": [x0, y0, x1, y1], "page": i, "pages": n, "gaussians": total}`; a
//! region with no Gaussian gets one empty page. The pages share the snapshot key, so the
//! query must turn zenoh's reply consolidation off (`ConsolidationMode::None`), or only the
//! last page arrives. Such a snapshot holds only the region: merge
//! it into a replica rather than replacing the replica with it. A query without parameters
//! gets the whole map, as before. A bad parameter gets an error reply naming it.

use glam::DVec2;

/// The most Gaussians in one reply (about 24 MB of `MapUpdate`).
pub const MAX_PAGE: usize = 250_000;
/// The largest box side, metres.
pub const MAX_SIDE_M: f64 = 100_000.0;

/// A region query, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionQuery {
    /// Lower corner, world x-y, metres.
    pub min: DVec2,
    /// Upper corner.
    pub max: DVec2,
    /// Gaussians per reply at most.
    pub page_size: usize,
}

/// Why a region query was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RegionError {
    /// A parameter this query does not take.
    #[error("unknown snapshot parameter `{0}` (use box=x0,y0,x1,y1 or around=x,y;radius=r, and page_size=n)")]
    Unknown(String),
    /// A value that does not parse or is out of range.
    #[error("snapshot parameter `{name}={value}`: {why}")]
    Bad {
        /// The parameter.
        name: &'static str,
        /// Its value as sent.
        value: String,
        /// What is wrong.
        why: &'static str,
    },
    /// Neither or both of `box` and `around`, or `around` without `radius`.
    #[error("a region query needs exactly one of box=x0,y0,x1,y1 and around=x,y;radius=r")]
    Shape,
}

/// `n` comma-separated finite numbers.
fn numbers(name: &'static str, value: &str, n: usize) -> Result<Vec<f64>, RegionError> {
    let bad = |why| RegionError::Bad {
        name,
        value: value.to_owned(),
        why,
    };
    let parsed: Vec<f64> = value
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad("not a list of numbers"))?;
    if parsed.len() != n {
        return Err(bad(match n {
            4 => "needs 4 numbers",
            2 => "needs 2 numbers",
            _ => "needs 1 number",
        }));
    }
    if !parsed.iter().all(|v| v.is_finite()) {
        return Err(bad("numbers must be finite"));
    }
    Ok(parsed)
}

impl RegionQuery {
    /// The query the parameters ask for: `None` when there are none (the whole map), an
    /// error naming the first bad one.
    pub fn parse<'a>(
        parameters: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> Result<Option<Self>, RegionError> {
        let (mut bbox, mut around, mut radius, mut page_size) = (None, None, None, None);
        let mut any = false;
        for (key, value) in parameters {
            any = true;
            match key {
                "box" => bbox = Some(numbers("box", value, 4)?),
                "around" => around = Some(numbers("around", value, 2)?),
                "radius" => radius = Some(numbers("radius", value, 1)?[0]),
                "page_size" => {
                    let n = value.trim().parse::<usize>().ok().filter(|n| *n > 0);
                    page_size = Some(n.ok_or_else(|| RegionError::Bad {
                        name: "page_size",
                        value: value.to_owned(),
                        why: "must be a whole number above 0",
                    })?);
                }
                other => return Err(RegionError::Unknown(other.to_owned())),
            }
        }
        if !any {
            return Ok(None);
        }
        let (min, max, name, value) = match (bbox, around, radius) {
            (Some(b), None, None) => (
                DVec2::new(b[0], b[1]),
                DVec2::new(b[2], b[3]),
                "box",
                format!("{},{},{},{}", b[0], b[1], b[2], b[3]),
            ),
            (None, Some(c), Some(r)) => {
                if r <= 0.0 {
                    return Err(RegionError::Bad {
                        name: "radius",
                        value: r.to_string(),
                        why: "must be above 0",
                    });
                }
                let c = DVec2::new(c[0], c[1]);
                (
                    c - r,
                    c + r,
                    "around",
                    format!("{},{};radius={r}", c.x, c.y),
                )
            }
            _ => return Err(RegionError::Shape),
        };
        let side = max - min;
        if side.min_element() < 0.0 {
            return Err(RegionError::Bad {
                name,
                value,
                why: "the lower corner must not exceed the upper one",
            });
        }
        if side.max_element() > MAX_SIDE_M {
            return Err(RegionError::Bad {
                name,
                value,
                why: "the region is wider than 100 km",
            });
        }
        Ok(Some(Self {
            min,
            max,
            page_size: page_size.unwrap_or(MAX_PAGE).min(MAX_PAGE),
        }))
    }

    /// The attachment of page `page` of `pages` over `total` Gaussians.
    pub fn attachment(&self, page: usize, pages: usize, total: usize) -> String {
        serde_json::json!({
            "region": [self.min.x, self.min.y, self.max.x, self.max.y],
            "page": page,
            "pages": pages,
            "gaussians": total,
        })
        .to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Option<RegionQuery>, RegionError> {
        RegionQuery::parse(s.split(';').filter(|p| !p.is_empty()).map(|p| {
            let (k, v) = p.split_once('=').unwrap_or((p, ""));
            (k, v)
        }))
    }

    #[test]
    fn boxes_points_and_pages_parse() {
        assert_eq!(parse(""), Ok(None));
        let q = parse("box=-10,0.5,20,30").unwrap().unwrap();
        assert_eq!(
            (q.min, q.max),
            (DVec2::new(-10.0, 0.5), DVec2::new(20.0, 30.0))
        );
        assert_eq!(q.page_size, MAX_PAGE);
        let q = parse("around=100,-50;radius=25;page_size=1000")
            .unwrap()
            .unwrap();
        assert_eq!(
            (q.min, q.max),
            (DVec2::new(75.0, -75.0), DVec2::new(125.0, -25.0))
        );
        assert_eq!(q.page_size, 1000);
        assert_eq!(
            parse("box=0,0,1,1;page_size=99999999")
                .unwrap()
                .unwrap()
                .page_size,
            MAX_PAGE
        );
        // A point box (zero extent) is a region.
        assert!(parse("box=5,5,5,5").unwrap().is_some());
    }

    #[test]
    fn bad_parameters_are_named() {
        let err = |s: &str| parse(s).unwrap_err().to_string();
        assert!(err("box=1,2,3").contains("needs 4 numbers"));
        assert!(err("box=0,0,nan,1").contains("finite"));
        assert!(err("box=0,0,inf,1").contains("finite"));
        assert!(err("box=a,b,c,d").contains("not a list of numbers"));
        assert!(err("box=10,0,0,10").contains("lower corner"));
        assert!(err("box=0,0,1e9,1").contains("100 km"));
        assert!(err("around=1,2").contains("exactly one"));
        assert!(err("around=1,2;radius=0").contains("above 0"));
        assert!(err("around=1,2;radius=-3").contains("above 0"));
        assert!(err("box=0,0,1,1;around=1,2;radius=3").contains("exactly one"));
        assert!(err("page_size=0;box=0,0,1,1").contains("page_size"));
        assert!(err("page_size=10").contains("exactly one"));
        assert!(err("tiles=1").contains("unknown snapshot parameter `tiles`"));
        assert!(err("box=1e308,1e308,1.7e308,1.7e308").contains("100 km"));
    }
}

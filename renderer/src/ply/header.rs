//! The PLY header: element and property declarations, read line by line with a size cap.

use std::io::{BufRead, Read};

use super::{PlyError, MAX_HEADER_BYTES};

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    /// Decodes a little-endian value from the start of `b`, which the caller guarantees
    /// holds at least [`Scalar::size`] bytes.
    pub(super) fn decode(self, b: &[u8]) -> f64 {
        match self {
            Self::I8 => b[0] as i8 as f64,
            Self::U8 => b[0] as f64,
            Self::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Self::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Self::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

/// One property of an element.
#[derive(Clone, Debug)]
pub(super) enum Property {
    Scalar(Scalar),
    /// A list: its length's type and its items' type.
    List(Scalar, Scalar),
}

/// One element declared by the header.
#[derive(Clone, Debug)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) props: Vec<(String, Property)>,
}

impl Element {
    /// Bytes per record when it has no list property.
    pub(super) fn stride(&self) -> Option<usize> {
        self.props.iter().try_fold(0, |acc, (_, p)| match p {
            Property::Scalar(t) => Some(acc + t.size()),
            Property::List(..) => None,
        })
    }

    /// The fewest bytes one binary record can take (lists empty).
    pub(super) fn min_record_bytes(&self) -> u128 {
        let sizes = self.props.iter().map(|(_, p)| match p {
            Property::Scalar(t) | Property::List(t, _) => t.size() as u128,
        });
        sizes.sum()
    }
}

/// The data encodings the reader handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    BinaryLittleEndian,
    Ascii,
}

/// What the header declares.
pub(super) struct Header {
    pub(super) format: Format,
    pub(super) elements: Vec<Element>,
}

fn bad(line: usize, reason: impl Into<String>) -> PlyError {
    PlyError::BadHeader {
        line,
        reason: reason.into(),
    }
}

/// Reads the header through `end_header`, leaving `r` at the first data byte.
pub(super) fn read_header(r: &mut impl BufRead) -> Result<Header, PlyError> {
    let mut budget = MAX_HEADER_BYTES;
    let mut buf = Vec::new();
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in 1.. {
        buf.clear();
        let n = r.by_ref().take(budget).read_until(b'\n', &mut buf)?;
        budget -= n as u64;
        if line == 1 {
            if buf != b"ply\n" && buf != b"ply\r\n" {
                return Err(PlyError::NotPly);
            }
            continue;
        }
        if buf.last() != Some(&b'\n') {
            let reason = match budget {
                0 => format!("header longer than {MAX_HEADER_BYTES} bytes"),
                _ => "the file ends before `end_header`".to_owned(),
            };
            return Err(bad(line, reason));
        }
        let first = buf.split(|c| c.is_ascii_whitespace()).next();
        if first == Some(b"comment") || first == Some(b"obj_info") {
            continue; // Free text, in whatever encoding the writer used.
        }
        let text = std::str::from_utf8(&buf).map_err(|_| bad(line, "not UTF-8 text"))?;
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, version] => {
                if format.is_some() {
                    return Err(bad(line, "a second `format` line"));
                }
                format = Some(match *kind {
                    "binary_little_endian" => Format::BinaryLittleEndian,
                    "ascii" => Format::Ascii,
                    other => return Err(PlyError::UnsupportedFormat(other.to_owned())),
                });
                if *version != "1.0" {
                    return Err(PlyError::UnsupportedFormat(format!("{kind} {version}")));
                }
            }
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| bad(line, format!("bad record count `{count}`")))?;
                if elements.iter().any(|e| e.name == *name) {
                    return Err(bad(line, format!("a second element `{name}`")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| bad(line, "a property before any element"))?;
                let ty = |name: &str| {
                    Scalar::parse(name).ok_or_else(|| bad(line, format!("unknown type `{name}`")))
                };
                let (name, prop) = match rest {
                    [t, name] => (name, Property::Scalar(ty(t)?)),
                    ["list", count, item, name] => {
                        let count = ty(count)?;
                        if !count.is_integer() {
                            return Err(bad(line, "a list length must be an integer type"));
                        }
                        (name, Property::List(count, ty(item)?))
                    }
                    _ => return Err(bad(line, "expected `property TYPE NAME`")),
                };
                if element.props.iter().any(|(n, _)| n == name) {
                    return Err(bad(line, format!("a second property `{name}`")));
                }
                element.props.push((name.to_string(), prop));
            }
            ["end_header"] => {
                let format = format.ok_or_else(|| bad(line, "no `format` line"))?;
                return Ok(Header { format, elements });
            }
            [keyword, ..] => return Err(bad(line, format!("unexpected `{keyword}` line"))),
        }
    }
    unreachable!("the header loop returns")
}

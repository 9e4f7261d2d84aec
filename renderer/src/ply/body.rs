//! The data after the header: elements before `vertex` skipped by their declared sizes,
//! vertex records decoded into Gaussians. Elements after `vertex` are never read.

use std::io::{self, BufRead, Read};

use glam::{Quat, Vec3};

use super::header::{Element, Format, Header, Property, Scalar};
use super::{PlyError, CHUNK_BYTES, MAX_TOKEN_BYTES, SH_C0};
use crate::gaussians::{Gaussian, GaussianSet};

/// The properties a vertex record must have, in the order [`VertexLayout`] keeps them.
const REQUIRED: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

/// Where each needed property sits in a vertex record: index among the properties and, for
/// binary files, byte offset.
#[derive(Clone, Copy, Debug)]
struct Field {
    index: usize,
    offset: usize,
    ty: Scalar,
}

/// Where the needed properties sit in a vertex record.
struct VertexLayout {
    required: [Field; 14],
    confidence: Option<Field>,
}

impl VertexLayout {
    fn new(el: &Element) -> Result<Self, PlyError> {
        let mut offset = 0;
        let mut fields = Vec::with_capacity(el.props.len());
        for (index, (name, prop)) in el.props.iter().enumerate() {
            let Property::Scalar(ty) = *prop else {
                let what = format!("list property `{name}` in the vertex element");
                return Err(PlyError::UnsupportedFormat(what));
            };
            fields.push((name.as_str(), Field { index, offset, ty }));
            offset += ty.size();
        }
        let find = |want: &str| fields.iter().find(|(n, _)| *n == want).map(|&(_, f)| f);
        let mut required = [Field {
            index: 0,
            offset: 0,
            ty: Scalar::F32,
        }; 14];
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            *slot = find(name).ok_or_else(|| PlyError::MissingProperty(name.to_owned()))?;
        }
        Ok(Self {
            required,
            confidence: find("confidence"),
        })
    }

    /// Builds a Gaussian from a record's values, `get` reading one field.
    fn gaussian(&self, get: impl Fn(Field) -> f64) -> Gaussian {
        let v: [f64; 14] = self.required.map(&get);
        let opacity_logit = v[6];
        Gaussian {
            mean: Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32),
            color: Vec3::new(
                (0.5 + SH_C0 * v[3]) as f32,
                (0.5 + SH_C0 * v[4]) as f32,
                (0.5 + SH_C0 * v[5]) as f32,
            ),
            opacity: super::opacity_from_logit(opacity_logit),
            log_scale: Vec3::new(v[7] as f32, v[8] as f32, v[9] as f32),
            rotation: Quat::from_xyzw(v[11] as f32, v[12] as f32, v[13] as f32, v[10] as f32),
            confidence: self.confidence.map_or(1.0, get) as f32,
        }
    }
}

/// Reads the data after the header; `available` is its length in bytes when known.
pub(super) fn read_body(
    r: &mut impl BufRead,
    header: &Header,
    available: Option<u64>,
) -> Result<GaussianSet, PlyError> {
    let vi = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| PlyError::MissingElement("vertex".to_owned()))?;
    let (before, vertex) = (&header.elements[..vi], &header.elements[vi]);
    let layout = VertexLayout::new(vertex)?;
    match header.format {
        Format::BinaryLittleEndian => read_binary(r, before, vertex, &layout, available),
        Format::Ascii => read_ascii(r, before, vertex, &layout),
    }
}

fn too_large(el: &Element, needed: u128, available: Option<u64>) -> PlyError {
    PlyError::TooLarge {
        element: el.name.clone(),
        count: el.count,
        needed_bytes: needed,
        available_bytes: available,
    }
}

fn read_binary(
    r: &mut impl BufRead,
    before: &[Element],
    vertex: &Element,
    layout: &VertexLayout,
    available: Option<u64>,
) -> Result<GaussianSet, PlyError> {
    // A lower bound on the data up to the end of the vertex element, checked before any
    // allocation so that a hostile count cannot make us reserve memory for it.
    let mut needed: u128 = 0;
    for el in before.iter().chain([vertex]) {
        needed += el.count as u128 * el.min_record_bytes();
        if needed > u64::MAX as u128 || available.is_some_and(|a| needed > a as u128) {
            return Err(too_large(el, needed, available));
        }
    }
    let mut b = Binary {
        r,
        pos: 0,
        expected: needed as u64,
    };
    for el in before {
        skip_element(&mut b, el)?;
    }

    let stride = vertex.stride().unwrap_or(1); // `VertexLayout::new` refused lists.
    let count = usize::try_from(vertex.count).map_err(|_| too_large(vertex, needed, available))?;
    let chunk = (CHUNK_BYTES / stride).max(1);
    // With the length known the count is validated, else memory grows with the data read.
    let reserve = if available.is_some() {
        count
    } else {
        count.min(chunk)
    };
    let mut set = GaussianSet::with_capacity(reserve);
    let mut buf = vec![0u8; count.min(chunk) * stride];
    let mut left = count;
    while left > 0 {
        let k = left.min(chunk);
        let bytes = &mut buf[..k * stride];
        b.fill(bytes)?;
        for rec in bytes.chunks_exact(stride) {
            set.push(layout.gaussian(|f| f.ty.decode(&rec[f.offset..])));
        }
        left -= k;
    }
    Ok(set)
}

/// Skips one element's records in binary data.
fn skip_element(b: &mut Binary<'_, impl BufRead>, el: &Element) -> Result<(), PlyError> {
    if let Some(stride) = el.stride() {
        return b.skip(el.count.saturating_mul(stride as u64));
    }
    let mut small = [0u8; 8];
    for record in 0..el.count {
        for (name, prop) in &el.props {
            match *prop {
                Property::Scalar(ty) => b.fill(&mut small[..ty.size()])?,
                Property::List(len_ty, item) => {
                    let len_bytes = &mut small[..len_ty.size()];
                    b.fill(len_bytes)?;
                    let len = len_ty.decode(len_bytes);
                    if len < 0.0 {
                        return Err(PlyError::BadData {
                            element: el.name.clone(),
                            record,
                            reason: format!("list `{name}` has negative length {len}"),
                        });
                    }
                    // An integer below 2^32 times at most 8: no overflow.
                    b.skip(len as u64 * item.size() as u64)?;
                }
            }
        }
    }
    Ok(())
}

/// Binary data being read, with the position kept for truncation reports.
struct Binary<'a, R> {
    r: &'a mut R,
    /// Data bytes consumed so far.
    pos: u64,
    /// Data bytes the header declares up to the end of the vertex element (lower bound).
    expected: u64,
}

impl<R: BufRead> Binary<'_, R> {
    /// The error for a read of `want` bytes that found only `got` before the end.
    fn truncated(&self, want: u64, got: u64) -> PlyError {
        PlyError::Truncated {
            expected_bytes: self.expected.max(self.pos.saturating_add(want)),
            got_bytes: self.pos + got,
        }
    }

    fn skip(&mut self, n: u64) -> Result<(), PlyError> {
        let got = io::copy(&mut self.r.by_ref().take(n), &mut io::sink())?;
        if got < n {
            return Err(self.truncated(n, got));
        }
        self.pos += n;
        Ok(())
    }

    fn fill(&mut self, buf: &mut [u8]) -> Result<(), PlyError> {
        let mut got = 0;
        while got < buf.len() {
            match self.r.read(&mut buf[got..]) {
                Ok(0) => return Err(self.truncated(buf.len() as u64, got as u64)),
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        self.pos += got as u64;
        Ok(())
    }
}

fn read_ascii(
    r: &mut impl BufRead,
    before: &[Element],
    vertex: &Element,
    layout: &VertexLayout,
) -> Result<GaussianSet, PlyError> {
    let mut t = Tokens {
        r,
        token: Vec::new(),
    };
    // An element without properties has no data, whatever its count.
    for el in before.iter().filter(|el| !el.props.is_empty()) {
        for record in 0..el.count {
            for (name, prop) in &el.props {
                let value = t.next_value(&el.name, record)?;
                if let Property::List(..) = prop {
                    if !(value >= 0.0 && value.fract() == 0.0) {
                        return Err(PlyError::BadData {
                            element: el.name.clone(),
                            record,
                            reason: format!("list `{name}` has bad length {value}"),
                        });
                    }
                    for _ in 0..value as u64 {
                        t.next_value(&el.name, record)?;
                    }
                }
            }
        }
    }
    // Memory grows with the records actually read.
    let mut set = GaussianSet::with_capacity(vertex.count.min(4096) as usize);
    let mut values = vec![0.0; vertex.props.len()];
    for record in 0..vertex.count {
        for v in values.iter_mut() {
            *v = t.next_value(&vertex.name, record)?;
        }
        set.push(layout.gaussian(|f| values[f.index]));
    }
    Ok(set)
}

/// Whitespace-separated numbers of an ascii body.
struct Tokens<'a, R> {
    r: &'a mut R,
    token: Vec<u8>,
}

impl<R: BufRead> Tokens<'_, R> {
    /// The next number, for record `record` of element `element` (named in errors).
    fn next_value(&mut self, element: &str, record: u64) -> Result<f64, PlyError> {
        let bad = |reason: String| PlyError::BadData {
            element: element.to_owned(),
            record,
            reason,
        };
        self.token.clear();
        loop {
            let buf = self.r.fill_buf()?;
            if buf.is_empty() {
                return Err(bad("the file ends before this record".to_owned()));
            }
            let ws = buf.iter().take_while(|c| c.is_ascii_whitespace()).count();
            let only_ws = ws == buf.len();
            self.r.consume(ws);
            if !only_ws {
                break;
            }
        }
        loop {
            let buf = self.r.fill_buf()?;
            let n = buf.iter().take_while(|c| !c.is_ascii_whitespace()).count();
            let done = n < buf.len() || buf.is_empty();
            if self.token.len() + n > MAX_TOKEN_BYTES {
                return Err(bad(format!("a token longer than {MAX_TOKEN_BYTES} bytes")));
            }
            self.token.extend_from_slice(&buf[..n]);
            self.r.consume(n);
            if done {
                break;
            }
        }
        let text = String::from_utf8_lossy(&self.token);
        text.parse()
            .map_err(|_| bad(format!("`{text}` is not a number")))
    }
}

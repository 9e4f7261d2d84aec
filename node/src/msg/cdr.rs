//! Plain CDR (XCDR1) as ROS 2 puts it on the wire: a 4-byte encapsulation header, then the
//! fields in order, each aligned to its own size (2, 4 or 8) counted from the first byte
//! after the header.
//!
//! The writer always emits little endian (`00 01 00 00`, CDR_LE), as every ROS 2 middleware
//! does by default. The reader accepts CDR_LE and CDR_BE (`00 00`): big endian costs one flag
//! here and some writers (rosbags' `serialize_cdr(little_endian=False)`) can produce it. Every
//! other representation (parameter lists, XCDR2) is refused with
//! [`DecodeError::UnsupportedEncapsulation`]. The two option bytes are ignored, and so are
//! bytes left after the last field (writers may pad the payload to a multiple of 4).
//!
//! Strings are a `u32` length that counts the terminating NUL, the bytes, then the NUL; a
//! length of 0 is read as the empty string (some writers emit it). Sequences are a `u32`
//! count then the elements; fixed arrays are the elements alone. Every count is checked
//! against the bytes left before anything is allocated, so no input makes the reader
//! allocate much more than its own length.

/// Why a CDR payload could not be decoded. Offsets count from the first byte of the payload
/// (the encapsulation header included); `what` names the field being read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Fewer than 4 bytes: not even an encapsulation header.
    #[error("CDR payload of {len} bytes has no 4-byte encapsulation header")]
    NoHeader {
        /// The payload's length.
        len: usize,
    },
    /// The representation identifier is not plain CDR (little or big endian).
    #[error("unsupported CDR encapsulation {0:02x} {1:02x} (only CDR_LE 00 01 and CDR_BE 00 00)")]
    UnsupportedEncapsulation(u8, u8),
    /// The payload ends inside a field.
    #[error(
        "CDR payload truncated at byte {at} reading `{what}`: {need} bytes needed, {left} left"
    )]
    Truncated {
        /// The field being read.
        what: &'static str,
        /// Offset where it starts.
        at: usize,
        /// Bytes it needs.
        need: usize,
        /// Bytes left.
        left: usize,
    },
    /// A string length or sequence count runs past the end of the payload.
    #[error("`{what}` at byte {at} declares {count} elements ({need} bytes at least), only {left} bytes left")]
    LengthPastEnd {
        /// The field being read.
        what: &'static str,
        /// Offset of the length.
        at: usize,
        /// The declared count.
        count: u32,
        /// Bytes the count needs at least.
        need: u64,
        /// Bytes left after the length.
        left: usize,
    },
    /// A string's bytes are not UTF-8.
    #[error("string `{what}` at byte {at} is not UTF-8")]
    InvalidUtf8 {
        /// The field being read.
        what: &'static str,
        /// Offset of its length.
        at: usize,
    },
    /// A string's last byte is not the NUL its length promises.
    #[error("string `{what}` at byte {at} does not end with NUL")]
    MissingNul {
        /// The field being read.
        what: &'static str,
        /// Offset of its length.
        at: usize,
    },
    /// A boolean byte other than 0 or 1.
    #[error("boolean `{what}` at byte {at} holds {value}, not 0 or 1")]
    InvalidBool {
        /// The field being read.
        what: &'static str,
        /// Its offset.
        at: usize,
        /// The byte found.
        value: u8,
    },
}

/// The encapsulation header the writer emits: CDR, little endian, no options.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Builds a CDR payload field by field (little endian).
#[derive(Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
    /// What alignment padding is filled with (0 unless [`CdrWriter::with_padding`]).
    pad: u8,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// A writer holding only the CDR_LE encapsulation header.
    pub fn new() -> Self {
        Self::with_padding(0)
    }

    /// A writer that fills alignment padding with `pad` instead of zeros. Padding carries no
    /// value and some implementations (Fast CDR under rclpy) leave it uninitialised; two
    /// encodings with different padding bytes tell a test which bytes are padding.
    pub fn with_padding(pad: u8) -> Self {
        Self {
            buf: CDR_LE_HEADER.to_vec(),
            pad,
        }
    }

    /// A writer holding only the header, with room for `bytes` more.
    pub fn with_capacity(bytes: usize) -> Self {
        let mut w = Self::new();
        w.buf.reserve(bytes);
        w
    }

    /// The finished payload, header included.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// Pads (with zeros, by default) so the next field starts at a multiple of `n` (after
    /// the header).
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - CDR_LE_HEADER.len();
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, self.pad);
    }

    /// One byte.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A boolean as one byte, 0 or 1.
    pub fn bool(&mut self, v: bool) {
        self.buf.push(v as u8);
    }

    /// An aligned `u32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An aligned `i32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An aligned `u64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An aligned `i64`.
    pub fn i64(&mut self, v: i64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An aligned `f64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A string: length with the NUL, bytes, NUL.
    pub fn string(&mut self, s: &str) {
        self.seq_len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A sequence length. Messages over 4 GiB cannot be expressed in CDR; the count is
    /// saturated there (callers building such messages have already failed elsewhere).
    pub fn seq_len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    /// A `uint8[]` sequence: count then bytes.
    pub fn bytes(&mut self, v: &[u8]) {
        self.bytes_from(v.len(), |b| b.extend_from_slice(v));
    }

    /// A `uint8[]` sequence of `n` bytes that `fill` appends to the payload, so a large
    /// sequence is written in place instead of built apart and copied. `fill` must append
    /// exactly `n` bytes (checked in debug builds).
    pub fn bytes_from(&mut self, n: usize, fill: impl FnOnce(&mut Vec<u8>)) {
        self.seq_len(n);
        let start = self.buf.len();
        fill(&mut self.buf);
        debug_assert_eq!(self.buf.len() - start, n, "bytes_from's count");
    }

    /// A `float64[]` sequence: count then values.
    pub fn f64_seq(&mut self, v: &[f64]) {
        self.seq_len(v.len());
        self.f64_array(v);
    }

    /// A `uint64[]` sequence: count then values.
    pub fn u64_seq(&mut self, v: &[u64]) {
        self.u64_seq_from(v.iter().copied());
    }

    /// A `uint64[]` sequence of the values `v` yields.
    pub fn u64_seq_from(&mut self, v: impl ExactSizeIterator<Item = u64>) {
        self.seq_len(v.len());
        for x in v {
            self.u64(x);
        }
    }

    /// A fixed `float64[N]` array: the values alone.
    pub fn f64_array(&mut self, v: &[f64]) {
        for &x in v {
            self.f64(x);
        }
    }
}

/// Reads a CDR payload field by field; every method checks the bytes left first.
#[derive(Debug)]
pub struct CdrReader<'a> {
    buf: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header and positions the reader on the first field.
    pub fn new(buf: &'a [u8]) -> Result<Self, DecodeError> {
        let [a, b, _, _] = *buf
            .first_chunk::<4>()
            .ok_or(DecodeError::NoHeader { len: buf.len() })?;
        let big_endian = match (a, b) {
            (0x00, 0x01) => false,
            (0x00, 0x00) => true,
            _ => return Err(DecodeError::UnsupportedEncapsulation(a, b)),
        };
        Ok(Self {
            buf,
            pos: CDR_LE_HEADER.len(),
            big_endian,
        })
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// Skips the padding before a field of alignment `n`; padding past the end is the
    /// field's own truncation, reported by [`CdrReader::take`].
    fn align(&mut self, n: usize) {
        let pos = self.pos - CDR_LE_HEADER.len();
        self.pos = (self.pos + (n - pos % n) % n).min(self.buf.len());
    }

    /// The next `n` bytes.
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], DecodeError> {
        if n > self.remaining() {
            return Err(DecodeError::Truncated {
                what,
                at: self.pos,
                need: n,
                left: self.remaining(),
            });
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// The next aligned `N` bytes in little-endian order.
    fn word<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], DecodeError> {
        self.align(N);
        let mut w = [0; N];
        w.copy_from_slice(self.take(N, what)?);
        if self.big_endian {
            w.reverse();
        }
        Ok(w)
    }

    /// One byte.
    pub fn u8(&mut self, what: &'static str) -> Result<u8, DecodeError> {
        Ok(self.take(1, what)?[0])
    }

    /// A boolean byte; anything but 0 or 1 is an error.
    pub fn bool(&mut self, what: &'static str) -> Result<bool, DecodeError> {
        let at = self.pos;
        match self.u8(what)? {
            0 => Ok(false),
            1 => Ok(true),
            value => Err(DecodeError::InvalidBool { what, at, value }),
        }
    }

    /// An aligned `u32`.
    pub fn u32(&mut self, what: &'static str) -> Result<u32, DecodeError> {
        self.word(what).map(u32::from_le_bytes)
    }

    /// An aligned `i32`.
    pub fn i32(&mut self, what: &'static str) -> Result<i32, DecodeError> {
        self.word(what).map(i32::from_le_bytes)
    }

    /// An aligned `u64`.
    pub fn u64(&mut self, what: &'static str) -> Result<u64, DecodeError> {
        self.word(what).map(u64::from_le_bytes)
    }

    /// An aligned `i64`.
    pub fn i64(&mut self, what: &'static str) -> Result<i64, DecodeError> {
        self.word(what).map(i64::from_le_bytes)
    }

    /// An aligned `f64`.
    pub fn f64(&mut self, what: &'static str) -> Result<f64, DecodeError> {
        self.word(what).map(f64::from_le_bytes)
    }

    /// A sequence count, checked to fit the bytes left at `min_elem_bytes` per element
    /// (at least 1), so callers may allocate for it.
    pub fn seq_len(
        &mut self,
        what: &'static str,
        min_elem_bytes: usize,
    ) -> Result<usize, DecodeError> {
        let count = self.u32(what)?;
        let at = self.pos - 4;
        let need = count as u64 * min_elem_bytes.max(1) as u64;
        if need > self.remaining() as u64 {
            return Err(DecodeError::LengthPastEnd {
                what,
                at,
                count,
                need,
                left: self.remaining(),
            });
        }
        Ok(count as usize)
    }

    /// A string (see the module documentation).
    pub fn string(&mut self, what: &'static str) -> Result<String, DecodeError> {
        let at = self.pos;
        let n = self.seq_len(what, 1)?;
        let Some((&last, text)) = self.take(n, what)?.split_last() else {
            return Ok(String::new());
        };
        if last != 0 {
            return Err(DecodeError::MissingNul { what, at });
        }
        String::from_utf8(text.to_vec()).map_err(|_| DecodeError::InvalidUtf8 { what, at })
    }

    /// A `uint8[]` sequence.
    pub fn bytes(&mut self, what: &'static str) -> Result<Vec<u8>, DecodeError> {
        let n = self.seq_len(what, 1)?;
        Ok(self.take(n, what)?.to_vec())
    }

    /// A `float64[]` sequence.
    pub fn f64_seq(&mut self, what: &'static str) -> Result<Vec<f64>, DecodeError> {
        let n = self.seq_len(what, 8)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// A `uint64[]` sequence.
    pub fn u64_seq(&mut self, what: &'static str) -> Result<Vec<u64>, DecodeError> {
        let n = self.seq_len(what, 8)?;
        (0..n).map(|_| self.u64(what)).collect()
    }

    /// A fixed `float64[N]` array.
    pub fn f64_array<const N: usize>(
        &mut self,
        what: &'static str,
    ) -> Result<[f64; N], DecodeError> {
        let mut a = [0.0; N];
        for v in &mut a {
            *v = self.f64(what)?;
        }
        Ok(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut w = CdrWriter::new();
        w.u8(7);
        w.f64(1.5);
        w.string("ab");
        let b = w.into_bytes();
        // header, u8, 7 pad, f64 at payload offset 8, u32 len 3 at 16, "ab\0".
        assert_eq!(b.len(), 4 + 8 + 8 + 4 + 3);
        assert_eq!(&b[12..20], &1.5f64.to_le_bytes());
        assert_eq!(&b[20..24], &3u32.to_le_bytes());
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.f64("b").unwrap(), 1.5);
        assert_eq!(r.string("c").unwrap(), "ab");
        assert_eq!(r.remaining(), 0);
    }

    #[test]
    fn big_endian_payloads_read_the_same_values() {
        let b = [
            0, 0, 0, 0, 0, 0, 1, 2, 0, 0, 0, 0, 0x3f, 0xf8, 0, 0, 0, 0, 0, 0,
        ];
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u32("x").unwrap(), 258);
        assert_eq!(r.f64("y").unwrap(), 1.5);
    }

    #[test]
    fn a_huge_count_is_refused_before_allocating() {
        let b = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, 1, 2];
        let err = CdrReader::new(&b).unwrap().bytes("data").unwrap_err();
        assert!(matches!(
            err,
            DecodeError::LengthPastEnd {
                count: u32::MAX,
                left: 2,
                ..
            }
        ));
        let err = CdrReader::new(&[0, 2, 0, 0]).unwrap_err();
        assert_eq!(err, DecodeError::UnsupportedEncapsulation(0, 2));
    }
}

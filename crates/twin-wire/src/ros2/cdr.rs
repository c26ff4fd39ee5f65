//! A little-endian CDR (OMG XCDR version 1, "plain CDR") writer and reader
//! for the few ROS 2 message types of [`super::msgs`], as rmw_zenoh puts them
//! on the wire: a 4-byte encapsulation header `00 01 00 00` (CDR, little
//! endian, no options), then the fields in order, each primitive aligned to
//! its own size (8 for `float64`) counted from the end of the header,
//! strings as a `uint32` length that counts a trailing NUL, the bytes and
//! the NUL, sequences as a `uint32` count and the elements, fixed arrays as
//! the elements alone.
//!
//! The reader never panics and never allocates more than the input can
//! hold: every length is checked against the bytes left before anything is
//! read or reserved.

/// The encapsulation header of little-endian plain CDR.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why CDR bytes cannot be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The payload is shorter than the encapsulation header.
    #[error("shorter than the 4-byte encapsulation header")]
    NoHeader,
    /// The encapsulation is not little-endian plain CDR (`00 01`); big
    /// endian (`00 00`) and XCDR2 are not read.
    #[error("encapsulation {0:#06x} is not little-endian plain CDR")]
    Encapsulation(u16),
    /// The payload ends inside a field.
    #[error("ends inside `{field}`")]
    Truncated {
        /// The field being read.
        field: &'static str,
    },
    /// A string is not NUL-terminated UTF-8.
    #[error("`{field}` is not a NUL-terminated UTF-8 string")]
    BadString {
        /// The field.
        field: &'static str,
    },
    /// A string or sequence announces more elements than the bytes left can
    /// hold.
    #[error("`{field}` announces {len} elements, more than the payload holds")]
    TooLong {
        /// The field.
        field: &'static str,
        /// The announced length.
        len: u32,
    },
    /// Bytes are left after the message.
    #[error("{0} bytes left after the message")]
    Trailing(usize),
}

/// Writes one message: the header, then fields in order.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// A writer holding the encapsulation header.
    pub fn new() -> Self {
        let mut buf = Vec::with_capacity(256);
        buf.extend_from_slice(&CDR_LE_HEADER);
        Self { buf }
    }

    fn align(&mut self, size: usize) {
        let offset = self.buf.len() - CDR_LE_HEADER.len();
        let pad = (size - offset % size) % size;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// An `int8` (or `char`).
    pub fn i8(&mut self, v: i8) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint8` (or `byte`, `bool`).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `uint16`.
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A fixed array of `float64` (no length on the wire).
    pub fn f64s(&mut self, vs: &[f64]) {
        for &v in vs {
            self.f64(v);
        }
    }

    /// A sequence's element count. Lengths beyond `u32` cannot be written;
    /// they saturate, which no message here comes near.
    pub fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    /// A string: its length with the NUL, the bytes, the NUL.
    pub fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// The message's bytes.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads one message written as [`CdrWriter`] writes it.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    body: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader of `bytes`, its encapsulation header checked.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let header = bytes.get(..4).ok_or(CdrError::NoHeader)?;
        let kind = u16::from_be_bytes([header[0], header[1]]);
        if kind != 0x0001 {
            return Err(CdrError::Encapsulation(kind));
        }
        Ok(Self {
            body: &bytes[4..],
            pos: 0,
        })
    }

    fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let pad = (N - self.pos % N) % N;
        let start = self.pos + pad;
        let bytes = self
            .body
            .get(start..start + N)
            .ok_or(CdrError::Truncated { field })?;
        self.pos = start + N;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        Ok(out)
    }

    fn left(&self) -> usize {
        self.body.len().saturating_sub(self.pos)
    }

    /// An `int8`.
    pub fn i8(&mut self, field: &'static str) -> Result<i8, CdrError> {
        self.take::<1>(field).map(i8::from_le_bytes)
    }

    /// A `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        self.take::<1>(field).map(|b| b[0])
    }

    /// A `uint16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, CdrError> {
        self.take::<2>(field).map(u16::from_le_bytes)
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        self.take::<4>(field).map(i32::from_le_bytes)
    }

    /// A `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        self.take::<4>(field).map(u32::from_le_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        self.take::<8>(field).map(f64::from_le_bytes)
    }

    /// A fixed array of `N` `float64`.
    pub fn f64s<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// A sequence's element count, refused when even elements of
    /// `min_element_bytes` each could not fit in what is left.
    pub fn len(
        &mut self,
        field: &'static str,
        min_element_bytes: usize,
    ) -> Result<usize, CdrError> {
        let len = self.u32(field)?;
        let n = len as usize;
        if n.saturating_mul(min_element_bytes.max(1)) > self.left() {
            return Err(CdrError::TooLong { field, len });
        }
        Ok(n)
    }

    /// A string.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.len(field, 1)?;
        if n == 0 {
            return Err(CdrError::BadString { field });
        }
        let bytes = &self.body[self.pos..self.pos + n];
        self.pos += n;
        let (text, nul) = bytes.split_at(n - 1);
        if nul != [0] {
            return Err(CdrError::BadString { field });
        }
        std::str::from_utf8(text)
            .map(str::to_owned)
            .map_err(|_| CdrError::BadString { field })
    }

    /// Checks that the whole payload was read. CDR writers may pad the end
    /// of a message to 4 or 8 bytes, so up to 7 zero bytes are allowed.
    pub fn finish(self) -> Result<(), CdrError> {
        let rest = self.body.get(self.pos..).unwrap_or_default();
        if rest.len() < 8 && rest.iter().all(|&b| b == 0) {
            Ok(())
        } else {
            Err(CdrError::Trailing(rest.len()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut w = CdrWriter::new();
        w.u8(7);
        w.f64(1.0);
        w.string("ab");
        w.u16(3);
        let bytes = w.finish();
        // header, u8, 7 pad, f64, len(3), "ab\0", 1 pad, u16
        assert_eq!(bytes.len(), 4 + 1 + 7 + 8 + 4 + 3 + 1 + 2);
        assert_eq!(&bytes[..5], &[0, 1, 0, 0, 7]);
        assert_eq!(&bytes[24..27], b"ab\0");
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.f64("b").unwrap(), 1.0);
        assert_eq!(r.string("c").unwrap(), "ab");
        assert_eq!(r.u16("d").unwrap(), 3);
        r.finish().unwrap();
    }

    #[test]
    fn lies_about_lengths_are_refused_before_anything_is_reserved() {
        let mut w = CdrWriter::new();
        w.u32(u32::MAX);
        let bytes = w.finish();
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(
            r.len("poses", 8),
            Err(CdrError::TooLong {
                field: "poses",
                len: u32::MAX
            })
        );
        assert_eq!(CdrReader::new(&[0, 1]).err(), Some(CdrError::NoHeader));
        assert_eq!(
            CdrReader::new(&[0, 0, 0, 0]).err(),
            Some(CdrError::Encapsulation(0))
        );
    }
}

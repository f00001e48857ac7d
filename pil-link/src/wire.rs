//! Little-endian payload writer and reader. Fixed-point values travel as their raw bits
//! (`to_bits()` / `from_bits()`), so both sides see the same numbers bit for bit.

use crate::{FrameKind, LinkError, MAX_PAYLOAD};

/// Appends little-endian fields to a payload buffer of [`MAX_PAYLOAD`] bytes.
#[derive(Clone, Debug)]
pub struct Writer {
    buf: [u8; MAX_PAYLOAD],
    len: usize,
}

impl Default for Writer {
    fn default() -> Self {
        Self::new()
    }
}

impl Writer {
    /// An empty payload.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_PAYLOAD],
            len: 0,
        }
    }

    /// Appends raw bytes; `BufferTooSmall` once the payload would exceed [`MAX_PAYLOAD`].
    pub fn bytes(&mut self, bytes: &[u8]) -> Result<&mut Self, LinkError> {
        let end = self.len + bytes.len();
        let dst = self
            .buf
            .get_mut(self.len..end)
            .ok_or(LinkError::BufferTooSmall { needed: end })?;
        dst.copy_from_slice(bytes);
        self.len = end;
        Ok(self)
    }

    /// Appends a byte.
    pub fn u8(&mut self, v: u8) -> Result<&mut Self, LinkError> {
        self.bytes(&[v])
    }

    /// Appends a `u16`.
    pub fn u16(&mut self, v: u16) -> Result<&mut Self, LinkError> {
        self.bytes(&v.to_le_bytes())
    }

    /// Appends a `u32`.
    pub fn u32(&mut self, v: u32) -> Result<&mut Self, LinkError> {
        self.bytes(&v.to_le_bytes())
    }

    /// Appends an `i32` (e.g. the raw bits of an `I16F16`).
    pub fn i32(&mut self, v: i32) -> Result<&mut Self, LinkError> {
        self.bytes(&v.to_le_bytes())
    }

    /// Appends an `i64` (e.g. the raw bits of an `I32F32`).
    pub fn i64(&mut self, v: i64) -> Result<&mut Self, LinkError> {
        self.bytes(&v.to_le_bytes())
    }

    /// The payload written so far.
    pub fn as_slice(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }
}

/// Reads little-endian fields from a payload; every read checks the bounds and fails with
/// `BadPayload` naming the frame kind, never panics.
#[derive(Clone, Debug)]
pub struct Reader<'a> {
    kind: FrameKind,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    /// Reads the payload of a frame of `kind`.
    pub const fn new(kind: FrameKind, bytes: &'a [u8]) -> Self {
        Self {
            kind,
            bytes,
            pos: 0,
        }
    }

    fn error(&self) -> LinkError {
        LinkError::BadPayload {
            kind: self.kind as u8,
            len: u8::try_from(self.bytes.len()).unwrap_or(u8::MAX),
        }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], LinkError> {
        let end = self.pos + N;
        let src = self.bytes.get(self.pos..end).ok_or(self.error())?;
        let mut out = [0_u8; N];
        out.copy_from_slice(src);
        self.pos = end;
        Ok(out)
    }

    /// Reads a byte.
    pub fn u8(&mut self) -> Result<u8, LinkError> {
        self.take::<1>().map(|[b]| b)
    }

    /// Reads a `u16`.
    pub fn u16(&mut self) -> Result<u16, LinkError> {
        self.take().map(u16::from_le_bytes)
    }

    /// Reads a `u32`.
    pub fn u32(&mut self) -> Result<u32, LinkError> {
        self.take().map(u32::from_le_bytes)
    }

    /// Reads an `i32`.
    pub fn i32(&mut self) -> Result<i32, LinkError> {
        self.take().map(i32::from_le_bytes)
    }

    /// Reads an `i64`.
    pub fn i64(&mut self) -> Result<i64, LinkError> {
        self.take().map(i64::from_le_bytes)
    }

    /// Reads the rest of the payload.
    pub fn rest(&mut self) -> &'a [u8] {
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        self.pos = self.bytes.len();
        rest
    }

    /// Succeeds only if every byte was read: a payload longer than its message is an error
    /// too (a peer with another layout slipped past the version check).
    pub fn finish(&self) -> Result<(), LinkError> {
        if self.pos == self.bytes.len() {
            Ok(())
        } else {
            Err(self.error())
        }
    }
}

/// Text into a payload (the board console's messages). Text beyond the payload is an error;
/// what fit stays written.
impl core::fmt::Write for Writer {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.bytes(s.as_bytes())
            .map(|_| ())
            .map_err(|_| core::fmt::Error)
    }
}

//! CRC-32/ISO-HDLC (the Ethernet / zlib CRC): reflected polynomial 0xEDB8_8320, initial value
//! and final XOR 0xFFFF_FFFF. Written here (no dependency) so the firmware and the harness
//! share one implementation. It detects every error burst up to 32 bits long and all 1-, 2-
//! and 3-bit errors in frames far longer than ours.

/// Reflected generator polynomial of CRC-32/ISO-HDLC.
const POLY_REFLECTED: u32 = 0xEDB8_8320;

/// 256-entry lookup table computed at compile time (1 KiB of flash on the target).
const TABLE: [u32; 256] = build_table();

// Compile-time only: an out-of-range index here fails the build, it cannot panic at run time.
#[allow(clippy::indexing_slicing)]
const fn build_table() -> [u32; 256] {
    let mut table = [0_u32; 256];
    let mut n = 0;
    while n < 256 {
        let mut c = n as u32;
        let mut bit = 0;
        while bit < 8 {
            c = if c & 1 == 1 {
                (c >> 1) ^ POLY_REFLECTED
            } else {
                c >> 1
            };
            bit += 1;
        }
        table[n] = c;
        n += 1;
    }
    table
}

/// Running CRC-32 over a byte stream, so the decoder can fold bytes in as they arrive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc32 {
    state: u32,
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A CRC over zero bytes so far.
    pub const fn new() -> Self {
        Self { state: 0xFFFF_FFFF }
    }

    /// Folds one byte into the CRC.
    #[inline]
    pub fn push(&mut self, byte: u8) {
        // index = low byte of (state XOR byte); masked to 0..=255 so it is always in range.
        let index = usize::from((self.state as u8) ^ byte);
        let entry = TABLE.get(index).copied().unwrap_or(0);
        self.state = (self.state >> 8) ^ entry;
    }

    /// Folds a slice of bytes into the CRC.
    pub fn extend(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.push(b);
        }
    }

    /// The CRC value of the bytes folded in so far.
    pub const fn value(&self) -> u32 {
        self.state ^ 0xFFFF_FFFF
    }
}

/// CRC-32/ISO-HDLC of a whole slice.
///
/// ```
/// // The standard check value: CRC-32 of the ASCII digits "123456789".
/// assert_eq!(pil_link::crc32(b"123456789"), 0xCBF4_3926);
/// ```
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = Crc32::new();
    crc.extend(bytes);
    crc.value()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_matches_the_catalogue() {
        // reveng catalogue "CRC-32/ISO-HDLC": check = 0xCBF43926.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn running_and_whole_slice_agree() {
        let data = b"stiffdrive processor in the loop";
        let mut crc = Crc32::new();
        for &b in data.iter() {
            crc.push(b);
        }
        assert_eq!(crc.value(), crc32(data));
    }
}

//! Typed link errors. Each names what was wrong and the values seen, so a fault report on
//! either side says exactly why the link was declared dead.

/// Everything that can go wrong with a frame or with the frame stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// The CRC-32 in the frame does not match the CRC of its bytes (corruption on the wire).
    BadCrc {
        /// CRC computed over the received header and payload.
        computed: u32,
        /// CRC carried by the frame.
        received: u32,
    },
    /// The frame is intact but speaks another protocol version.
    BadVersion {
        /// Version byte received; this build speaks [`crate::PROTOCOL_VERSION`].
        received: u8,
    },
    /// The length byte exceeds [`crate::MAX_PAYLOAD`].
    BadLength {
        /// Length received, in bytes.
        len: u8,
    },
    /// The frame is intact but its kind byte names no known message.
    UnknownKind {
        /// Kind byte received.
        kind: u8,
    },
    /// A frame arrived with a sequence number other than the one expected (a frame was
    /// lost, repeated or reordered).
    OutOfSequence {
        /// Sequence number expected.
        expected: u16,
        /// Sequence number received.
        received: u16,
    },
    /// No complete frame arrived within the deadline (lost or late frame, dead peer).
    Timeout {
        /// Deadline that expired, in milliseconds.
        waited_ms: u32,
    },
    /// The payload length does not fit the message kind.
    BadPayload {
        /// Kind byte of the frame.
        kind: u8,
        /// Payload length received, in bytes.
        len: u8,
    },
    /// A frame or payload does not fit the buffer it is written into.
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
    },
    /// The drive's motor kind is not one the firmware's board layer drives (a
    /// `[drive.pmsm]` drive on a board that drives one DC winding).
    UnsupportedMotor,
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::BadCrc { computed, received } => write!(
                f,
                "bad CRC: frame carries {received:#010x}, bytes give {computed:#010x}"
            ),
            Self::BadVersion { received } => write!(
                f,
                "protocol version {received}, this side speaks {}",
                crate::PROTOCOL_VERSION
            ),
            Self::BadLength { len } => write!(
                f,
                "payload length {len} exceeds the maximum {}",
                crate::MAX_PAYLOAD
            ),
            Self::UnknownKind { kind } => write!(f, "unknown frame kind {kind:#04x}"),
            Self::OutOfSequence { expected, received } => write!(
                f,
                "out of sequence: expected frame {expected}, got {received}"
            ),
            Self::Timeout { waited_ms } => write!(f, "no frame within {waited_ms} ms"),
            Self::BadPayload { kind, len } => write!(
                f,
                "payload of {len} bytes does not fit frame kind {kind:#04x}"
            ),
            Self::BufferTooSmall { needed } => write!(f, "buffer too small: {needed} bytes needed"),
            Self::UnsupportedMotor => f.write_str(
                "drive.pmsm: the firmware's board layer drives a DC winding only; a PMSM drive runs on the host (`stiffdrive run --config FILE`)",
            ),
        }
    }
}

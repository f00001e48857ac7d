//! pil-link: the processor-in-the-loop link between `hil-harness` and the firmware running
//! in QEMU. Each tick the harness sends the sampled sensors, the firmware answers with its
//! commands; frames are versioned and checksummed so a lost, corrupted or late frame is seen
//! by both sides.
//!
//! Layers: [`crc`] (CRC-32 written here), [`frame`] (wire format and a byte-at-a-time
//! decoder), [`wire`] (little-endian payload reader/writer).
#![cfg_attr(not(test), no_std)]

pub mod crc;
mod error;
pub mod frame;
pub mod wire;

pub use crc::{crc32, Crc32};
pub use error::LinkError;
pub use frame::{
    Decoder, Frame, FrameKind, SequenceCheck, CRC_LEN, HEADER_LEN, MAX_FRAME, MAX_PAYLOAD,
    PROTOCOL_VERSION, SYNC,
};

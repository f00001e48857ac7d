//! pil-link: the processor-in-the-loop link between `hil-harness` and the firmware running
//! in QEMU. Each tick the harness sends the sampled sensors, the firmware answers with its
//! commands; frames are versioned and checksummed so a lost, corrupted or late frame is seen
//! by both sides.
//!
//! Layers, bottom up: [`crc`] (CRC-32 written here), [`frame`] (wire format and a
//! byte-at-a-time decoder), [`wire`] (little-endian payload fields), [`message`] (session
//! payloads), [`tick`] and [`settings`] (controller-core's inputs, outputs and
//! `DriveConfig` as raw bits), [`run_config`] (the `Config` payload: the settings and the
//! run's identification excitation, if any), [`session`] (the firmware's state machine: sequence, watchdog, latched safe
//! state) and, with the `std` feature, [`host`] (the harness's lock-step client with fault
//! injection) and [`qemu`] (starts the PIL image with UART0 on a Unix socket). [`board`] is the board console, a
//! session of its own in the same frames.
#![cfg_attr(not(any(test, feature = "std")), no_std)]

pub mod board;
pub mod crc;
mod error;
pub mod frame;
#[cfg(feature = "std")]
pub mod host;
pub mod message;
#[cfg(feature = "std")]
pub mod qemu;
pub mod run_config;
pub mod session;
pub mod settings;
pub mod tick;
pub mod wire;

pub use crc::{Crc32, crc32};
pub use error::LinkError;
pub use frame::{
    CRC_LEN, Decoder, Frame, FrameKind, HEADER_LEN, MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION, SYNC,
    SequenceCheck,
};
pub use message::{FaultCode, FaultReport, Hello, HelloAck, SafeOutputs, WATCHDOG_MS_RANGE};
pub use session::{FirmwareSession, SessionState, Target};

//! The board console: a session between `stiffdrive board` and the drive firmware over its
//! serial port, in the link's frames ([`crate::frame`], [`crate::wire`]) with frame kinds of
//! its own (`BoardRequest`, `BoardReply`, `ScopeData`), so the PIL protocol is unchanged.
//! Every request carries [`BOARD_VERSION`]; a firmware of another version refuses it.
//!
//! * [`keys`]: the settings by their machine-file key (`drive.velocity_bandwidth_rad_s`),
//!   with controller-core's ranges;
//! * [`message`]: requests and replies; [`scope`]: the scope stream; [`faults`]: the fault
//!   history; [`store`]: the saved-settings record; [`identify`]: a measurement run on the
//!   board, streamed as the scope is; [`calibrate`]: a PMSM's motor calibration run on the
//!   board, streamed the same way;
//! * [`session`]: the firmware side, host-testable; with `std`, [`client`]: the host side.

pub mod calibrate;
#[cfg(feature = "std")]
pub mod client;
pub mod faults;
pub mod identify;
pub mod keys;
pub mod message;
pub mod scope;
pub mod session;
pub mod store;

/// Version of the board console protocol. Bump it whenever a board payload changes.
pub const BOARD_VERSION: u8 = 2;

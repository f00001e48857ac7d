//! The host side of the board console (needs `std`): one request, one reply, over the
//! link's [`HostLink`] (a serial device, or QEMU's UART on a pseudo-terminal). Scope
//! frames that arrive while a reply is awaited go to the caller's sink.

use super::faults::FaultHistory;
use super::message::{Refusal, Reply, Request, StatusReport, get_f64};
use super::scope::{ScopeChunk, ScopeInfo};
use crate::host::{HostError, HostLink, Transport};
use crate::wire::Writer;
use crate::{FrameKind, LinkError};
use std::time::{Duration, Instant};

/// Why a console request failed.
#[derive(Debug)]
pub enum BoardError {
    /// The link failed (I/O, timeout, a corrupt reply).
    Host(HostError),
    /// The firmware refused the request; its message names the key and the range.
    Refused {
        /// The refusal code.
        refusal: Refusal,
        /// The firmware's message.
        message: String,
    },
    /// The reply does not parse.
    Reply(LinkError),
}

impl core::fmt::Display for BoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Host(e) => write!(f, "board link: {e}"),
            Self::Refused { refusal, message } => write!(f, "refused ({refusal:?}): {message}"),
            Self::Reply(e) => write!(f, "board reply: {e}"),
        }
    }
}

impl std::error::Error for BoardError {}

impl From<HostError> for BoardError {
    fn from(e: HostError) -> Self {
        Self::Host(e)
    }
}

/// A console session with a board.
pub struct BoardClient<S: Transport> {
    link: HostLink<S>,
    timeout: Duration,
}

impl<S: Transport> BoardClient<S> {
    /// A session over `stream`; each reply must come within `timeout`.
    pub fn new(stream: S, timeout: Duration) -> Self {
        Self {
            link: HostLink::new(stream, timeout),
            timeout,
        }
    }

    /// Sends `request` and returns the body of its reply; scope frames received meanwhile
    /// go to `scope`.
    ///
    /// # Errors
    /// [`BoardError`]: refused, no reply in time, a bad reply.
    pub fn request_with(
        &mut self,
        request: &Request<'_>,
        scope: &mut dyn FnMut(ScopeChunk),
    ) -> Result<Vec<u8>, BoardError> {
        let mut w = Writer::new();
        request.encode(&mut w).map_err(BoardError::Reply)?;
        let seq = self.link.send_next(FrameKind::BoardRequest, w.as_slice())?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let frame = self.link.receive(deadline)?;
            match frame.kind {
                FrameKind::ScopeData => {
                    scope(ScopeChunk::decode(frame.payload()).map_err(BoardError::Reply)?);
                }
                // A late reply to an earlier request (after a timeout) is not this one's.
                FrameKind::BoardReply if frame.seq == seq => {
                    let reply = Reply::decode(frame.payload()).map_err(BoardError::Reply)?;
                    return match reply.result {
                        Ok(body) => Ok(body.to_vec()),
                        Err((refusal, message)) => Err(BoardError::Refused {
                            refusal,
                            message: message.to_string(),
                        }),
                    };
                }
                _ => {}
            }
        }
    }

    /// [`BoardClient::request_with`], no scope stream expected.
    ///
    /// # Errors
    /// As `request_with`.
    pub fn request(&mut self, request: &Request<'_>) -> Result<Vec<u8>, BoardError> {
        self.request_with(request, &mut |_| {})
    }

    /// The board's status, handed to `f`.
    ///
    /// # Errors
    /// As `request_with`.
    pub fn status<T>(&mut self, f: impl FnOnce(&StatusReport<'_>) -> T) -> Result<T, BoardError> {
        let body = self.request(&Request::Status)?;
        let report = StatusReport::decode(&body).map_err(BoardError::Reply)?;
        Ok(f(&report))
    }

    /// The value of `key`.
    ///
    /// # Errors
    /// As `request_with`; refused for an unknown key.
    pub fn get(&mut self, key: &str) -> Result<f64, BoardError> {
        get_f64(&self.request(&Request::Get(key))?).map_err(BoardError::Reply)
    }

    /// Sets `key` to `value`; returns the value as stored.
    ///
    /// # Errors
    /// As `request_with`; refused while enabled or out of range.
    pub fn set(&mut self, key: &str, value: f64) -> Result<f64, BoardError> {
        get_f64(&self.request(&Request::Set(key, value))?).map_err(BoardError::Reply)
    }

    /// The fault history.
    ///
    /// # Errors
    /// As `request_with`.
    pub fn faults(&mut self) -> Result<FaultHistory, BoardError> {
        FaultHistory::decode(&self.request(&Request::Faults)?).map_err(BoardError::Reply)
    }

    /// Starts the scope; returns its rate and channel names.
    ///
    /// # Errors
    /// As `request_with`.
    pub fn scope_start(&mut self) -> Result<(u32, Vec<String>), BoardError> {
        let body = self.request(&Request::ScopeStart)?;
        let info = ScopeInfo::decode(&body).map_err(BoardError::Reply)?;
        let names = info.channels.split(',').map(str::to_string).collect();
        Ok((info.rate_hz, names))
    }

    /// Receives scope chunks into `sink` until it returns false or `deadline` passes.
    ///
    /// # Errors
    /// A link error, or a bad chunk.
    pub fn scope_receive(
        &mut self,
        deadline: Instant,
        sink: &mut dyn FnMut(ScopeChunk) -> bool,
    ) -> Result<(), BoardError> {
        loop {
            let frame = self.link.receive(deadline)?;
            if frame.kind == FrameKind::ScopeData {
                let chunk = ScopeChunk::decode(frame.payload()).map_err(BoardError::Reply)?;
                if !sink(chunk) {
                    return Ok(());
                }
            }
        }
    }

    /// Writes `bytes` to the line as they are (tests: a damaged frame).
    ///
    /// # Errors
    /// An I/O error.
    pub fn write_raw(&mut self, bytes: &[u8]) -> Result<(), BoardError> {
        self.link.write_raw(bytes).map_err(BoardError::Host)
    }

    /// Waits up to `total` for the board to answer `Status` (after a reset: it reboots),
    /// asking every `every`.
    ///
    /// # Errors
    /// The last error when it never answered.
    pub fn wait_ready(&mut self, total: Duration, every: Duration) -> Result<(), BoardError> {
        let end = Instant::now() + total;
        let saved = self.timeout;
        self.timeout = every;
        let mut result = self.request(&Request::Status).map(|_| ());
        while result.is_err() && Instant::now() < end {
            result = self.request(&Request::Status).map(|_| ());
        }
        self.timeout = saved;
        result
    }
}

//! Bytes from a UART receive interrupt to thread mode (the `pil` and `board` images).

use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};

/// Bytes from the UART receive interrupt to thread mode: a single-producer single-consumer
/// ring of atomics (the interrupt only pushes, thread mode only pops).
pub struct ByteRing {
    bytes: [AtomicU8; RING_LEN],
    head: AtomicU32,
    tail: AtomicU32,
    overflows: AtomicU32,
}

/// Ring capacity in bytes (a power of two; more than one frame in flight never happens in
/// lock step, so this is generous).
pub const RING_LEN: usize = 512;

impl Default for ByteRing {
    fn default() -> Self {
        Self::new()
    }
}

impl ByteRing {
    /// An empty ring.
    pub const fn new() -> Self {
        Self {
            bytes: [const { AtomicU8::new(0) }; RING_LEN],
            head: AtomicU32::new(0),
            tail: AtomicU32::new(0),
            overflows: AtomicU32::new(0),
        }
    }

    /// Producer side (the receive interrupt). A full ring drops the byte and counts it: the
    /// frame it belonged to then fails its CRC, which the session treats as a link fault.
    pub fn push(&self, byte: u8) {
        let head = self.head.load(Ordering::Relaxed);
        let tail = self.tail.load(Ordering::Acquire);
        if head.wrapping_sub(tail) as usize >= RING_LEN {
            self.overflows.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if let Some(slot) = self.bytes.get(head as usize % RING_LEN) {
            slot.store(byte, Ordering::Relaxed);
        }
        self.head.store(head.wrapping_add(1), Ordering::Release);
    }

    /// Consumer side (thread mode).
    pub fn pop(&self) -> Option<u8> {
        let tail = self.tail.load(Ordering::Relaxed);
        let head = self.head.load(Ordering::Acquire);
        if head == tail {
            return None;
        }
        let byte = self
            .bytes
            .get(tail as usize % RING_LEN)
            .map_or(0, |slot| slot.load(Ordering::Relaxed));
        self.tail.store(tail.wrapping_add(1), Ordering::Release);
        Some(byte)
    }

    /// True when no byte is waiting.
    pub fn is_empty(&self) -> bool {
        self.head.load(Ordering::Acquire) == self.tail.load(Ordering::Relaxed)
    }

    /// Bytes dropped because the ring was full.
    pub fn overflows(&self) -> u32 {
        self.overflows.load(Ordering::Relaxed)
    }
}

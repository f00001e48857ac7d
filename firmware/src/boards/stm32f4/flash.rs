//! The board console's settings sector on the STM32F407: flash sector 11 (0x080E_0000,
//! 128 KiB), which `link/memory-stm32f407.x` keeps out of the image (region `SETTINGS`;
//! `link/check-stm32f407.x` ties it to [`SETTINGS_SECTOR`]). Erased and programmed through
//! the FLASH registers as RM0090 §3.6 describes: unlock (KEYR), PSIZE x32, sector erase
//! (SER, SNB, STRT), word programming (PG), each step waiting for BSY with a bounded poll
//! count and checked for the error flags; locked again on every path; then read back.
//!
//! While the flash erases or programs, every read of it stalls the bus: code and the
//! vector table are fetched from it, so the loop interrupts would be held up. A save
//! therefore runs only with the drive disabled (`board_console` refuses it otherwise),
//! stops the loop timers for its length and gives the watchdog a long timeout
//! (a sector erase takes up to 2 s at x32, RM0090 / the STM32F407 datasheet), and restores
//! both after.

use pil_link::board::store::{SaveError, RECORD_LEN};
use stm32f4::stm32f407 as pac;

use super::{iwdg, set_watchdog, tim6, tim7, Clocks, WATCHDOG_DRIVE, WATCHDOG_SAVE};

/// Address of the settings sector (sector 11; sector 7 on the three-phase image's
/// STM32F446RE, `link/memory-stm32f446re.x`).
pub const SETTINGS_SECTOR: usize = if cfg!(feature = "board-stm32f4-3ph") {
    0x0806_0000
} else {
    0x080E_0000
};
/// Bytes of the settings sector.
pub const SETTINGS_SECTOR_LEN: usize = 128 * 1024;
/// Its sector number (FLASH_CR.SNB).
const SECTOR: u32 = if cfg!(feature = "board-stm32f4-3ph") {
    7
} else {
    11
};
/// Words a record takes, the last padded with erased bytes (0xFF).
const RECORD_WORDS: usize = RECORD_LEN.div_ceil(4);

const _: () = assert!(RECORD_WORDS * 4 <= SETTINGS_SECTOR_LEN);

// KEYR unlock sequence.
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
// SR bits: EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR; BSY.
const SR_EOP: u32 = 1;
const SR_ERRORS: u32 = (1 << 1) | (1 << 4) | (1 << 5) | (1 << 6) | (1 << 7);
const SR_BSY: u32 = 1 << 16;
// CR bits: PG, SER, SNB[6:3], PSIZE[9:8] (0b10: x32), STRT, LOCK.
const CR_PG: u32 = 1;
const CR_SER: u32 = 1 << 1;
const CR_PSIZE_X32: u32 = 0b10 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
// ACR: data cache enable and reset (stale flash words must not be read back).
const ACR_DCEN: u32 = 1 << 10;
const ACR_DCRST: u32 = 1 << 12;

// SAFETY: FLASH's KEYR/CR/SR are written only here, from thread mode, and ACR only by
// `init` before and here after (the data-cache reset): a shared reference is sound.
register_block!(flash: FLASH => flash);

/// The word at `offset` bytes into the settings sector.
fn read_word(offset: usize) -> u32 {
    // SAFETY: `offset` < SETTINGS_SECTOR_LEN (callers index records, asserted above): a
    // word of flash that no Rust object occupies; a volatile read has no other effect.
    #[allow(unsafe_code)]
    unsafe {
        core::ptr::read_volatile((SETTINGS_SECTOR + offset) as *const u32)
    }
}

/// Reads the start of the settings sector into `record`.
pub fn read_settings_sector(record: &mut [u8; RECORD_LEN]) {
    for (i, chunk) in record.chunks_mut(4).enumerate() {
        let word = read_word(4 * i).to_le_bytes();
        for (b, w) in chunk.iter_mut().zip(word) {
            *b = w;
        }
    }
}

/// Polls for an erase: the clock's rate in polls, ≥ 4 s at ≥ 4 cycles a poll (twice the
/// datasheet's 2 s maximum for 128 KiB at x32); for a word: ≥ 1 ms (100 µs maximum).
fn polls(erase: bool) -> u32 {
    let hz = Clocks::now().sysclk_hz;
    if erase {
        hz
    } else {
        hz / 4000
    }
}

/// Waits until BSY clears (refreshing the watchdog), then checks the error flags of `step`.
fn finish(step: &'static str, polls: u32) -> Result<(), SaveError> {
    let f = flash();
    let mut idle = false;
    for _ in 0..polls {
        wr!(iwdg().kr(), 0xAAAA);
        if f.sr().read().bits() & SR_BSY == 0 {
            idle = true;
            break;
        }
    }
    if !idle {
        return Err(SaveError::Timeout(step));
    }
    let status = f.sr().read().bits();
    if status & SR_ERRORS != 0 {
        return Err(SaveError::Flash { step, status });
    }
    Ok(())
}

/// The record as words, the tail padded with 0xFF.
fn word(record: &[u8; RECORD_LEN], i: usize) -> u32 {
    let mut w = [0xFF_u8; 4];
    for (k, b) in w.iter_mut().enumerate() {
        if let Some(&r) = record.get(4 * i + k) {
            *b = r;
        }
    }
    u32::from_le_bytes(w)
}

/// The first byte offset of the record's words where `expected` does not read back.
fn first_mismatch(expected: impl Fn(usize) -> u32) -> Option<u32> {
    (0..RECORD_WORDS).find_map(|i| {
        let diff = read_word(4 * i) ^ expected(i);
        (diff != 0).then(|| (4 * i) as u32 + diff.trailing_zeros() / 8)
    })
}

/// Flushes the flash data cache, so reads after an erase or program see the flash.
fn flush_data_cache() {
    let f = flash();
    let on = f.acr().read().bits() & ACR_DCEN != 0;
    rmw!(f.acr(), ACR_DCEN, 0);
    rmw!(f.acr(), 0, ACR_DCRST);
    rmw!(f.acr(), ACR_DCRST, if on { ACR_DCEN } else { 0 });
}

/// Unlock, erase, blank check, program: the flash unlocked, to be locked by the caller.
fn erase_and_program(record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
    let f = flash();
    if f.cr().read().bits() & CR_LOCK != 0 {
        wr!(f.keyr(), KEY1);
        wr!(f.keyr(), KEY2);
    }
    if f.cr().read().bits() & CR_LOCK != 0 {
        return Err(SaveError::Locked);
    }
    finish("start", polls(true))?;
    wr!(f.sr(), SR_EOP | SR_ERRORS); // rc_w1: clear what an earlier operation left
    wr!(f.cr(), CR_PSIZE_X32 | CR_SER | (SECTOR << 3));
    wr!(f.cr(), CR_PSIZE_X32 | CR_SER | (SECTOR << 3) | CR_STRT);
    let erased = finish("erase", polls(true));
    wr!(f.cr(), 0);
    erased?;
    flush_data_cache();
    if let Some(offset) = first_mismatch(|_| u32::MAX) {
        return Err(SaveError::NotBlank { offset });
    }
    wr!(f.cr(), CR_PSIZE_X32 | CR_PG);
    let mut programmed = Ok(());
    for i in 0..RECORD_WORDS {
        // SAFETY: a word of the settings sector (RECORD_WORDS·4 ≤ its length), which the
        // image does not occupy; with PG set this write programs it.
        #[allow(unsafe_code)]
        unsafe {
            core::ptr::write_volatile((SETTINGS_SECTOR + 4 * i) as *mut u32, word(record, i));
        }
        programmed = finish("program", polls(false));
        if programmed.is_err() {
            break;
        }
    }
    wr!(f.cr(), 0);
    programmed
}

/// Writes `record` at the start of the settings sector (erasing it first) and reads it
/// back. The loop timers stop meanwhile and the watchdog runs with its long timeout.
///
/// # Errors
/// The step that failed ([`SaveError`]); the flash is locked again in every case.
pub fn write_settings_sector(record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
    let timers = (tim6().cr1().read().bits(), tim7().cr1().read().bits());
    wr!(tim6().cr1(), 0);
    wr!(tim7().cr1(), 0);
    set_watchdog(WATCHDOG_SAVE);
    let result = erase_and_program(record);
    rmw!(flash().cr(), 0, CR_LOCK);
    flush_data_cache();
    set_watchdog(WATCHDOG_DRIVE);
    wr!(tim6().cr1(), timers.0);
    wr!(tim7().cr1(), timers.1);
    result?;
    match first_mismatch(|i| word(record, i)) {
        Some(offset) => Err(SaveError::Verify { offset }),
        None => Ok(()),
    }
}

//! A NOR flash in RAM: erased bytes read `0xFF`, a write can only clear bits (written over
//! erased words, as on the STM32F4), erase sets a whole page back to `0xFF`. The QEMU board
//! keeps its parameter store in one (QEMU's netduinoplus2 does not emulate the flash
//! controller, so the store lasts until QEMU exits), and the host tests run the store on it.
//!
//! Owns [`RamFlash`], [`RamFlashError`]. May import nothing of the crate.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Word size of [`RamFlash`] writes, bytes (the STM32F4's with x32 parallelism).
pub const WORD: usize = 4;

/// `SIZE` bytes of NOR flash in pages of `PAGE` bytes (`SIZE` a multiple of `PAGE`).
#[derive(Clone)]
pub struct RamFlash<const SIZE: usize, const PAGE: usize> {
    mem: [u8; SIZE],
}

impl<const SIZE: usize, const PAGE: usize> Default for RamFlash<SIZE, PAGE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize, const PAGE: usize> RamFlash<SIZE, PAGE> {
    /// Erased flash.
    pub const fn new() -> Self {
        Self { mem: [0xFF; SIZE] }
    }

    /// All bits programmed (0x00): erase before use. A `static` of it goes to `.bss` (zeroed at
    /// reset) rather than carrying an 0xFF image in `.data` (the QEMU board's store).
    pub const fn zeroed() -> Self {
        Self { mem: [0; SIZE] }
    }

    /// The raw image (tests).
    pub fn bytes(&self) -> &[u8] {
        &self.mem
    }

    /// The raw image, writable (tests corrupt it).
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.mem
    }
}

/// A [`RamFlash`] operation outside the memory or not aligned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RamFlashError {
    /// Outside the memory.
    OutOfBounds,
    /// Not word- (write) or page- (erase) aligned.
    NotAligned,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
        }
    }
}

impl<const SIZE: usize, const PAGE: usize> ErrorType for RamFlash<SIZE, PAGE> {
    type Error = RamFlashError;
}

fn span(offset: u32, len: usize, size: usize) -> Result<core::ops::Range<usize>, RamFlashError> {
    let start = offset as usize;
    let end = start.checked_add(len).ok_or(RamFlashError::OutOfBounds)?;
    if end > size {
        return Err(RamFlashError::OutOfBounds);
    }
    Ok(start..end)
}

impl<const SIZE: usize, const PAGE: usize> ReadNorFlash for RamFlash<SIZE, PAGE> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let r = span(offset, bytes.len(), SIZE)?;
        let src = self.mem.get(r).ok_or(RamFlashError::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize, const PAGE: usize> NorFlash for RamFlash<SIZE, PAGE> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if !(from as usize).is_multiple_of(PAGE) || !(to as usize).is_multiple_of(PAGE) || to < from {
            return Err(RamFlashError::NotAligned);
        }
        let r = span(from, (to - from) as usize, SIZE)?;
        self.mem.get_mut(r).ok_or(RamFlashError::OutOfBounds)?.fill(0xFF);
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if !(offset as usize).is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD) {
            return Err(RamFlashError::NotAligned);
        }
        let r = span(offset, bytes.len(), SIZE)?;
        for (m, b) in self.mem.get_mut(r).ok_or(RamFlashError::OutOfBounds)?.iter_mut().zip(bytes) {
            *m &= *b;
        }
        Ok(())
    }
}

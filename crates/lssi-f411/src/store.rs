//! The configuration kept across resets: the last `Configure` a host sent and the device
//! accepted, in flash sector 7 (0x0806_0000, 128 KiB; memory.x leaves it out of FLASH).
//!
//! Layout: `MAGIC` (4 bytes), the frame's length (u16, little-endian), then the frame
//! exactly as it came over the wire (postcard, CRC-32C, COBS): the CRC guards the stored
//! copy too, and a frame of another protocol version does not decode, so an image of a
//! newer protocol starts from its own configuration instead of misreading an old one.
//!
//! Erasing the sector stalls the flash for about a second (RM0383: 1–2 s for 128 KiB at
//! x32 parallelism): no interrupt handler in flash runs meanwhile. The caller counts the
//! samples the timer did not take as overruns; the identifier restarts with the new
//! configuration anyway.

use lssi_core::Config;
use lssi_device::wire;
use lssi_proto::{HostMsg, MAX_HOST_FRAME_LEN, WireConfig, WireDuty, decode_frame, encode};
use stm32f4xx_hal::flash::{Error, FlashExt, LockedFlash};

/// The sector and its offset from the start of flash.
const SECTOR: u8 = 7;
const OFFSET: usize = 0x6_0000;
/// "LSSI" in ASCII: a written record (an erased sector reads 0xFF).
const MAGIC: [u8; 4] = *b"LSSI";
const HEADER: usize = 6;

/// Why the stored configuration is not used.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub enum Unused {
    /// No record (a fresh part, or never configured by a host).
    Empty,
    /// A record whose frame does not decode (damaged, or another protocol version).
    Undecodable,
}

/// The stored configuration and its duty cycle, if there is one that decodes.
pub fn load(flash: &LockedFlash) -> Result<(Config, Option<WireDuty>), Unused> {
    let bytes = flash.read();
    let Some(record) = bytes.get(OFFSET..OFFSET + HEADER + MAX_HOST_FRAME_LEN) else {
        return Err(Unused::Empty);
    };
    if record[..4] != MAGIC {
        return Err(Unused::Empty);
    }
    let len = usize::from(u16::from_le_bytes([record[4], record[5]]));
    if len == 0 || len > MAX_HOST_FRAME_LEN {
        return Err(Unused::Undecodable);
    }
    let mut frame = [0u8; MAX_HOST_FRAME_LEN];
    frame[..len].copy_from_slice(&record[HEADER..HEADER + len]);
    match decode_frame::<HostMsg>(&mut frame[..len]) {
        Ok(HostMsg::Configure(c)) => Ok((wire::config_from_wire(&c), c.duty)),
        _ => Err(Unused::Undecodable),
    }
}

/// Keeps `config` (erases the sector, then writes the record).
pub fn save(flash: &mut LockedFlash, config: &WireConfig) -> Result<(), Error> {
    let mut record = [0u8; HEADER + MAX_HOST_FRAME_LEN];
    let Ok(len) = encode(&HostMsg::Configure(*config), &mut record[HEADER..]) else {
        defmt::panic!("a Configure frame is larger than MAX_HOST_FRAME_LEN")
    };
    record[..4].copy_from_slice(&MAGIC);
    record[4..HEADER].copy_from_slice(&(len as u16).to_le_bytes());
    let mut unlocked = flash.unlocked();
    unlocked.erase(SECTOR)?;
    unlocked.program(OFFSET, record[..HEADER + len].iter())
}

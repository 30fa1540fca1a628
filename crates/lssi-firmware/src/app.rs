//! The demo application: echoes every byte received back to the host, so the link can be
//! tested end to end. `lssi-device`'s command loop takes its place (see `main.rs`).

use lssi_firmware::transport::Transport;

/// Echoes forever.
pub fn run(link: &mut impl Transport) -> ! {
    let mut echoed: u32 = 0;
    loop {
        if let Some(b) = link.read() {
            link.write(&[b]);
            echoed = echoed.wrapping_add(1);
            defmt::trace!("echo {=u8:#04x} ({=u32} so far)", b, echoed);
            if b == b'\n' {
                defmt::debug!("echoed {=u32} bytes", echoed);
            }
        }
    }
}

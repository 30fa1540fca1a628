//! The defmt global logger: every encoded defmt frame goes to the debug transport
//! (semihosting under feature `qemu`, RTT under feature `rtt`) **and** into a small ring
//! buffer ([`RING_LEN`] bytes in `.bss`) that the main loop drains over the UART as
//! `DeviceMsg::Log` frames ([`take`], then `lssi_device::Device::send_log`), so that a board
//! without a debugger still reports its log lines to the host.
//!
//! The ring holds whole defmt frames only: a frame is staged as the encoder produces it and
//! committed when it ends; if it does not fit, the whole frame is dropped (the frames already
//! in the ring stay) and [`dropped`] counts it. The bytes come out in order, so the host can
//! concatenate the contents of the `Log` frames into one defmt stream. All state is touched
//! with interrupts disabled (from `acquire` to `release`, and inside [`take`]).

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Bytes of the ring buffer (a defmt frame of the start-up lines is 3 to 20 bytes).
pub const RING_LEN: usize = 256;

/// Committed bytes `[head, head + len)` (modulo [`RING_LEN`]); the frame being written is
/// staged in the `staged` bytes after them.
struct Ring {
    buf: [u8; RING_LEN],
    head: u16,
    len: u16,
    staged: u16,
    overflow: bool,
}

impl Ring {
    const fn new() -> Self {
        Self {
            buf: [0; RING_LEN],
            head: 0,
            len: 0,
            staged: 0,
            overflow: false,
        }
    }

    fn begin(&mut self) {
        self.staged = 0;
        self.overflow = false;
    }

    fn stage(&mut self, bytes: &[u8]) {
        if self.overflow {
            return;
        }
        let used = usize::from(self.len) + usize::from(self.staged);
        if RING_LEN - used < bytes.len() {
            self.overflow = true;
            return;
        }
        let mut at = (usize::from(self.head) + used) % RING_LEN;
        for &b in bytes {
            self.buf[at] = b;
            at = (at + 1) % RING_LEN;
        }
        // Fits: used + bytes.len() <= RING_LEN <= u16::MAX.
        self.staged += bytes.len() as u16;
    }

    /// Commits the staged frame; `false` if it overflowed and was dropped.
    fn commit(&mut self) -> bool {
        let whole = !self.overflow;
        if whole {
            self.len += self.staged;
        }
        self.begin();
        whole
    }

    fn take(&mut self, out: &mut [u8]) -> usize {
        let n = out.len().min(usize::from(self.len));
        let mut at = usize::from(self.head);
        for slot in &mut out[..n] {
            *slot = self.buf[at];
            at = (at + 1) % RING_LEN;
        }
        // Both fit in u16: at < RING_LEN, n <= len.
        self.head = at as u16;
        self.len -= n as u16;
        n
    }
}

/// The logger's state, only touched with interrupts disabled while [`TAKEN`] is set (or
/// inside [`take`], which runs with interrupts disabled and `TAKEN` clear).
struct State {
    encoder: defmt::Encoder,
    sink: Sink,
    /// Interrupts were enabled before `acquire` disabled them.
    restore: bool,
}

/// Where the encoded bytes go: the debug transport and the ring.
struct Sink {
    ring: Ring,
    #[cfg(feature = "qemu")]
    stdout: Option<semihosting::io::Stdout>,
}

impl Sink {
    /// Sends encoded bytes to the debug transport and stages them in the ring.
    fn emit(&mut self, bytes: &[u8]) {
        #[cfg(feature = "qemu")]
        if let Some(out) = self.stdout.as_mut() {
            use semihosting::io::Write as _;
            let _ = out.write_all(bytes);
        }
        #[cfg(feature = "rtt")]
        rtt::write_all(bytes);
        self.ring.stage(bytes);
    }
}

struct Shared(UnsafeCell<State>);

#[allow(unsafe_code)]
// SAFETY: every access to the inner state happens with interrupts disabled on this single
// core, and `TAKEN` rules out re-entry from the logger itself.
unsafe impl Sync for Shared {}

static STATE: Shared = Shared(UnsafeCell::new(State {
    encoder: defmt::Encoder::new(),
    sink: Sink {
        ring: Ring::new(),
        #[cfg(feature = "qemu")]
        stdout: None,
    },
    restore: false,
}));

/// Set from `acquire` to `release`.
static TAKEN: AtomicBool = AtomicBool::new(false);
/// defmt frames dropped because the ring was full.
static DROPPED: AtomicU32 = AtomicU32::new(0);

/// Runs `f` on the state. Callers hold interrupts disabled and are the only user of the
/// state for the duration (see [`State`]).
fn with_state<R>(f: impl FnOnce(&mut State) -> R) -> R {
    #[allow(unsafe_code)]
    // SAFETY: see `State`: interrupts are disabled and no other reference is live (the
    // reference does not escape `f`).
    let state = unsafe { &mut *STATE.0.get() };
    f(state)
}

#[defmt::global_logger]
struct Logger;

#[allow(unsafe_code)]
// SAFETY: `acquire` disables interrupts and refuses re-entry, so `write`, `flush` and
// `release` run alone; defmt pairs each `acquire` with one `release`.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        let enabled = cortex_m::register::primask::read().is_active();
        cortex_m::interrupt::disable();
        if TAKEN.load(Ordering::Relaxed) {
            panic!("defmt logger taken reentrantly")
        }
        TAKEN.store(true, Ordering::Relaxed);
        with_state(|s| {
            s.restore = enabled;
            #[cfg(feature = "qemu")]
            if s.sink.stdout.is_none() {
                s.sink.stdout = semihosting::io::stdout().ok();
            }
            s.sink.ring.begin();
            let State { encoder, sink, .. } = s;
            encoder.start_frame(|b| sink.emit(b));
        });
    }

    unsafe fn flush() {}

    unsafe fn release() {
        if !TAKEN.load(Ordering::Relaxed) {
            panic!("defmt release out of context")
        }
        let restore = with_state(|s| {
            let State { encoder, sink, .. } = s;
            encoder.end_frame(|b| sink.emit(b));
            if !sink.ring.commit() {
                DROPPED.fetch_add(1, Ordering::Relaxed);
            }
            s.restore
        });
        TAKEN.store(false, Ordering::Relaxed);
        if restore {
            #[allow(unsafe_code)]
            // SAFETY: interrupts were enabled before the matching `acquire`.
            unsafe {
                cortex_m::interrupt::enable()
            };
        }
    }

    unsafe fn write(bytes: &[u8]) {
        if !TAKEN.load(Ordering::Relaxed) {
            panic!("defmt write out of context")
        }
        with_state(|s| {
            let State { encoder, sink, .. } = s;
            encoder.write(bytes, |b| sink.emit(b));
        });
    }
}

/// Moves up to `out.len()` bytes of whole, committed defmt frames (in order) out of the
/// ring into `out` and returns how many (0: nothing to send). Frames may be split across
/// calls; the host concatenates. Call it from the main loop, not from the logger.
pub fn take(out: &mut [u8]) -> usize {
    cortex_m::interrupt::free(|_| {
        if TAKEN.load(Ordering::Relaxed) {
            // Called while a frame is being written (from a fault handler): leave it.
            return 0;
        }
        with_state(|s| s.sink.ring.take(out))
    })
}

/// defmt frames dropped since reset because the ring was full.
pub fn dropped() -> u32 {
    DROPPED.load(Ordering::Relaxed)
}

/// A minimal SEGGER RTT control block with one up channel, "defmt", as probe-rs expects
/// (the layout of defmt-rtt's): non-blocking (the rest of a write is dropped when the
/// buffer is full) unless the probe switches the channel to blocking mode.
#[cfg(feature = "rtt")]
mod rtt {
    use core::cell::UnsafeCell;
    use core::mem::MaybeUninit;
    use core::sync::atomic::{AtomicU32, Ordering};

    const SIZE: usize = 1024;
    const MODE_MASK: u32 = 0b11;
    const MODE_BLOCK_IF_FULL: u32 = 2;
    const MODE_NON_BLOCKING_TRIM: u32 = 1;

    #[repr(C)]
    pub(super) struct Header {
        id: [u8; 16],
        max_up_channels: u32,
        max_down_channels: u32,
        up: Channel,
    }

    #[repr(C)]
    struct Channel {
        name: *const u8,
        buffer: *mut u8,
        size: u32,
        write: AtomicU32,
        read: AtomicU32,
        flags: AtomicU32,
    }

    #[allow(unsafe_code)]
    // SAFETY: the pointers are to statics; the buffer is written only by `write_all`, with
    // interrupts disabled (inside the logger), and read by the probe.
    unsafe impl Sync for Header {}

    struct Buffer(UnsafeCell<MaybeUninit<[u8; SIZE]>>);

    #[allow(unsafe_code)]
    // SAFETY: as for `Header`.
    unsafe impl Sync for Buffer {}

    // `.uninit` (cortex-m-rt's NOLOAD section): 1 KiB the start-up need not zero, as in
    // defmt-rtt. SAFETY: the section exists in cortex-m-rt's link.x, and the buffer is
    // `MaybeUninit`, only written before the probe reads it.
    #[allow(unsafe_code)]
    #[unsafe(link_section = ".uninit.lssi-rtt.BUFFER")]
    static BUFFER: Buffer = Buffer(UnsafeCell::new(MaybeUninit::uninit()));

    static NAME: [u8; 6] = *b"defmt\0";

    #[allow(unsafe_code)]
    #[unsafe(no_mangle)]
    static _SEGGER_RTT: Header = Header {
        id: *b"SEGGER RTT\0\0\0\0\0\0",
        max_up_channels: 1,
        max_down_channels: 0,
        up: Channel {
            name: NAME.as_ptr(),
            buffer: BUFFER.0.get().cast(),
            size: SIZE as u32,
            write: AtomicU32::new(0),
            read: AtomicU32::new(0),
            flags: AtomicU32::new(MODE_NON_BLOCKING_TRIM),
        },
    };

    /// Appends `bytes` to the up channel (see the module's note on blocking).
    pub(super) fn write_all(mut bytes: &[u8]) {
        let ch = &_SEGGER_RTT.up;
        let blocking = ch.flags.load(Ordering::Relaxed) & MODE_MASK == MODE_BLOCK_IF_FULL;
        while !bytes.is_empty() {
            let write = ch.write.load(Ordering::Acquire) as usize;
            let read = ch.read.load(Ordering::Relaxed) as usize;
            let room = if read > write {
                read - write - 1
            } else if read == 0 {
                SIZE - write - 1
            } else {
                SIZE - write
            };
            if room == 0 {
                if blocking {
                    continue;
                }
                return;
            }
            let n = room.min(bytes.len());
            #[allow(unsafe_code)]
            // SAFETY: `write + n <= SIZE`, and the probe reads only `[read, write)`.
            unsafe {
                core::ptr::copy_nonoverlapping(bytes.as_ptr(), ch.buffer.add(write), n);
            }
            ch.write
                .store(((write + n) % SIZE) as u32, Ordering::Release);
            bytes = &bytes[n..];
        }
    }
}

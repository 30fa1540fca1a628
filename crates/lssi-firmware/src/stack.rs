//! Peak stack use, by painting.
//!
//! cortex-m-rt's `paint-stack` feature fills the whole stack region, from `_stack_end` (just
//! above the statics) up to `_stack_start` (the initial stack pointer), with
//! [`PAINT`] in its reset handler, before `main` runs and before any Rust code touches the
//! stack. This replaces a `#[pre_init]` hook, which is deprecated because it runs Rust code
//! before RAM is initialised. Whatever the program has used since is no longer painted:
//! [`peak_used`] finds the lowest unpainted word.
//!
//! To measure one phase rather than the whole run, [`repaint`] paints again everything below
//! the current stack pointer; [`peak_used`] after the phase then minus the depth at the call
//! ([`used_now`]) is the phase's own use.
//!
//! The region is the whole of RAM above the statics (4 MiB less a little on the
//! mps2-an386 memory map); scanning it takes about 6 instructions a word (6.3 million
//! instructions there, 0.25 s of a 25 MHz core).

/// The word cortex-m-rt paints the stack with.
pub const PAINT: u32 = cortex_m_rt::STACK_PAINT_VALUE;

#[allow(unsafe_code)]
// SAFETY (of the declaration): both symbols are defined by cortex-m-rt's `link.x`; only
// their addresses are used, never their contents.
unsafe extern "C" {
    /// Top of the stack region (exclusive): the initial stack pointer.
    static _stack_start: u32;
    /// Bottom of the stack region (inclusive), 4-aligned, above `.bss` and `.uninit`.
    static _stack_end: u32;
}

/// `(bottom, top)` addresses of the stack region.
fn region() -> (usize, usize) {
    (
        (&raw const _stack_end) as usize,
        (&raw const _stack_start) as usize,
    )
}

/// Size of the stack region in bytes.
pub fn size() -> usize {
    let (bottom, top) = region();
    top - bottom
}

/// Bytes of stack in use at the caller (initial stack pointer minus the current one).
#[inline(always)]
pub fn used_now() -> usize {
    region()
        .1
        .saturating_sub(cortex_m::register::msp::read() as usize)
}

/// Peak stack use in bytes since reset, or since the last [`repaint`]: the distance from
/// the top of the stack to the lowest word that no longer holds [`PAINT`].
pub fn peak_used() -> usize {
    let (bottom, top) = region();
    let mut address = bottom;
    while address < top && read_word(address) == PAINT {
        address += 4;
    }
    top - address
}

/// Paints the stack below the current stack pointer again, so that a following
/// [`peak_used`] reports the deepest point reached after this call.
#[inline(never)]
pub fn repaint() {
    let (bottom, _) = region();
    #[allow(unsafe_code)]
    // SAFETY: the loop writes whole words from `bottom` (4-aligned, the lowest address of
    // the stack region) up to, not including, the stack pointer as it is inside this asm
    // block. Everything there is free stack: live frames, this function's included, lie at
    // or above the pointer (reading it in Rust instead would let the compiler push the
    // frame after the read and paint over it). The block itself pushes nothing; an
    // interrupt taken meanwhile pushes its frame below the pointer and is gone on return.
    unsafe {
        core::arch::asm!(
            "mov {limit}, sp",
            "2:",
            "cmp {address}, {limit}",
            "bhs 3f",
            "str {paint}, [{address}], #4",
            "b 2b",
            "3:",
            address = inout(reg) bottom => _,
            limit = out(reg) _,
            paint = in(reg) PAINT,
            options(nostack),
        );
    }
}

#[inline(always)]
fn read_word(address: usize) -> u32 {
    #[allow(unsafe_code)]
    // SAFETY: callers pass a 4-aligned address inside the stack region [_stack_end,
    // _stack_start), which is RAM. The part below the stack pointer belongs to no Rust
    // object; the part above may be live frames, which a volatile read does not disturb.
    unsafe {
        core::ptr::read_volatile(address as *const u32)
    }
}

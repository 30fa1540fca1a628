//! A static handed out once as `&'static mut`: where the firmware keeps the device
//! application (16 KiB, too big to build on the stack and move).
//!
//! ```ignore
//! static DEVICE: TakeOnce<Device> = TakeOnce::new();
//! let device: &'static mut Device = DEVICE.take_with(Device::new).expect("taken once");
//! ```
//!
//! The storage is zeroed `.bss`, and the value is built in place the first time: a value
//! given in the static's initialiser would go to `.data` as soon as one of its bytes is not
//! zero (lssi-device's `Device` has a few), and `.data` costs its whole size in flash too.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

/// Storage for a value in a static, built and lent out mutably at most once.
pub struct TakeOnce<T> {
    taken: AtomicBool,
    value: UnsafeCell<MaybeUninit<T>>,
}

#[allow(unsafe_code)]
// SAFETY: the only access to `value` is through `take_with`, which hands out one `&mut` for
// the whole program and never another (the atomic swap decides, also against an interrupt
// handler calling it); `T: Send` because that reference may be taken in any context.
unsafe impl<T: Send> Sync for TakeOnce<T> {}

impl<T> Default for TakeOnce<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> TakeOnce<T> {
    /// Empty storage (usable in a `static` initialiser).
    pub const fn new() -> Self {
        Self {
            taken: AtomicBool::new(false),
            value: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }

    /// Builds the value with `init` in place and returns it, the first time; `None` after
    /// (and `init` is not called).
    #[inline(always)]
    #[allow(
        clippy::mut_from_ref,
        reason = "the atomic flag makes this the only reference ever handed out"
    )]
    pub fn take_with(&'static self, init: impl FnOnce() -> T) -> Option<&'static mut T> {
        if self.taken.swap(true, Ordering::AcqRel) {
            return None;
        }
        #[allow(unsafe_code)]
        // SAFETY: the swap above returned `false` exactly once, so this is the only
        // reference to the storage there will ever be; it lives as long as the static.
        let slot = unsafe { &mut *self.value.get() };
        Some(slot.write(init()))
    }
}

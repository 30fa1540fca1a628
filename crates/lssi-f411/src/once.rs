//! (A copy of lssi-firmware's `once`, which this crate does not depend on.) A static handed out once as `&'static mut`: where the firmware keeps the device
//! application and the benchmark its identifier (10 KiB, too big to build on the stack and
//! move).
//!
//! ```ignore
//! #[unsafe(link_section = ".bss.lssi.DEVICE")]
//! static DEVICE: TakeOnce<Device> = TakeOnce::new(Device::new());
//! let device: &'static mut Device = DEVICE.take().expect("taken once");
//! ```
//!
//! The value is the static's initialiser, a constant: nothing is built at run time, so it
//! never exists on the stack (a value built at start-up and written into the static was
//! built in `app::run`'s frame first and copied, 9.5 KB of stack for good). Its bytes must
//! all be zero, as lssi-device's `Device::new()` and lssi-core's `IdentifierSlot::new()`
//! are: then the static lies in `.bss` and costs no flash (in `.data` it would cost its
//! whole size in flash too). Put such a static in a `.bss.*` section explicitly, as above:
//! an initialiser with a byte that is not zero then fails the build ("non-zero initializer
//! found in section") instead of moving 10 KiB into flash unnoticed.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

/// Storage for a value in a static, lent out mutably at most once.
pub struct TakeOnce<T> {
    taken: AtomicBool,
    value: UnsafeCell<T>,
}

#[allow(unsafe_code)]
// SAFETY: the only access to `value` is through `take`, which hands out one `&mut` for the
// whole program and never another (the atomic swap decides, also against an interrupt
// handler calling it); `T: Send` because that reference may be taken in any context.
unsafe impl<T: Send> Sync for TakeOnce<T> {}

impl<T> TakeOnce<T> {
    /// Storage holding `value` (usable in a `static` initialiser, where `value` is a
    /// constant: see the module docs for why its bytes should all be zero).
    pub const fn new(value: T) -> Self {
        Self {
            taken: AtomicBool::new(false),
            value: UnsafeCell::new(value),
        }
    }

    /// The value, the first time; `None` after.
    #[allow(
        clippy::mut_from_ref,
        reason = "the atomic flag makes this the only reference ever handed out"
    )]
    pub fn take(&'static self) -> Option<&'static mut T> {
        if self.taken.swap(true, Ordering::AcqRel) {
            return None;
        }
        #[allow(unsafe_code)]
        // SAFETY: the swap above returned `false` exactly once, so this is the only
        // reference to the storage there will ever be; it lives as long as the static.
        Some(unsafe { &mut *self.value.get() })
    }
}

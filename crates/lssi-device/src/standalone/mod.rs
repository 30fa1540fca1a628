//! The standalone instrument: the device samples its own sensor by a timer, identifies
//! without a host and reports by itself. Board-independent and safe: a board (the QEMU
//! stand-in, a real part with its HAL) wires these three parts to its interrupts.
//!
//! ```text
//! timer interrupt (highest)   Sampler::tick   reading + timer stamp → Event queue (spsc, 64) ; full → overruns += 1
//! identify (middle priority)  Engine::run     queue → Identifier::push_with; at a screening, a Snapshot → Shared
//! thread mode (lowest)        Reporter        Snapshot → select() → Model ; Model + Health every period ; RX commands
//! ```
//!
//! - **Time comes from the timer**: a sample's `t` is its index over the sampling rate, its
//!   stamp the clock at the interrupt; when the identify task runs does not move either.
//! - **No stall**: the screening (≈ 18 M instructions on the M4F) runs in thread mode on a
//!   [`Snapshot`] while rows go on at a higher priority; the model is, bit for bit, the one
//!   the identifier would have made in place (`Identifier::push_with`), so the host's
//!   `lssi identify` gives the device's model.
//! - **Channels far from zero lose no bits**: each engine learns a reference per channel
//!   from its first 1,024 finite rows ([`References`]: `lssi identify`'s rule, the mean when
//!   it lies more than 3 ranges from zero; x and v, and a system's electrical channel). Rows
//!   go to the identifier as they come until then; a channel far from zero then restarts
//!   the identifier in place and every row from that one on is pushed less its reference.
//!   `Health` carries the references (`reference`): the model is about the channels less
//!   them. Channels about zero never restart anything.
//! - **Ownership moves, nothing is shared mutably**: the one snapshot travels between the
//!   identify task and thread mode as a `&'static mut` through two one-place mailboxes
//!   (critical sections of a few instructions); counters are atomics.
//!
//! The board provides a [`Clock`] (a free-running tick counter), a [`Transport`] for
//! frames, and calls [`Engine::run`] whenever the timer has queued a sample (e.g. by pending
//! a software interrupt).

mod engine;
mod flavour;
mod reference;
mod reporter;
mod sampler;
mod shared;
#[cfg(feature = "system")]
mod system;

#[cfg(doc)]
use crate::Transport;
pub use engine::{Engine, IdentifyTask, Task};
pub use flavour::{FromHost, Screening};
#[cfg(doc)]
use lssi_core::Snapshot;
pub use reference::{REFERENCE_RANGES, REFERENCE_ROWS, References, Rule};
pub use reporter::{Drift, Reporter};
pub use sampler::{STUCK_RUN, Sampler, Schedule};
pub use shared::{
    Clock, Counters, Event, EventQueue, QUEUE_SLOTS, Reading, Shared, Status, model_stride_for,
};
#[cfg(feature = "system")]
pub use system::{SystemEngine, SystemShot};

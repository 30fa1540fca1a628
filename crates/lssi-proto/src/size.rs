//! Worst-case sizes, computed at compile time.
//!
//! ```
//! use lssi_proto::size::{frame_len, varint_len};
//! assert_eq!(varint_len(127), 1);
//! assert_eq!(varint_len(128), 2);
//! // 492 bytes of payload and CRC: two COBS code bytes and the 0x00 delimiter.
//! assert_eq!(frame_len(488), 495);
//! ```
//!
//! postcard's [`MaxSize`] derive knows heapless 0.7 only, so the types here
//! that hold a `heapless::Vec` (0.9) implement it by hand from these helpers; the `max_size`
//! test checks each by hand-made implementation against the encoding of its worst-case value.

use crate::CRC_LEN;
use postcard::experimental::max_size::MaxSize;

/// Bytes postcard spends on `n` as a varint (lengths, enum discriminants, `u16`..`u64`).
pub const fn varint_len(n: usize) -> usize {
    let mut len = 1;
    let mut rest = n >> 7;
    while rest != 0 {
        len += 1;
        rest >>= 7;
    }
    len
}

/// Worst-case postcard size of a sequence of at most `capacity` elements of `T`:
/// the varint length, then the elements.
pub const fn vec_max_size<T: MaxSize>(capacity: usize) -> usize {
    varint_len(capacity) + capacity * T::POSTCARD_MAX_SIZE
}

/// Longest frame for a message of at most `message_len` postcard bytes: the CRC, COBS's
/// worst case (one code byte per 254 bytes, plus one), and the `0x00` delimiter.
pub const fn frame_len(message_len: usize) -> usize {
    let stuffed = message_len + CRC_LEN;
    stuffed + stuffed / 254 + 1 + 1
}

/// The larger of `a` and `b`, usable in constants.
pub const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

/// The largest of `sizes`, usable in constants (0 when empty).
pub const fn max_of(sizes: &[usize]) -> usize {
    let mut largest = 0;
    let mut rest = sizes;
    while let [first, tail @ ..] = rest {
        largest = max(largest, *first);
        rest = tail;
    }
    largest
}

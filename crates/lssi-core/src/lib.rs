//! lssi core (placeholder).
#![no_std]

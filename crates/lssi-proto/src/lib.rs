//! The lssi wire format (placeholder).
#![no_std]

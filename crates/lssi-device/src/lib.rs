//! The lssi device application (placeholder until the replay work lands).
#![no_std]

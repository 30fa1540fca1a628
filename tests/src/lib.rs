//! End-to-end tests across the lssi crates; the tests live in `tests/tests/`.

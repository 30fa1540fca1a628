//! The `lssi` command (placeholder).
fn main() {}

//! firmware-sim (placeholder until the replay work lands).
fn main() {}

//! Ephemeris benches (placeholder until the ephem subsystem lands).
fn main() {}

//! Placeholder for the ephemeris benchmark (the lead's branch replaces this file).
fn main() {}

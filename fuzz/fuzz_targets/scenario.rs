//! Scenario TOML: parsing and the whole-scenario preflight.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    if let Ok(text) = std::str::from_utf8(bytes) {
        let _ = penumbra::scenario::Scenario::from_toml(text, std::path::Path::new("fuzz.toml"));
    }
});

//! Site files: the input as CSV and as GeoJSON (the reader takes a path: a file in /dev/shm).
#![no_main]
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from("/dev/shm").join(format!("penumbra-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    dir.join(name)
}

libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    for name in ["s.csv", "s.geojson"] {
        let path = scratch(name);
        std::fs::write(&path, bytes).unwrap();
        let _ = penumbra::model::read_sites_file(&path, Default::default());
    }
});

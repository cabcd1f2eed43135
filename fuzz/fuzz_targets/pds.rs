//! PDS3 (attached label) and PDS4 (XML label naming `pds4_seed.img`, copied beside it from the
//! fuzz fixtures) DEM readers; the input is the label (PDS3: label and image in one file).
#![no_main]
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from("/dev/shm").join(format!("penumbra-fuzz-{}", std::process::id()));
    if !dir.join("pds4_seed.img").exists() {
        std::fs::create_dir_all(&dir).unwrap();
        let fixture = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures/fuzz/pds4_seed.img");
        std::fs::copy(fixture, dir.join("pds4_seed.img")).unwrap();
    }
    dir.join(name)
}

libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let img = scratch("a.img");
    std::fs::write(&img, bytes).unwrap();
    if let Ok(dem) = penumbra::terrain::pds3::read_pds3(&img) {
        let _ = dem.check();
    }
    let xml = scratch("a.xml");
    std::fs::write(&xml, bytes).unwrap();
    if let Ok(dem) = penumbra::terrain::pds4::read_pds4(&xml) {
        let _ = dem.check();
    }
});

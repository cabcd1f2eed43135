//! Fourier horizon-map TIFF reader.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let _ = penumbra::shadow::fourier::HorizonMap::read_tiff_from(
        std::io::Cursor::new(bytes),
        bytes.len() as u64,
        "fuzz",
    );
});

//! GeoTIFF DEM reader (strips, tiles, Deflate, LZW; every sample format), then the DEM's checks.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    if let Ok((dem, _)) =
        penumbra::terrain::geotiff::read_geotiff_from(std::io::Cursor::new(bytes), "fuzz")
    {
        let _ = dem.check();
    }
});

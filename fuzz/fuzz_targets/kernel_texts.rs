//! SPICE text kernels in memory: the meta-kernel parser, the leap-seconds check and the
//! frame-kernel conversion (anise's text kernel parser).
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let name = std::path::Path::new("fuzz");
    let _ = penumbra::ephem::metakernel::kernels_to_load(&String::from_utf8_lossy(bytes));
    let _ = penumbra::ephem::kernels::check_leap_seconds(name, bytes);
    let _ = penumbra::ephem::kernels::frame_parameters(name, bytes);
});

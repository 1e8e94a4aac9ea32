#![no_main]
//! cargo-fuzz target `view`: see `fbwag_fuzz::view` (fuzz/src/lib.rs).
libfuzzer_sys::fuzz_target!(|data: &[u8]| fbwag_fuzz::view(data));

#![no_main]
//! cargo-fuzz target `frame`: see `fbwag_fuzz::frame` (fuzz/src/lib.rs).
libfuzzer_sys::fuzz_target!(|data: &[u8]| fbwag_fuzz::frame(data));

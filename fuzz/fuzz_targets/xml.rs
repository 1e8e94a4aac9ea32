#![no_main]
//! cargo-fuzz target `xml`: see `fbwag_fuzz::xml` (fuzz/src/lib.rs).
libfuzzer_sys::fuzz_target!(|data: &[u8]| fbwag_fuzz::xml(data));

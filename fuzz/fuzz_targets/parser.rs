#![no_main]
//! cargo-fuzz target `parser`: see `fbwag_fuzz::parser` (fuzz/src/lib.rs).
libfuzzer_sys::fuzz_target!(|data: &[u8]| fbwag_fuzz::parser(data));

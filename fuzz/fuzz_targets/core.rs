//! libFuzzer target: the core extraction (see `precisemc_fuzz::fuzz_core`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| precisemc_fuzz::fuzz_core(data));

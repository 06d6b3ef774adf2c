//! libFuzzer target: the C API (see `precisemc_fuzz::fuzz_c_api`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| precisemc_fuzz::fuzz_c_api(data));

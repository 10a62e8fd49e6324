//! libFuzzer entry for [`psr_fuzz::c_api`]: `scripts/fuzz.sh c_api SECONDS`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| psr_fuzz::c_api::run(data));

//! libFuzzer entry for [`psr_fuzz::reconstruct`]: `scripts/fuzz.sh reconstruct SECONDS`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| psr_fuzz::reconstruct::run(data));

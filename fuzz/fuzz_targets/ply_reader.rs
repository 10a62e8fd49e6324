//! libFuzzer entry for [`psr_fuzz::ply_reader`]: `scripts/fuzz.sh ply_reader SECONDS`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| psr_fuzz::ply_reader::run(data));

#![no_main]
// The parser behind `strands_ply`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("strands_ply", data);
});

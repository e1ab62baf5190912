#![no_main]
// The parser behind `strands_hair`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("strands_hair", data);
});

#![no_main]
// The parser behind `npy`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("npy", data);
});

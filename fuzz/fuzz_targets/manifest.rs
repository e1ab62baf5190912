#![no_main]
// The parser behind `manifest`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("manifest", data);
});

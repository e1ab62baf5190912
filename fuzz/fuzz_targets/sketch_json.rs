#![no_main]
// The parser behind `sketch_json`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("sketch_json", data);
});

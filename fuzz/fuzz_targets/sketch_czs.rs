#![no_main]
// The parser behind `sketch_czs`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("sketch_czs", data);
});

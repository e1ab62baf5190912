#![no_main]
// The parser behind `sketch_svg`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("sketch_svg", data);
});

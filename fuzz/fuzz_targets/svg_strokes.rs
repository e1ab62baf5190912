#![no_main]
// The parser behind `svg_strokes`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("svg_strokes", data);
});

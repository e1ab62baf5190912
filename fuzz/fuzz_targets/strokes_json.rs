#![no_main]
// The parser behind `strokes_json`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("strokes_json", data);
});

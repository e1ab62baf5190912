#![no_main]
// The parser behind `landmarks_json`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("landmarks_json", data);
});

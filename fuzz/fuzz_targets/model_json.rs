#![no_main]
// The parser behind `model_json`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("model_json", data);
});

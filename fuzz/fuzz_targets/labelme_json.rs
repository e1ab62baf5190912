#![no_main]
// The parser behind `labelme_json`: see coif::testing::fuzz.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    coif::testing::fuzz::run("labelme_json", data);
});

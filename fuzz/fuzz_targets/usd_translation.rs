//! Arbitrary bytes as a `.usda` layer through the client's translation, a commit and the
//! server's validation of the resulting sync stream: errors are fine, panics are bugs.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = tessera::fuzzing::usd_text(data);
});

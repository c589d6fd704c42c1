//! Arbitrary bytes through `tessera_server::fuzzing::render_settings_bytes`: errors are fine, panics and
//! allocation beyond the entry point's limits are bugs.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = tessera_server::fuzzing::render_settings_bytes(data);
});

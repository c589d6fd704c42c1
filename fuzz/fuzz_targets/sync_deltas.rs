//! Arbitrary bytes as a stream of length-delimited `SyncRequest` messages applied to a fresh
//! session and committed: errors are fine, panics and unbounded allocation are bugs.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = tessera_server::fuzzing::sync_bytes(data);
});

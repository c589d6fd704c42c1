//! Entry point for fuzzing the client's USD translation (the `fuzz/` cargo-fuzz target and the
//! stable smoke run in `tests/`): arbitrary bytes as a `.usda` layer are read, translated,
//! committed and sent through the sync protocol to a server session. Bad input must end in an
//! error, never a panic.

use std::sync::atomic::{AtomicU64, Ordering};

/// Reads `data` as a `.usda` file and takes it as far as it goes: translation, commit, and the
/// server's validation of the sync stream the client would send.
pub fn usd_text(data: &[u8]) -> Result<(), String> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!("tessera-fuzz-{}-{}.usda", std::process::id(), COUNTER.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&path, data).map_err(|e| e.to_string())?;
    let result = (|| {
        let t = crate::usd::load(&path).map_err(|e| format!("{e:#}"))?;
        render_core::scene::commit(&t.to_scene_desc(), &mut render_core::scene::BlasCache::default()).map_err(|e| e.to_string())?;
        tessera_server::fuzzing::sync_bytes(&tessera_server::fuzzing::encode_stream(&crate::sync::full_sync(&t)))?;
        Ok(())
    })();
    std::fs::remove_file(&path).ok();
    result
}

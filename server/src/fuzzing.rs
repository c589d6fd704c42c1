//! Entry points for fuzzing the server's scene validation (the `fuzz/` cargo-fuzz targets and
//! the stable smoke run in `tests/`): arbitrary bytes are read as a stream of length-delimited
//! `SyncRequest` messages, applied to a fresh session and committed. Bad input must end in an
//! error status, never a panic, and memory must stay proportional to the input (chunks are
//! only stored as they arrive).

use prost::Message;
use tessera_proto::v1 as pb;

use crate::limits::Limits;
use crate::session::Session;

/// Limits small enough that a fuzzer's commits stay fast, as a server may configure them.
pub fn fuzz_limits() -> Limits {
    Limits {
        max_triangles_per_mesh: 200_000,
        max_total_triangles: 1_000_000,
        max_instances: 100_000,
        max_texture_file_bytes: 1 << 20,
        max_texture_texels: 1 << 20,
        ..Limits::default()
    }
}

/// Most messages one input may hold.
const MAX_MESSAGES: usize = 4096;

/// Encodes sync items as the byte stream [`sync_bytes`] reads (seed corpora).
pub fn encode_stream(items: &[pb::sync_request::Item]) -> Vec<u8> {
    let mut out = Vec::new();
    for item in items {
        pb::SyncRequest { session_id: String::new(), item: Some(item.clone()) }.encode_length_delimited(&mut out).expect("a Vec grows");
    }
    out
}

/// Decodes `data` as sync messages, applies them in one transaction and commits. Returns the
/// scene version or the first error status's message.
pub fn sync_bytes(data: &[u8]) -> Result<u64, String> {
    let session = Session::new("fuzz".into());
    let mut tx = session.begin(fuzz_limits(), std::sync::Arc::new(crate::textures::TextureStore::new(1 << 20)));
    let mut buf = data;
    for _ in 0..MAX_MESSAGES {
        if buf.is_empty() {
            break;
        }
        let msg = pb::SyncRequest::decode_length_delimited(&mut buf).map_err(|e| format!("decode: {e}"))?;
        if let Some(item) = msg.item {
            tx.apply(item).map_err(|s| s.message().to_string())?;
        }
    }
    session.commit(tx).map(|(v, _)| v).map_err(|s| s.message().to_string())
}

/// Limits of the texture entry point: a fuzzer's inputs claim any size in their headers.
const FUZZ_TEXELS: u64 = 1 << 20;
const FUZZ_DECODE_BYTES: u64 = 64 << 20;

/// Decodes `data` as a texture file, as an upload is decoded: any format the decoders know,
/// refused by its header when it claims more than the limits. Errors are expected; a panic
/// or an allocation beyond the limits is a bug.
pub fn texture_bytes(data: &[u8]) -> Result<(u32, u32), String> {
    for name in ["upload.png", "upload.tga"] {
        if let Ok(image) = render_core::texture::Image::decode_within(data, name, FUZZ_TEXELS, FUZZ_DECODE_BYTES) {
            return Ok(image.size());
        }
    }
    render_core::texture::Image::decode_within(data, "upload", FUZZ_TEXELS, FUZZ_DECODE_BYTES).map(|i| i.size()).map_err(|e| e.to_string())
}

/// Decodes `data` as a `RenderSettings` message and validates it as a Render request would,
/// down to the film reservation's size. Returns the film's bytes or the refusal.
pub fn render_settings_bytes(data: &[u8]) -> Result<u64, String> {
    let settings = pb::RenderSettings::decode(data).map_err(|e| format!("decode: {e}"))?;
    let job = crate::render_job::RenderJob::new(&settings, &fuzz_limits()).map_err(|s| s.message().to_string())?;
    Ok(job.film_bytes())
}

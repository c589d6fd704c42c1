//! Decoded textures kept across sessions, keyed by the SHA-256 of the file's bytes, under a
//! byte limit with least-recently-used eviction. A session's scene holds its own references,
//! so eviction only forgets a texture for future syncs; it never pulls one from under a render.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use render_core::texture::Image;

pub use tessera_wire::content_hash;

/// True when `key` has the shape of a [`content_hash`].
pub fn is_content_hash(key: &str) -> bool {
    key.strip_prefix("sha256:").is_some_and(|h| h.len() == 64 && h.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)))
}

struct Entry {
    image: Arc<Image>,
    last_use: u64,
}

#[derive(Default)]
struct Inner {
    entries: HashMap<String, Entry>,
    bytes: usize,
    clock: u64,
}

/// The server-wide texture cache.
pub struct TextureStore {
    inner: Mutex<Inner>,
    limit: usize,
}

impl TextureStore {
    /// An empty store holding at most `limit` decoded bytes.
    pub fn new(limit: usize) -> Self {
        TextureStore { inner: Mutex::default(), limit }
    }

    /// The texture with this content hash, if held (it becomes the most recently used).
    pub fn get(&self, hash: &str) -> Option<Arc<Image>> {
        let mut inner = self.inner.lock().unwrap();
        inner.clock += 1;
        let now = inner.clock;
        inner.entries.get_mut(hash).map(|e| {
            e.last_use = now;
            Arc::clone(&e.image)
        })
    }

    /// Those of `hashes` the store does not hold.
    pub fn missing(&self, hashes: &[String]) -> Vec<String> {
        let inner = self.inner.lock().unwrap();
        hashes.iter().filter(|h| !inner.entries.contains_key(*h)).cloned().collect()
    }

    /// Adds a texture, then evicts the least recently used others until the store is under
    /// its limit (a texture larger than the limit alone stays until the next insert).
    pub fn insert(&self, hash: &str, image: Arc<Image>) {
        let mut inner = self.inner.lock().unwrap();
        inner.clock += 1;
        let now = inner.clock;
        let bytes = image.bytes();
        if let Some(old) = inner.entries.insert(hash.to_string(), Entry { image, last_use: now }) {
            inner.bytes -= old.image.bytes();
        }
        inner.bytes += bytes;
        while inner.bytes > self.limit {
            let Some(oldest) = inner.entries.iter().filter(|(k, _)| *k != hash).min_by_key(|(_, e)| e.last_use).map(|(k, _)| k.clone())
            else {
                break;
            };
            let e = inner.entries.remove(&oldest).expect("present");
            inner.bytes -= e.image.bytes();
            tracing::debug!(hash = oldest, bytes = e.image.bytes(), "texture evicted");
        }
    }

    /// Decoded bytes held.
    pub fn bytes(&self) -> usize {
        self.inner.lock().unwrap().bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(side: u32) -> Arc<Image> {
        Arc::new(Image::from_u8(side, side, 1, vec![0; (side * side) as usize]))
    }

    #[test]
    fn hashes_are_sha256_hex() {
        // FIPS 180-2's test vector for "abc".
        assert_eq!(content_hash(b"abc"), "sha256:ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
        assert!(is_content_hash(&content_hash(b"")));
        assert!(!is_content_hash("sha256:XYZ") && !is_content_hash("/World/tex.png"));
    }

    #[test]
    fn the_least_recently_used_texture_goes_first() {
        let store = TextureStore::new(250);
        store.insert("a", image(10));
        store.insert("b", image(10));
        assert!(store.get("a").is_some(), "a is now more recent than b");
        store.insert("c", image(10));
        assert_eq!(store.missing(&["a".into(), "b".into(), "c".into()]), vec!["b".to_string()]);
        assert_eq!(store.bytes(), 200);
        // One texture above the limit displaces everything else but stays itself.
        store.insert("big", image(20));
        assert_eq!(store.missing(&["a".into(), "c".into(), "big".into()]).len(), 2);
        assert!(store.get("big").is_some());
    }
}

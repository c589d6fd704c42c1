//! Tessera's scene and tiles on the wire: the one place that turns render-core's scene
//! description into protobuf messages and back, so the client that encodes and the server
//! that decodes cannot disagree.

#![deny(missing_docs)]

pub mod convert;

pub use tessera_proto::v1 as pb;

use sha2::{Digest, Sha256};

/// The key of a texture file on the wire: `sha256:` and the hex digest of its bytes.
pub fn content_hash(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    let mut s = String::with_capacity(7 + 64);
    s.push_str("sha256:");
    for b in digest {
        s.push_str(&format!("{b:02x}"));
    }
    s
}

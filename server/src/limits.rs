//! Every size a client controls has a limit, reported by `GetCapabilities` and enforced
//! with a clear status.

/// Server limits.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Triangles in one mesh.
    pub max_triangles_per_mesh: u64,
    /// Triangles in one scene.
    pub max_total_triangles: u64,
    /// Image width or height.
    pub max_resolution: u32,
    /// Samples per pixel.
    pub max_spp: u32,
    /// Concurrent sessions, all tenants together.
    pub max_sessions: u32,
    /// Concurrent sessions of one tenant.
    pub max_sessions_per_tenant: u32,
    /// Scalar elements in one array chunk.
    pub max_array_chunk_elements: u64,
    /// Instances in one instancer.
    pub max_instances: u64,
    /// Decoded texture bytes kept for reuse across sessions.
    pub texture_cache_bytes: u64,
    /// Encoded bytes of one texture file.
    pub max_texture_file_bytes: u64,
    /// Texels of one decoded texture (checked from its header, before decoding).
    pub max_texture_texels: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_triangles_per_mesh: 50_000_000,
            max_total_triangles: 200_000_000,
            max_resolution: 16_384,
            max_spp: 1 << 20,
            max_sessions: 64,
            max_sessions_per_tenant: 64,
            // 1 Mi floats = 4 MiB would hit gRPC's default limit; stay well under it.
            max_array_chunk_elements: 256 * 1024,
            max_instances: 10_000_000,
            texture_cache_bytes: 4 << 30,
            max_texture_file_bytes: 2 << 30,
            max_texture_texels: 16384 * 16384,
        }
    }
}

/// Longest prim path a client may send, in bytes (USD sets no limit; real paths are far
/// shorter, and every lookup and log line carries them).
pub const MAX_PRIM_PATH_BYTES: usize = 4096;

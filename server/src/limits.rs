//! Every size a client controls has a limit, reported by `GetCapabilities` and enforced
//! with a clear status.

use tessera_proto::v1 as pb;

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

impl Limits {
    /// As a wire message, with the configuration's budgets and timeouts.
    pub fn to_wire(&self, config: &crate::config::ServerConfig) -> pb::Limits {
        use render_core::material::network;
        pb::Limits {
            max_instances: self.max_instances,
            max_sessions_per_tenant: self.max_sessions_per_tenant,
            memory_budget: config.memory_budget,
            session_memory_budget: config.session_memory_budget,
            max_material_nodes: network::MAX_NODES as u32,
            max_material_connections: network::MAX_CONNECTIONS as u32,
            max_material_depth: network::MAX_CHAIN_DEPTH as u32,
            max_prim_path_bytes: crate::session::MAX_PRIM_PATH_BYTES as u32,
            session_idle_timeout_seconds: config.session_idle_timeout.as_secs_f64(),
            stall_timeout_seconds: config.stall_timeout.as_secs_f64(),
            max_triangles_per_mesh: self.max_triangles_per_mesh,
            max_total_triangles: self.max_total_triangles,
            max_resolution: self.max_resolution,
            max_spp: self.max_spp,
            max_sessions: self.max_sessions,
            max_array_chunk_elements: self.max_array_chunk_elements,
            texture_cache_bytes: self.texture_cache_bytes,
            max_texture_file_bytes: self.max_texture_file_bytes,
            max_texture_texels: self.max_texture_texels,
        }
    }
}

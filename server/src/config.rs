//! What an operator sets: limits, memory budgets, authentication, timeouts.

use std::time::Duration;

use crate::auth::Auth;
use crate::limits::Limits;
use tessera_proto::v1 as pb;

/// The server's configuration.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// Sizes and counts a client controls.
    pub limits: Limits,
    /// Bytes all sessions together may hold (scenes, films, decoded textures).
    pub memory_budget: u64,
    /// Bytes one session may hold; at most [`Self::memory_budget`].
    pub session_memory_budget: u64,
    /// Tokens and their tenants.
    pub auth: Auth,
    /// A session with no call and no open stream for this long is closed.
    pub session_idle_timeout: Duration,
    /// A Render stream whose client reads nothing for this long is dropped.
    pub stall_timeout: Duration,
    /// How long running renders get to finish after a shutdown signal.
    pub shutdown_grace: Duration,
}

impl Default for ServerConfig {
    fn default() -> Self {
        let budget = crate::budget::default_server_budget();
        ServerConfig {
            limits: Limits::default(),
            memory_budget: budget,
            session_memory_budget: budget,
            auth: Auth::open(),
            session_idle_timeout: Duration::from_secs(600),
            stall_timeout: Duration::from_secs(30),
            shutdown_grace: Duration::from_secs(10),
        }
    }
}

impl ServerConfig {
    /// The limits as a wire message, with the configuration's budgets and timeouts.
    pub fn limits_to_wire(&self) -> pb::Limits {
        let (config, limits) = (self, &self.limits);
        use render_core::material::network;
        pb::Limits {
            max_instances: limits.max_instances,
            max_sessions_per_tenant: limits.max_sessions_per_tenant,
            memory_budget: config.memory_budget,
            session_memory_budget: config.session_memory_budget,
            max_material_nodes: network::MAX_NODES as u32,
            max_material_connections: network::MAX_CONNECTIONS as u32,
            max_material_depth: network::MAX_CHAIN_DEPTH as u32,
            max_prim_path_bytes: crate::limits::MAX_PRIM_PATH_BYTES as u32,
            session_idle_timeout_seconds: config.session_idle_timeout.as_secs_f64(),
            stall_timeout_seconds: config.stall_timeout.as_secs_f64(),
            max_triangles_per_mesh: limits.max_triangles_per_mesh,
            max_total_triangles: limits.max_total_triangles,
            max_resolution: limits.max_resolution,
            max_spp: limits.max_spp,
            max_sessions: limits.max_sessions,
            max_array_chunk_elements: limits.max_array_chunk_elements,
            texture_cache_bytes: limits.texture_cache_bytes,
            max_texture_file_bytes: limits.max_texture_file_bytes,
            max_texture_texels: limits.max_texture_texels,
        }
    }
}

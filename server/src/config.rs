//! What an operator sets: limits, memory budgets, authentication, timeouts.

use std::time::Duration;

use crate::auth::Auth;
use crate::limits::Limits;

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

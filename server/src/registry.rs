//! The open sessions, by id and owner: creation under the total and per-tenant limits,
//! look-up that hides other tenants' sessions, closing, and reaping the idle.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tonic::Status;

use crate::auth::Tenant;
use crate::budget::Budget;
use crate::session::{Session, random_id};

/// Every open session.
#[derive(Default)]
pub struct Registry {
    sessions: Mutex<HashMap<String, Arc<Session>>>,
}

impl Registry {
    /// Opens a session for `tenant` under the limits, with its own memory budget beside the
    /// server's.
    #[allow(clippy::result_large_err)]
    pub fn create(
        &self,
        tenant: Tenant,
        max_total: u32,
        max_per_tenant: u32,
        session_budget: u64,
        server: &Arc<Budget>,
    ) -> Result<Arc<Session>, Status> {
        let mut sessions = self.sessions.lock().unwrap();
        if sessions.len() >= max_total as usize {
            return Err(Status::resource_exhausted(format!("{} sessions are open, the server's limit", sessions.len())));
        }
        let own = sessions.values().filter(|s| s.tenant == tenant).count();
        if own >= max_per_tenant as usize {
            return Err(Status::resource_exhausted(format!(
                "tenant '{}' has {own} sessions open, the limit per tenant; close one (or let it idle out)",
                tenant.0
            )));
        }
        let id = random_id();
        let budget = Budget::new(format!("session '{id}'"), session_budget);
        let session = Arc::new(Session::owned(id.clone(), tenant, vec![budget, Arc::clone(server)]));
        sessions.insert(id, Arc::clone(&session));
        Ok(session)
    }

    /// The session `id` if `tenant` owns it. Another tenant's session reads as absent, with
    /// the same message, so ids cannot be probed.
    #[allow(clippy::result_large_err)]
    pub fn get(&self, id: &str, tenant: &Tenant) -> Result<Arc<Session>, Status> {
        let sessions = self.sessions.lock().unwrap();
        match sessions.get(id) {
            Some(s) if s.tenant == *tenant => {
                s.touch();
                Ok(Arc::clone(s))
            }
            _ => Err(not_found(id)),
        }
    }

    /// Removes the session `id` of `tenant`, stopping its render and freeing its scene.
    #[allow(clippy::result_large_err)]
    pub fn close(&self, id: &str, tenant: &Tenant) -> Result<(), Status> {
        let session = {
            let mut sessions = self.sessions.lock().unwrap();
            match sessions.get(id) {
                Some(s) if s.tenant == *tenant => sessions.remove(id).expect("present"),
                _ => return Err(not_found(id)),
            }
        };
        shut(&session);
        Ok(())
    }

    /// Closes every session idle for longer than `timeout`; returns their ids.
    pub fn reap_idle(&self, timeout: Duration) -> Vec<String> {
        let idle: Vec<Arc<Session>> = {
            let mut sessions = self.sessions.lock().unwrap();
            let ids: Vec<String> = sessions.iter().filter(|(_, s)| s.idle_for() > timeout).map(|(id, _)| id.clone()).collect();
            ids.iter().filter_map(|id| sessions.remove(id)).collect()
        };
        for s in &idle {
            tracing::info!(session = %s.id, tenant = %s.tenant.0, "idle session closed");
            shut(s);
        }
        idle.iter().map(|s| s.id.clone()).collect()
    }

    /// Flags every running render to stop; returns how many there were.
    pub fn cancel_all(&self) -> usize {
        self.sessions.lock().unwrap().values().filter(|s| s.cancel_render()).count()
    }

    /// Sessions open now.
    pub fn len(&self) -> usize {
        self.sessions.lock().unwrap().len()
    }

    /// True when no session is open.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

fn not_found(id: &str) -> Status {
    let shown: String = id.chars().take(80).collect();
    Status::not_found(format!("session '{}' does not exist (closed, idle too long, or never created)", shown.escape_debug()))
}

/// Stops a removed session's render and frees its scene now, not when the last render thread
/// lets go of it.
fn shut(session: &Session) {
    session.cancel_render();
    session.clear();
}

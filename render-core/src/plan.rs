//! The render plan: which effects a scene calls for, and which prims call for them.

/// One simulated effect.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanEntry {
    /// Short effect name, e.g. `direct-lighting`.
    pub effect: String,
    /// Why it is on (or what it costs).
    pub reason: String,
    /// Prims that call for it (possibly truncated, with a count).
    pub prims: Vec<String>,
}

/// What the renderer will simulate for a committed scene.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderPlan {
    /// Enabled effects.
    pub entries: Vec<PlanEntry>,
    /// Effects the renderer supports but this scene does not need, and so skips.
    pub skipped: Vec<String>,
}

impl RenderPlan {
    /// Adds an effect, listing at most a handful of prims.
    pub fn enable(&mut self, effect: &str, reason: impl Into<String>, prims: impl IntoIterator<Item = String>) {
        const SHOWN: usize = 8;
        let all: Vec<String> = prims.into_iter().collect();
        let mut shown: Vec<String> = all.iter().take(SHOWN).cloned().collect();
        if all.len() > SHOWN {
            shown.push(format!("... and {} more", all.len() - SHOWN));
        }
        self.entries.push(PlanEntry { effect: effect.into(), reason: reason.into(), prims: shown });
    }

    /// True when `effect` is enabled.
    pub fn has(&self, effect: &str) -> bool {
        self.entries.iter().any(|e| e.effect == effect)
    }
}

impl std::fmt::Display for RenderPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for e in &self.entries {
            writeln!(f, "  + {:<18} {}", e.effect, e.reason)?;
            if !e.prims.is_empty() {
                writeln!(f, "  {:<20} {}", "", e.prims.join(", "))?;
            }
        }
        for s in &self.skipped {
            writeln!(f, "  - {s}")?;
        }
        Ok(())
    }
}

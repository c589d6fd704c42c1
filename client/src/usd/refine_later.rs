//! Subdivision surfaces refined after the traversal, several at once.
//!
//! OpenSubdiv's limit stencils are most of the time a subdivided scene takes to read (80% of
//! `materials/principled_grid.usda`'s), and the stage can only be read on one thread (see the
//! module above). So a mesh whose refined faces nothing else needs during the traversal (no
//! GeomSubsets, no deformation samples) enters the scene with an empty mesh and is refined,
//! with the others like it, once every prim has been visited: a big mesh alone on every pool
//! thread, small ones side by side. Each comes out as it would have inline: the same mesh in
//! the same place, its warnings and its entry in the render plan where they would have been.

use std::sync::Arc;

use anyhow::Result;
use openusd::usd::Prim;
use rayon::prelude::*;
use render_core::geometry::Mesh;

use super::geometry::{CageRead, refine_cage};
use super::mesh::{MeshSource, check_faces, triangulate_with_faces};
use super::subdivision::{self, SubdivTags};
use super::{Reader, Subdivided};

/// A mesh whose refinement waits for the end of the traversal.
pub(super) struct LaterRefinement {
    /// Its index in the translation's meshes.
    mesh: usize,
    path: String,
    src: MeshSource,
    tags: SubdivTags,
    level: u32,
    /// Where its warnings and its entry in `subdivided` go.
    warnings_at: usize,
    subdivided_at: usize,
}

/// What one refinement made.
struct RefinedMesh {
    mesh: Mesh,
    warnings: Vec<String>,
    subdivided: Option<Subdivided>,
}

impl Reader<'_> {
    /// The level to refine `cage` at after the traversal, or None when it must be refined now
    /// (or not at all): it does not subdivide, deforms over the shutter, or has faces that
    /// cannot be triangulated (that error skips the prim, which only the traversal can do).
    pub(super) fn refinement_to_defer(&self, prim: &Prim, p: &str, cage: &CageRead) -> Result<Option<u32>> {
        if !cage.tags.is_subdivided() || cage.deforms() || check_faces(&cage.src).is_err() {
            return Ok(None);
        }
        let level = self.refinement_level(prim, p)?;
        Ok((level > 0).then_some(level))
    }

    /// Adds the mesh prim with an empty mesh, refined at `level` by [`Reader::refine_deferred`].
    pub(super) fn add_mesh_refined_later(&mut self, prim: &Prim, p: &str, cage: CageRead, level: u32, visible: bool) -> Result<()> {
        let mesh = self.out.meshes.len();
        self.add_mesh(prim, p, Mesh::default(), visible)?;
        let subdivided_at = self.out.subdivided.len();
        let job = LaterRefinement {
            mesh,
            path: p.to_string(),
            src: cage.src,
            tags: cage.tags,
            level,
            warnings_at: cage.warnings_at,
            subdivided_at,
        };
        self.later.push(job);
        Ok(())
    }

    /// Refines every deferred mesh, on the thread pool, and puts each result where the
    /// traversal left its place.
    pub(super) fn refine_deferred(&mut self) {
        let jobs = std::mem::take(&mut self.later);
        if jobs.is_empty() {
            return;
        }
        let _span = tracing::info_span!("refine_deferred", meshes = jobs.len()).entered();
        let places: Vec<(usize, usize, usize)> = jobs.iter().map(|j| (j.mesh, j.warnings_at, j.subdivided_at)).collect();
        // Big meshes one after another, each on every thread (a refiner per thread), then the
        // small ones side by side, one thread (and one refiner) each.
        let (big, small): (Vec<_>, Vec<_>) =
            jobs.into_iter().enumerate().partition(|(_, j)| subdivision::spreads_over_threads(&j.src, j.level));
        let mut done: Vec<(usize, RefinedMesh)> = big.into_iter().map(|(k, j)| (k, refine(j))).collect();
        done.par_extend(small.into_par_iter().map(|(k, j)| (k, refine(j))));
        done.sort_unstable_by_key(|(k, _)| *k);
        let refined = done.into_iter().map(|(_, r)| r);
        let (mut warnings, mut subdivided) = (Vec::new(), Vec::new());
        for ((mesh, warnings_at, subdivided_at), r) in places.into_iter().zip(refined) {
            self.out.meshes[mesh].1.mesh = Arc::new(r.mesh);
            warnings.extend(r.warnings.into_iter().map(|w| (warnings_at, w)));
            subdivided.extend(r.subdivided.map(|s| (subdivided_at, s)));
        }
        insert_all(&mut self.out.warnings, warnings);
        insert_all(&mut self.out.subdivided, subdivided);
    }

    /// Forgets the deferred meshes from index `kept` on (their prim was skipped).
    pub(super) fn forget_deferred_from(&mut self, kept: usize) {
        self.later.retain(|j| j.mesh < kept);
    }
}

/// One deferred mesh refined and triangulated as the traversal would have done it.
fn refine(job: LaterRefinement) -> RefinedMesh {
    let LaterRefinement { path: p, src, tags, level, .. } = job;
    let mut warnings = Vec::new();
    let (mut src, refined) = refine_cage(&p, src, &tags, level, &mut warnings);
    if refined.is_some() {
        subdivision::share_normals(&mut src);
    }
    let subdivided = refined.map(|(entry, _)| entry);
    let mesh = match triangulate_with_faces(&src, |w| warnings.push(format!("{p}: {w}"))) {
        Ok((mesh, _)) => mesh,
        // Not reached: the cage's faces were checked, and refined faces are whole by construction.
        Err(e) => {
            warnings.push(format!("{p}: {e}; the mesh is left empty"));
            Mesh::default()
        }
    };
    RefinedMesh { mesh, warnings, subdivided }
}

/// Puts each of `inserts` into `v` before the element that was at its position (or at the
/// end), in one pass: positions do not decrease, and items at one position keep their order.
/// One `Vec::insert` per item would move the tail each time, quadratic in a stage of many
/// meshes with warnings.
fn insert_all<T>(v: &mut Vec<T>, inserts: Vec<(usize, T)>) {
    if inserts.is_empty() {
        return;
    }
    let mut old = std::mem::take(v).into_iter().enumerate().peekable();
    v.reserve(old.len() + inserts.len());
    for (at, item) in inserts {
        while let Some((_, x)) = old.next_if(|(i, _)| *i < at) {
            v.push(x);
        }
        v.push(item);
    }
    v.extend(old.map(|(_, x)| x));
}

#[cfg(test)]
mod tests {
    use super::insert_all;

    #[test]
    fn inserted_items_land_before_the_element_at_their_position() {
        let mut v = vec!["a", "b", "c"];
        insert_all(&mut v, vec![(0, "0"), (2, "2x"), (2, "2y"), (3, "end")]);
        assert_eq!(v, ["0", "a", "b", "2x", "2y", "c", "end"]);
        let mut empty: Vec<&str> = Vec::new();
        insert_all(&mut empty, vec![(0, "x"), (0, "y")]);
        assert_eq!(empty, ["x", "y"]);
    }
}

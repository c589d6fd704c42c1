//! `UsdGeomPoints` as spheres whose diameters are the points' `widths`: one tessellated unit
//! sphere per Points prim, drawn through the instancing path (a transform per point, no
//! triangles per point): a million points render in under 1 GiB (tests/tests/points_memory.rs),
//! where a mesh of a million spheres would be billions of triangles.

use anyhow::{Context, Result};
use glam::{Affine3A, DMat4, DVec3, Vec3};
use render_core::scene::InstancerDesc;

use super::*;

/// Most points one prim may have (a transform each: 64 bytes, ~1 GB at the limit).
pub const MAX_POINTS: usize = 16 << 20;

/// The object-to-world transform of a sphere of diameter `width` at `point`, for each point.
pub fn sphere_instances(world: DMat4, points: &[Vec3], widths: &[f32]) -> Vec<Affine3A> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let radius = 0.5 * widths.get(i).or(widths.first()).copied().unwrap_or(1.0) as f64;
            let m = world * DMat4::from_translation(p.as_dvec3()) * DMat4::from_scale(DVec3::splat(radius));
            Affine3A::from_mat4(m.as_mat4())
        })
        .collect()
}

impl Reader<'_> {
    pub(super) fn points(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let time = self.time;
        let points = match get(prim, "points", time)? {
            Some(v) => values::vec3_array(&v)
                .with_context(|| format!("{p}: attribute 'points' has type {}, expected point3f[]", values::type_of(&v)))?,
            None => anyhow::bail!("{p}: attribute 'points' is missing"),
        };
        if points.len() > MAX_POINTS {
            anyhow::bail!("{p}: attribute 'points' has {} points, more than the {MAX_POINTS} one prim may have", points.len());
        }
        if let Some((i, v)) = points.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            anyhow::bail!("{p}: attribute 'points': point {i} is {v} (NaN or Inf)");
        }
        let widths = self.widths(prim, p, points.len())?;
        // The sphere itself, never drawn directly: the instancer places it at every point.
        let proto = format!("{p}[sphere]");
        let material = self.usable_material(prim)?;
        let sphere = shapes::tessellate(shapes::Shape::Sphere { radius: 1.0 });
        self.add_mesh_with(prim, &proto, sphere, false, material)?;
        let transforms = if visible { sphere_instances(self.world_transform(prim.path())?, &points, &widths) } else { Vec::new() };
        self.out.instancers.push((format!("{p}[points]"), InstancerDesc { prototype: proto, transforms }));
        Ok(())
    }

    /// `widths`: one per point, or one for all; unauthored, 1 (Hydra's default). A count that
    /// fits neither is a warning and the default; a negative or non-finite width an error.
    fn widths(&mut self, prim: &Prim, p: &str, n: usize) -> Result<Vec<f32>> {
        let Some(widths) = get_floats(prim, p, "widths", self.time)? else { return Ok(vec![1.0]) };
        if let Some((i, w)) = widths.iter().enumerate().find(|(_, w)| !(w.is_finite() && **w >= 0.0)) {
            anyhow::bail!("{p}: attribute 'widths': width {i} is {w}; widths are finite and not negative");
        }
        if widths.len() != n && widths.len() != 1 {
            self.out.warnings.push(format!("{p}: attribute 'widths' has {} values for {n} points; width 1 is used", widths.len()));
            return Ok(vec![1.0]);
        }
        Ok(widths)
    }
}

//! `UsdGeomPoints` as spheres whose diameters are the points' `widths`, or, when the prim
//! authors `normals`, as discs facing them (as Hydra's Storm draws them): one tessellated unit
//! sphere or disc per Points prim, drawn through the instancing path (a transform per point, no
//! triangles per point): a million points render in under 1 GiB (tests/tests/memory.rs),
//! where a mesh of a million spheres would be billions of triangles.

use anyhow::{Context, Result};
use glam::{Affine3A, DMat4, DQuat, DVec3, Vec3};
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

/// The object-to-world transform of a disc of diameter `width` at `point` facing `normal`
/// (one normal per point, or one for all), for each point. Normals are unit length or are
/// normalised here; [`Reader::disc_normals`] has refused zero and non-finite ones.
pub fn disc_instances(world: DMat4, points: &[Vec3], widths: &[f32], normals: &[Vec3]) -> Vec<Affine3A> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let radius = 0.5 * widths.get(i).or(widths.first()).copied().unwrap_or(1.0) as f64;
            let n = normals.get(i).or(normals.first()).copied().unwrap_or(Vec3::Z).as_dvec3().normalize();
            let facing = DQuat::from_rotation_arc(DVec3::Z, n);
            let m = world * DMat4::from_scale_rotation_translation(DVec3::splat(radius), facing, p.as_dvec3());
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
        let normals = self.disc_normals(prim, p, points.len())?;
        // The sphere or disc itself, never drawn directly: the instancer places it at every point.
        let (proto, shape) = match normals {
            Some(_) => (format!("{p}[disc]"), shapes::Shape::Disc { radius: 1.0 }),
            None => (format!("{p}[sphere]"), shapes::Shape::Sphere { radius: 1.0 }),
        };
        let material = self.usable_material(prim)?;
        self.add_mesh_with(prim, &proto, shapes::tessellate(shape), false, material)?;
        let world = self.world_transform(prim.path())?;
        let transforms = match (&normals, visible) {
            (_, false) => Vec::new(),
            (Some(n), true) => disc_instances(world, &points, &widths, n),
            (None, true) => sphere_instances(world, &points, &widths),
        };
        let link_collections = self.link_collections(prim.path());
        self.out
            .instancers
            .push((format!("{p}[points]"), InstancerDesc { prototype: proto, transforms, motion: Vec::new(), link_collections }));
        Ok(())
    }

    /// The `normals` discs face, one per point or one for all; `None` (spheres) when none are
    /// authored, or, with a warning, when their count fits neither. A zero or non-finite normal
    /// faces nowhere: an error naming it.
    fn disc_normals(&mut self, prim: &Prim, p: &str, n: usize) -> Result<Option<Vec<Vec3>>> {
        let Some((normals, _)) = self.normals(prim, p)? else { return Ok(None) };
        if normals.len() != n && normals.len() != 1 {
            self.out
                .warnings
                .push(format!("{p}: attribute 'normals' has {} values for {n} points; the points render as spheres", normals.len()));
            return Ok(None);
        }
        if let Some((i, v)) = normals.iter().enumerate().find(|(_, v)| !(v.is_finite() && v.length_squared() > 0.0)) {
            anyhow::bail!("{p}: attribute 'normals': normal {i} is {v}, which orients no disc");
        }
        Ok(Some(normals))
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

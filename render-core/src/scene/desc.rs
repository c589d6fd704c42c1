//! The scene description a session edits, keyed by USD path, and its validation.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::Affine3A;

use crate::camera::CameraDesc;
use crate::geometry::Mesh;
use crate::light::LightDesc;
use crate::material::MaterialNetwork;

/// A mesh prim.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDesc {
    /// Geometry, shared so unchanged meshes keep their BLAS across commits.
    pub mesh: Arc<Mesh>,
    /// Object to world.
    pub transform: Affine3A,
    /// Object to world at evenly spaced times from shutter open to close when the mesh moves
    /// ([`crate::motion`]); empty when it does not.
    pub motion: Vec<Affine3A>,
    /// Bound material path; empty for none.
    pub material: String,
    /// Rendered at all (false for invisible meshes and instancer prototypes).
    pub visible: bool,
    /// The light-link collections the prim belongs to ([`super::LightLinks`]).
    pub link_collections: Vec<String>,
    /// UsdLux `MeshLightAPI` (or `LightAPI`) on the mesh: it is a light as well.
    pub light: Option<crate::light::MeshLight>,
}

/// A point instancer: world transforms of instances of one prototype mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct InstancerDesc {
    /// Path of the prototype mesh in [`SceneDesc::meshes`].
    pub prototype: String,
    /// Object-to-world transform of each instance.
    pub transforms: Vec<Affine3A>,
    /// When the instances move: each instance's placements at the same number of evenly
    /// spaced times over the shutter ([`crate::motion`]), instance after instance; empty
    /// when they do not.
    pub motion: Vec<Affine3A>,
    /// The light-link collections its instances belong to, besides their prototype's
    /// ([`super::LightLinks`]).
    pub link_collections: Vec<String>,
}

impl InstancerDesc {
    /// Placements over the shutter per instance (0 when the instances do not move).
    pub fn motion_samples(&self) -> usize {
        if self.transforms.is_empty() { 0 } else { self.motion.len() / self.transforms.len() }
    }
}

/// Everything a session has synced, keyed by USD path.
#[derive(Clone, Debug, Default)]
pub struct SceneDesc {
    /// Meshes.
    pub meshes: BTreeMap<String, MeshDesc>,
    /// Instancers.
    pub instancers: BTreeMap<String, InstancerDesc>,
    /// Material networks.
    pub materials: BTreeMap<String, MaterialNetwork>,
    /// Lights.
    pub lights: BTreeMap<String, LightDesc>,
    /// Cameras.
    pub cameras: BTreeMap<String, CameraDesc>,
    /// Decoded texture files by content hash, as materials name them.
    pub textures: BTreeMap<String, Arc<crate::texture::Image>>,
    /// Volumes.
    pub volumes: BTreeMap<String, crate::volume::VolumeDesc>,
}

/// A scene that cannot be committed, naming the prim and field at fault.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SceneError {
    /// Invalid data on a prim.
    #[error("{prim}: {field}: {problem}")]
    Invalid {
        /// Prim path.
        prim: String,
        /// Attribute or field.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A reference to a prim that does not exist.
    #[error("{prim}: {field} refers to {target}, which is not in the scene")]
    Dangling {
        /// Prim path.
        prim: String,
        /// Field holding the reference.
        field: String,
        /// Missing path.
        target: String,
    },
}

/// Largest coordinate a point may have, in object or world space. Squared distances and
/// cross products of coordinates beyond ~1e19 overflow f32 (the BVH builder indexed out of
/// bounds on a point at 1e38); 1e15 scene units is already 6 700 astronomical units in metres.
pub const MAX_COORDINATE: f32 = 1e15;

/// Checks a mesh for what would break the renderer: non-finite or overflowing positions,
/// indices out of range, normal arrays of the wrong length. Bad normals are not an error; they
/// are repaired at shading time (the geometric normal is used).
pub fn validate_mesh(path: &str, mesh: &Mesh) -> Result<(), SceneError> {
    let invalid = |field: &str, problem: String| SceneError::Invalid { prim: path.to_string(), field: field.to_string(), problem };
    if let Some((i, p)) = mesh.positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return Err(invalid("points", format!("point {i} is {p} (NaN or Inf)")));
    }
    if let Some((i, p)) = mesh.positions.iter().enumerate().find(|(_, p)| p.abs().max_element() > MAX_COORDINATE) {
        return Err(invalid("points", format!("point {i} is {p}, beyond ±{MAX_COORDINATE:e}: single-precision geometry overflows there")));
    }
    check_deformation(mesh).map_err(|e| invalid("deformation", e))?;
    let n = mesh.positions.len() as u64;
    for (t, tri) in mesh.indices.iter().enumerate() {
        for (k, &v) in tri.iter().enumerate() {
            if v as u64 >= n {
                return Err(invalid("faceVertexIndices", format!("triangle {t} corner {k} has index {v}, out of range for {n} points")));
            }
        }
    }
    // Per-corner data must match the layout it claims, or shading would index past its end.
    fn check<T>(a: &crate::geometry::Attribute<T>, mesh: &Mesh) -> Result<(), String> {
        use crate::geometry::Attribute;
        let (got, want, interp) = match a {
            Attribute::None => return Ok(()),
            Attribute::Vertex(v) => (v.len(), mesh.positions.len(), "vertex"),
            Attribute::FaceVarying(v) => (v.len(), 3 * mesh.indices.len(), "faceVarying"),
        };
        if got == want { Ok(()) } else { Err(format!("{got} {interp} values for {want} expected")) }
    }
    check(&mesh.normals, mesh).map_err(|e| invalid("normals", e))?;
    check(&mesh.uvs, mesh).map_err(|e| invalid("uvs", e))?;
    for p in &mesh.primvars {
        check(&p.values, mesh).map_err(|e| invalid(&format!("primvars:{}", p.name), e))?;
    }
    Ok(())
}

/// Deformation samples are whole sets of the mesh's positions, 2 to
/// [`crate::motion::MAX_MOTION_SAMPLES`] of them, finite and in range.
fn check_deformation(mesh: &Mesh) -> Result<(), String> {
    if mesh.deformation.is_empty() {
        return Ok(());
    }
    let (len, n) = (mesh.deformation.len(), mesh.positions.len());
    if n == 0 || len % n != 0 || !(2..=crate::motion::MAX_MOTION_SAMPLES).contains(&(len / n)) {
        return Err(format!("{len} positions are not 2 to {} sets of the mesh's {n} points", crate::motion::MAX_MOTION_SAMPLES));
    }
    match mesh.deformation.iter().enumerate().find(|(_, p)| !p.is_finite() || p.abs().max_element() > MAX_COORDINATE) {
        Some((i, p)) => Err(format!("position {} of sample {} is {p}, not finite or beyond ±{MAX_COORDINATE:e}", i % n, i / n)),
        None => Ok(()),
    }
}

//! What commits keep for the next: BLASes, mip pyramids, dome maps' distributions, tangents and
//! displaced meshes, by geometry identity.

use std::collections::HashMap;
use std::sync::Arc;

use crate::bvh::Blas;
use crate::geometry::Mesh;

/// BLASes kept between commits, keyed by mesh path and geometry identity.
#[derive(Default)]
pub struct BlasCache {
    pub(super) entries: HashMap<String, (Arc<Mesh>, Arc<Blas>)>,
    /// Mip pyramids by (content hash, colour space), kept while a material reads them.
    pub(super) textures: HashMap<(String, crate::texture::ColorSpace), Arc<crate::texture::Texture>>,
    /// Dome maps' sampling distributions by their texture's (content hash, colour space), kept
    /// while a dome reads them.
    pub(super) domes: HashMap<(String, crate::texture::ColorSpace), Arc<crate::light::environment::DomeMap>>,
    /// BLAS builds done by the last commit (for tests and logs).
    pub last_builds: usize,
    /// MikkTSpace tangents of normal-mapped meshes, by mesh geometry.
    pub(super) tangents: Vec<(Arc<Mesh>, Arc<crate::geometry::Attribute<glam::Vec4>>)>,
    /// Displaced meshes by mesh path, with the geometry and material they came from.
    pub(super) displaced: HashMap<String, super::displace::Displaced>,
}

//! One session: the scene a client has synced, its committed form and version, and the
//! render running on it. A `Sync` stream is a transaction: deltas are staged against a copy
//! of the description and committed together, or not at all.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use render_core::geometry::{Mesh, Primvar};
use render_core::scene::{BlasCache, CommittedScene, InstancerDesc, MeshDesc, SceneDesc, commit};
use render_core::volume::{VolumeDesc, VoxelGrid};
use tessera_proto::v1 as pb;
use tonic::Status;

use crate::auth::Tenant;
use crate::budget::{Budget, Reservation};
use crate::convert::{self, invalid};
use crate::limits::Limits;
use crate::textures::{TextureStore, content_hash, is_content_hash};

/// A session's committed state.
pub struct Committed {
    /// The description the scene was built from.
    pub desc: SceneDesc,
    /// The renderable scene.
    pub scene: Arc<CommittedScene>,
    /// Bumped by every successful sync.
    pub version: u64,
    /// The memory the scene is estimated to hold, reserved against the budgets.
    memory: Reservation,
}

/// Figures a session's owner and the operator can read (`GetSessionStats`).
#[derive(Debug, Default)]
pub struct SessionCounters {
    /// Successful syncs.
    pub syncs: AtomicU64,
    /// Renders started.
    pub renders: AtomicU64,
    /// Camera samples taken over all renders.
    pub samples: AtomicU64,
    /// Seconds spent rendering, in microseconds.
    pub render_micros: AtomicU64,
    /// Bytes of array and texture data received.
    pub bytes_received: AtomicU64,
}

/// A client's session.
pub struct Session {
    /// Session id: 128 random bits, so no client can guess another's.
    pub id: String,
    /// The tenant that created it; invisible to every other.
    pub tenant: Tenant,
    state: Mutex<Option<Committed>>,
    cache: Mutex<BlasCache>,
    version: AtomicU64,
    /// Cancel flag of the render in progress, if any.
    pub render_cancel: Mutex<Option<Arc<AtomicBool>>>,
    /// This session's budget, then the server's.
    budgets: Vec<Arc<Budget>>,
    /// True while a Sync is being applied (one at a time).
    syncing: AtomicBool,
    /// A new scene version is being built: the running render stops its pass at once, so
    /// the commit has the cores and the edit reaches the screen without waiting for the pass.
    committing: AtomicBool,
    /// Open Render and Sync streams; a session with one is never idle.
    open_streams: AtomicUsize,
    last_active: Mutex<Instant>,
    /// Figures for `GetSessionStats`.
    pub counters: SessionCounters,
}

/// Held while a stream (Render or Sync) is open on a session: it keeps the session from being
/// reaped as idle, and marks it active again when it ends.
pub struct StreamGuard(Arc<Session>);

impl Drop for StreamGuard {
    fn drop(&mut self) {
        self.0.open_streams.fetch_sub(1, Ordering::AcqRel);
        self.0.touch();
    }
}

/// Held by the one Sync applying to a session.
pub struct SyncGuard(Arc<Session>);

impl Drop for SyncGuard {
    fn drop(&mut self) {
        self.0.syncing.store(false, Ordering::Release);
    }
}

/// Holds a session's commit flag up while a commit runs, whatever way it ends.
struct CommitFlag<'a>(&'a AtomicBool);

impl<'a> CommitFlag<'a> {
    fn raise(flag: &'a AtomicBool) -> Self {
        flag.store(true, Ordering::Release);
        CommitFlag(flag)
    }
}

impl Drop for CommitFlag<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Release);
    }
}

/// Most named primvars one mesh may carry (materials read a handful).
const MAX_PRIMVARS_PER_MESH: usize = 64;

/// Arrays of one mesh arriving in chunks.
#[derive(Default)]
struct StagedMesh {
    prim: pb::MeshPrim,
    points: Vec<f32>,
    indices: Vec<u32>,
    normals: Vec<f32>,
    uvs: Vec<f32>,
    filled: [u64; 4],
    /// Values and received count of each declared primvar.
    primvars: Vec<(Vec<f32>, u64)>,
}

/// A volume's voxels arriving in chunks.
struct StagedVolume {
    prim: pb::VolumePrim,
    density: Vec<f32>,
    temperature: Vec<f32>,
    color: Vec<f32>,
    filled: [u64; 3],
}

/// A texture file arriving in chunks.
struct StagedTexture {
    source: String,
    declared: u64,
    bytes: Vec<u8>,
}

/// Deltas of one `Sync` stream, applied to a copy of the scene description.
pub struct Transaction {
    desc: SceneDesc,
    textures: HashMap<String, StagedTexture>,
    store: Arc<TextureStore>,
    meshes: HashMap<String, StagedMesh>,
    /// Instancers staged: their delta (declared length, motion samples per instance), then
    /// transforms (then motion) as they arrive.
    instancers: HashMap<String, (pb::InstancerPrim, Vec<f64>)>,
    /// Volumes staged: their delta, then density, temperature and colour voxels as they arrive.
    volumes: HashMap<String, StagedVolume>,
    /// Prims applied.
    pub applied: u32,
    limits: Limits,
    /// What the staged arrays hold, reserved as they arrive.
    memory: Reservation,
    budgets: Vec<Arc<Budget>>,
    /// Bytes of array data received.
    pub bytes_received: u64,
    /// Textures this sync decoded, for the shared store once it commits.
    decoded: Vec<(String, Arc<render_core::texture::Image>)>,
}

/// A transaction's result before the commit: the description, the reservation of its staged
/// arrays, and the textures it decoded.
struct Finished {
    desc: SceneDesc,
    staged: Reservation,
    decoded: Vec<(String, Arc<render_core::texture::Image>)>,
}

/// Bytes a committed triangle is estimated to hold: 12 of indices, 36 of ray-tracing
/// triangle, 4 of id and the CWBVH nodes (measured 88 in all on a 1M-triangle mesh,
/// `docs/benchmarks.md`), plus the transient of its build (PLOC's binary tree and boxes),
/// rounded up.
pub const BYTES_PER_TRIANGLE: u64 = 256;
/// Bytes per instance: two affine maps, its bounds and its BVH share.
pub const BYTES_PER_INSTANCE: u64 = 160;
/// Bytes a deforming triangle holds per deformation sample: its ray-tracing triangle at that
/// sample (vertex and two edges, 16 bytes each), besides the sample's positions.
pub const BYTES_PER_TRIANGLE_SAMPLE: u64 = 48;
/// Bytes a light holds: its description, its committed form and its share of the light tree
/// and of the tree of lights rays cross, its path, rounded up. A client controls how many.
pub const BYTES_PER_LIGHT: u64 = 1024;
/// Bytes one motion sample of a light or camera holds (an affine map), in the description and
/// once more committed.
pub const BYTES_PER_MOTION_SAMPLE: u64 = 96;

/// The memory a description is estimated to hold once committed.
pub fn scene_bytes(desc: &SceneDesc) -> u64 {
    let meshes: u64 = desc
        .meshes
        .values()
        .map(|m| {
            let mesh = &m.mesh;
            let tris = mesh.indices.len() as u64;
            let deformation = mesh.deformation.len() as u64 * 12 + tris * mesh.deformation_samples() as u64 * BYTES_PER_TRIANGLE_SAMPLE;
            tris * BYTES_PER_TRIANGLE + mesh.positions.len() as u64 * 12 + attribute_bytes(mesh) + deformation
        })
        .sum();
    let instances: u64 =
        desc.instancers.values().map(|i| i.transforms.len() as u64 * BYTES_PER_INSTANCE + i.motion.len() as u64 * 48).sum();
    // Mip levels add a third; the environment's importance map and tangents stay below that.
    let textures: u64 = desc.textures.values().map(|t| t.bytes() as u64 * 2).sum();
    // Majorant cells (5 bytes per 8³ voxels of at least 4 bytes each) stay below 1/256 of the grids.
    let volumes: u64 = desc.volumes.values().map(|v| v.bytes() + v.bytes() / 256 + v.motion.len() as u64 * BYTES_PER_MOTION_SAMPLE).sum();
    let lights: u64 = desc.lights.values().map(|l| BYTES_PER_LIGHT + l.motion.len() as u64 * BYTES_PER_MOTION_SAMPLE).sum();
    let cameras: u64 = desc.cameras.values().map(|c| c.motion.len() as u64 * BYTES_PER_MOTION_SAMPLE).sum();
    meshes + instances + textures + volumes + lights + cameras
}

fn attribute_bytes(mesh: &Mesh) -> u64 {
    use render_core::geometry::Attribute;
    let len = |a: &Attribute<glam::Vec3>| match a {
        Attribute::None => 0,
        Attribute::Vertex(v) | Attribute::FaceVarying(v) => v.len() as u64 * 12,
    };
    let uvs = match &mesh.uvs {
        Attribute::None => 0,
        Attribute::Vertex(v) | Attribute::FaceVarying(v) => v.len() as u64 * 8,
    };
    len(&mesh.normals) + uvs + mesh.primvars.iter().map(|p| len(&p.values)).sum::<u64>()
}

/// A fresh session id: `s-` and 128 random bits in hex.
pub fn random_id() -> String {
    let mut bits = [0u8; 16];
    getrandom::fill(&mut bits).expect("the OS random source is available");
    let mut id = String::with_capacity(2 + 32);
    id.push_str("s-");
    for b in bits {
        id.push_str(&format!("{b:02x}"));
    }
    id
}

impl Session {
    /// A new, empty session with no owner or budget beyond the defaults (tests, fuzzing).
    pub fn new(id: String) -> Self {
        Self::owned(id, Tenant(Arc::from(crate::auth::LOCAL)), Vec::new())
    }

    /// A new, empty session of `tenant`, its memory held against `budgets` (its own, then the
    /// server's).
    pub fn owned(id: String, tenant: Tenant, budgets: Vec<Arc<Budget>>) -> Self {
        Session {
            id,
            tenant,
            state: Mutex::new(None),
            cache: Mutex::new(BlasCache::default()),
            version: AtomicU64::new(0),
            render_cancel: Mutex::new(None),
            budgets,
            syncing: AtomicBool::new(false),
            committing: AtomicBool::new(false),
            open_streams: AtomicUsize::new(0),
            last_active: Mutex::new(Instant::now()),
            counters: SessionCounters::default(),
        }
    }

    /// The budgets this session's memory is held against.
    pub fn budgets(&self) -> &[Arc<Budget>] {
        &self.budgets
    }

    /// Marks the session as used now.
    pub fn touch(&self) {
        *self.last_active.lock().unwrap() = Instant::now();
    }

    /// How long since the session was last used, or zero while a stream is open on it.
    pub fn idle_for(&self) -> std::time::Duration {
        if self.open_streams.load(Ordering::Acquire) > 0 {
            return std::time::Duration::ZERO;
        }
        self.last_active.lock().unwrap().elapsed()
    }

    /// Counts an open stream until the guard drops.
    pub fn open_stream(self: &Arc<Self>) -> StreamGuard {
        self.open_streams.fetch_add(1, Ordering::AcqRel);
        self.touch();
        StreamGuard(Arc::clone(self))
    }

    /// Claims the session's one Sync slot; `ABORTED` while another Sync holds it (the client
    /// retries after that one returns, so no update is lost silently).
    #[allow(clippy::result_large_err)]
    pub fn claim_sync(self: &Arc<Self>) -> Result<SyncGuard, Status> {
        if self.syncing.swap(true, Ordering::AcqRel) {
            return Err(Status::aborted(format!(
                "session '{}' is already applying a Sync; send one Sync at a time (retry after the other returns)",
                self.id
            )));
        }
        Ok(SyncGuard(Arc::clone(self)))
    }

    /// Whether a Sync holds the session's Sync slot now.
    pub fn is_syncing(&self) -> bool {
        self.syncing.load(Ordering::Acquire)
    }

    /// Whether a new scene version is being committed now.
    pub fn is_committing(&self) -> bool {
        self.committing.load(Ordering::Acquire)
    }

    /// Bytes the committed scene is estimated to hold.
    pub fn scene_bytes(&self) -> u64 {
        self.state.lock().unwrap().as_ref().map_or(0, |c| c.memory.bytes())
    }

    /// Triangles in the committed scene's meshes, those dicing made included.
    pub fn triangles(&self) -> u64 {
        let state = self.state.lock().unwrap();
        state.as_ref().map_or(0, |c| c.desc.meshes.values().map(|m| m.mesh.indices.len() as u64).sum::<u64>() + c.scene.diced_triangles)
    }

    /// The current scene version (0 before the first sync).
    pub fn version(&self) -> u64 {
        self.version.load(Ordering::Acquire)
    }

    /// The committed scene and its version.
    pub fn current(&self) -> Option<(Arc<CommittedScene>, u64)> {
        self.state.lock().unwrap().as_ref().map(|c| (c.scene.clone(), c.version))
    }

    /// Starts a transaction on a copy of the current description.
    pub fn begin(&self, limits: Limits, store: Arc<TextureStore>) -> Transaction {
        let desc = self.state.lock().unwrap().as_ref().map(|c| c.desc.clone()).unwrap_or_default();
        let memory = Reservation::take(&self.budgets, 0, "a sync").expect("nothing fits");
        Transaction {
            desc,
            textures: HashMap::new(),
            store,
            meshes: HashMap::new(),
            instancers: HashMap::new(),
            volumes: HashMap::new(),
            applied: 0,
            limits,
            memory,
            budgets: self.budgets.clone(),
            bytes_received: 0,
            decoded: Vec::new(),
        }
    }

    /// Commits a transaction: validates, reserves the new scene's memory, builds what
    /// changed, and swaps it in. Blocking (BVH builds): call from a blocking thread.
    pub fn commit(&self, tx: Transaction) -> Result<(u64, Vec<String>), Status> {
        let received = tx.bytes_received;
        let store = Arc::clone(&tx.store);
        let Finished { desc, staged, decoded } = tx.finish()?;
        let bytes = scene_bytes(&desc);
        // The old scene stays live (renders hold it) until the new one replaces it: reserve
        // the larger of the two now, and settle on the new size after the swap.
        let old = self.scene_bytes();
        let mut memory = Reservation::take(&self.budgets, bytes.saturating_sub(old), &format!("the scene of session '{}'", self.id))?;
        // From here on the edit is valid: the running render gives the cores to the commit.
        let _flag = CommitFlag::raise(&self.committing);
        drop(staged);
        let scene = {
            let mut cache = self.cache.lock().unwrap();
            commit(&desc, &mut cache).map_err(|e| Status::invalid_argument(e.to_string()))?
        };
        // Dicing for displacement makes triangles the description does not hold.
        let diced = scene.diced_triangles.saturating_mul(BYTES_PER_TRIANGLE);
        memory.grow(diced, &format!("displacement dicing in session '{}' ({} triangles)", self.id, scene.diced_triangles))?;
        let warnings = scene.warnings.clone();
        let mut state = self.state.lock().unwrap();
        let version = self.version.load(Ordering::Acquire) + 1;
        let previous = state.take().map(|c| c.memory);
        if let Some(previous) = previous {
            memory.absorb(previous);
        }
        memory.resize(bytes + diced, "").expect("shrinking always succeeds");
        *state = Some(Committed { desc, scene: Arc::new(scene), version, memory });
        self.version.store(version, Ordering::Release);
        self.counters.syncs.fetch_add(1, Ordering::Relaxed);
        self.counters.bytes_received.fetch_add(received, Ordering::Relaxed);
        drop(state);
        for (hash, image) in decoded {
            store.insert(&hash, image);
        }
        Ok((version, warnings))
    }

    /// Drops the committed scene and its memory (the session is closing).
    pub fn clear(&self) {
        *self.state.lock().unwrap() = None;
        *self.cache.lock().unwrap() = BlasCache::default();
    }

    /// Flags the render in progress to stop; returns whether there was one.
    pub fn cancel_render(&self) -> bool {
        match self.render_cancel.lock().unwrap().as_ref() {
            Some(flag) => {
                flag.store(true, Ordering::Release);
                true
            }
            None => false,
        }
    }
}

fn fill<T: Copy + Default>(
    prim: &str,
    field: &str,
    dst: &mut Vec<T>,
    declared: u64,
    offset: u64,
    src: &[T],
    filled: &mut u64,
) -> Result<(), Status> {
    let end = offset.checked_add(src.len() as u64).ok_or_else(|| invalid(prim, field, "chunk offset overflows"))?;
    if end > declared {
        return Err(invalid(prim, field, format!("chunk [{offset}, {end}) runs past the declared length {declared}")));
    }
    // Chunks arrive in order, so what the server holds never exceeds what the client sent: a
    // declared length alone (up to the per-mesh limit) allocates nothing.
    if offset != dst.len() as u64 {
        return Err(invalid(prim, field, format!("chunk at offset {offset} arrives out of order (expected {})", dst.len())));
    }
    dst.extend_from_slice(src);
    *filled += src.len() as u64;
    Ok(())
}

impl Transaction {
    /// Applies one message of the stream.
    pub fn apply(&mut self, item: pb::sync_request::Item) -> Result<(), Status> {
        match item {
            pb::sync_request::Item::Prim(delta) => self.apply_prim(delta),
            pb::sync_request::Item::Chunk(chunk) => {
                self.reserve_chunk(&chunk)?;
                self.apply_chunk(chunk)
            }
        }
    }

    /// Enforces the advertised chunk size and reserves what the chunk will hold.
    fn reserve_chunk(&mut self, c: &pb::ArrayChunk) -> Result<(), Status> {
        // Texture bytes count four to an element, as floats do.
        let elements = c.floats.len() as u64 + c.uints.len() as u64 + c.doubles.len() as u64 + (c.data.len() as u64).div_ceil(4);
        if elements > self.limits.max_array_chunk_elements {
            return Err(invalid(
                &c.path,
                "chunk",
                format!("{elements} elements in one chunk, over the limit of {}", self.limits.max_array_chunk_elements),
            ));
        }
        let bytes = 4 * (c.floats.len() + c.uints.len()) as u64 + 8 * c.doubles.len() as u64 + c.data.len() as u64;
        self.bytes_received += bytes;
        self.memory.grow(bytes, &format!("{}: the arrays of this sync", c.path))
    }

    /// Refuses a mesh whose declared arrays and BVH could not fit in the memory free now,
    /// before any of its data arrives.
    fn check_declared_mesh(&self, path: &str, m: &pb::MeshPrim) -> Result<(), Status> {
        let floats = m.points_len + m.triangle_indices_len + m.normals_len + m.uvs_len + m.primvars.iter().map(|p| p.len).sum::<u64>();
        // A deforming mesh's BLAS keeps each triangle at every sample besides the frame.
        let per_triangle = BYTES_PER_TRIANGLE.saturating_add((m.point_samples as u64).saturating_mul(BYTES_PER_TRIANGLE_SAMPLE));
        let bytes = floats.saturating_mul(4).saturating_add((m.triangle_indices_len / 3).saturating_mul(per_triangle));
        Budget::check_fits(&self.budgets, bytes, &format!("{path}: {} triangles as declared", m.triangle_indices_len / 3))
    }

    fn apply_prim(&mut self, d: pb::PrimDelta) -> Result<(), Status> {
        if let Some(pb::prim_delta::Payload::Texture(t)) = &d.payload {
            return self.apply_texture(&d.path, t);
        }
        let path = d.path.clone();
        check_prim_path(&path)?;
        self.applied += 1;
        let kind = pb::PrimKind::try_from(d.kind).unwrap_or(pb::PrimKind::Unspecified);
        use pb::prim_delta::Payload;
        match (kind, d.payload) {
            (pb::PrimKind::Remove, _) => {
                self.desc.meshes.remove(&path);
                self.desc.lights.remove(&path);
                self.desc.cameras.remove(&path);
                self.desc.materials.remove(&path);
                self.desc.instancers.remove(&path);
                self.desc.volumes.remove(&path);
                self.meshes.remove(&path);
                self.volumes.remove(&path);
            }
            (pb::PrimKind::Mesh, Some(Payload::Mesh(m))) => self.apply_mesh(path, d.dirty, m)?,
            (pb::PrimKind::Instancer, Some(Payload::Instancer(i))) => self.apply_instancer(path, i)?,
            (pb::PrimKind::Volume, Some(Payload::Volume(v))) => self.apply_volume(path, v)?,
            (pb::PrimKind::Material, Some(Payload::Material(m))) => {
                let network = convert::material_from_wire(&m);
                network.validate(&path).map_err(|e| Status::invalid_argument(e.to_string()))?;
                self.desc.materials.insert(path, network);
            }
            (pb::PrimKind::Light, Some(Payload::Light(l))) => {
                let l = convert::light_from_wire(&path, &l)?;
                self.desc.lights.insert(path, l);
            }
            (pb::PrimKind::Camera, Some(Payload::Camera(c))) => {
                let c = convert::camera_from_wire(&path, &c)?;
                self.desc.cameras.insert(path, c);
            }
            (kind, payload) => {
                return Err(invalid(
                    &path,
                    "payload",
                    format!("kind {kind:?} with payload {:?} is not a valid delta", payload.map(|_| "of another kind")),
                ));
            }
        }
        Ok(())
    }

    /// A mesh delta: with dirty geometry, its declared arrays (checked against the limits and
    /// the budget) are staged for the chunks that follow; otherwise only its placement,
    /// material and visibility change.
    fn apply_mesh(&mut self, path: String, dirty: u32, m: pb::MeshPrim) -> Result<(), Status> {
        let geometry_dirty =
            dirty & (pb::DirtyBits::DirtyPoints as u32 | pb::DirtyBits::DirtyTopology as u32 | pb::DirtyBits::DirtyNormals as u32) != 0;
        convert::link_collections_from_wire(&path, &m.link_collections)?;
        let light = m.light.as_ref().map(|l| convert::mesh_light_from_wire(&path, l)).transpose()?;
        if geometry_dirty {
            let tris = m.triangle_indices_len / 3;
            if tris > self.limits.max_triangles_per_mesh {
                return Err(Status::resource_exhausted(format!(
                    "{path}: {tris} triangles exceed the limit of {} per mesh",
                    self.limits.max_triangles_per_mesh
                )));
            }
            let cap = 9 * self.limits.max_triangles_per_mesh;
            let sets = 1 + m.point_samples as u64;
            if m.point_samples == 1 || m.point_samples as usize > render_core::motion::MAX_MOTION_SAMPLES {
                return Err(invalid(
                    &path,
                    "point_samples",
                    format!("{} deformation samples; 0, or 2 to {}", m.point_samples, render_core::motion::MAX_MOTION_SAMPLES),
                ));
            }
            if !m.points_len.is_multiple_of(3 * sets) {
                return Err(invalid(&path, "points", format!("{} values are not {sets} whole sets of points", m.points_len)));
            }
            if m.points_len / sets > cap || m.normals_len > cap {
                return Err(Status::resource_exhausted(format!("{path}: declared array lengths exceed the per-mesh limit")));
            }
            if m.uvs_len > cap {
                return Err(Status::resource_exhausted(format!("{path}: declared array lengths exceed the per-mesh limit")));
            }
            if !m.uvs_len.is_multiple_of(2) {
                return Err(invalid(&path, "uvs", "length must be a multiple of 2"));
            }
            if m.primvars.len() > MAX_PRIMVARS_PER_MESH {
                return Err(invalid(&path, "primvars", format!("{} primvars, more than {MAX_PRIMVARS_PER_MESH}", m.primvars.len())));
            }
            for pv in &m.primvars {
                if pv.len > cap {
                    return Err(Status::resource_exhausted(format!("{path}: declared array lengths exceed the per-mesh limit")));
                }
                if pv.len % 3 != 0 {
                    return Err(invalid(&path, &format!("primvars:{}", pv.name), "length must be a multiple of 3"));
                }
            }
            if !m.points_len.is_multiple_of(3) || !m.triangle_indices_len.is_multiple_of(3) || !m.normals_len.is_multiple_of(3) {
                return Err(invalid(&path, "mesh", "array lengths must be multiples of 3"));
            }
            self.check_declared_mesh(&path, &m)?;
            let primvars = vec![(Vec::new(), 0); m.primvars.len()];
            self.meshes.insert(path, StagedMesh { prim: m, primvars, ..Default::default() });
        } else {
            // Transform, material or visibility only: keep the geometry, and change only what
            // the dirty bits name (as Hydra's change tracker means them).
            let existing = self.desc.meshes.get_mut(&path).ok_or_else(|| {
                invalid(&path, "dirty", "no geometry was synced before for this mesh; send DIRTY_POINTS | DIRTY_TOPOLOGY")
            })?;
            let bit = |b: pb::DirtyBits| dirty & b as u32 != 0;
            if bit(pb::DirtyBits::DirtyTransform) {
                existing.transform = convert::affine(&path, "transform", &m.transform)?;
                existing.motion = convert::motion_from_wire(&path, "motion", &m.motion)?;
            }
            if bit(pb::DirtyBits::DirtyMaterialId) {
                existing.material = m.material_path;
            }
            if bit(pb::DirtyBits::DirtyVisibility) {
                existing.visible = m.visible;
            }
            if bit(pb::DirtyBits::DirtyCategories) {
                existing.link_collections = m.link_collections;
            }
            if bit(pb::DirtyBits::DirtyParams) {
                existing.light = light;
            }
        }
        Ok(())
    }

    /// An instancer delta: its transforms follow as chunks.
    fn apply_instancer(&mut self, path: String, i: pb::InstancerPrim) -> Result<(), Status> {
        let k = i.motion_samples as u64;
        if k == 1 || k > render_core::motion::MAX_MOTION_SAMPLES as u64 {
            return Err(invalid(
                &path,
                "motion_samples",
                format!("{k}; moving instances have 2 to {}", render_core::motion::MAX_MOTION_SAMPLES),
            ));
        }
        let per_instance = 16 * (1 + k);
        if !i.transforms_len.is_multiple_of(per_instance) {
            return Err(invalid(&path, "transforms", format!("length must be a multiple of {per_instance}")));
        }
        let instances = i.transforms_len / per_instance;
        if instances > self.limits.max_instances {
            return Err(Status::resource_exhausted(format!("{path}: more than {} instances", self.limits.max_instances)));
        }
        check_prim_path(&i.prototype_path)?;
        convert::link_collections_from_wire(&path, &i.link_collections)?;
        Budget::check_fits(
            &self.budgets,
            instances.saturating_mul(BYTES_PER_INSTANCE + 128 + 48 * k),
            &format!("{path}: {instances} instances as declared"),
        )?;
        self.instancers.insert(path, (i, Vec::new()));
        Ok(())
    }

    /// A volume delta: its declared voxels (checked against their dims, the voxel limit and the
    /// budget) are staged for the chunks that follow.
    fn apply_volume(&mut self, path: String, v: pb::VolumePrim) -> Result<(), Status> {
        let voxels = VoxelGrid::voxel_count(glam::UVec3::new(v.dims_x, v.dims_y, v.dims_z));
        if voxels != v.density_len {
            return Err(invalid(&path, "density", format!("{} values declared for {voxels} voxels", v.density_len)));
        }
        if voxels > render_core::volume::grid::MAX_VOXELS {
            return Err(Status::resource_exhausted(format!(
                "{path}: {voxels} voxels exceed the limit of {} per grid",
                render_core::volume::grid::MAX_VOXELS
            )));
        }
        if v.temperature_len != 0 && v.temperature_len != voxels {
            return Err(invalid(&path, "temperature", format!("{} values; 0 or one per voxel ({voxels})", v.temperature_len)));
        }
        if v.color_len != 0 && v.color_len != 3 * voxels {
            return Err(invalid(&path, "color", format!("{} values; 0 or three per voxel ({voxels})", v.color_len)));
        }
        let bytes = (v.density_len + v.temperature_len + v.color_len) * 4;
        Budget::check_fits(&self.budgets, bytes.saturating_mul(2), &format!("{path}: {voxels} voxels as declared"))?;
        self.volumes
            .insert(path, StagedVolume { prim: v, density: Vec::new(), temperature: Vec::new(), color: Vec::new(), filled: [0; 3] });
        Ok(())
    }

    /// A texture file's header: its content hash (the delta's path) and length.
    fn apply_texture(&mut self, hash: &str, t: &pb::TexturePrim) -> Result<(), Status> {
        if !is_content_hash(hash) {
            return Err(invalid(&t.source, "texture path", format!("'{hash}' is not a content hash (sha256: and 64 hex digits)")));
        }
        if t.bytes_len > self.limits.max_texture_file_bytes {
            return Err(Status::resource_exhausted(format!(
                "texture '{}' is {} bytes, over the limit of {}",
                t.source, t.bytes_len, self.limits.max_texture_file_bytes
            )));
        }
        self.applied += 1;
        self.textures.insert(hash.to_string(), StagedTexture { source: t.source.clone(), declared: t.bytes_len, bytes: Vec::new() });
        Ok(())
    }

    fn apply_chunk(&mut self, c: pb::ArrayChunk) -> Result<(), Status> {
        let field = pb::ArrayField::try_from(c.field).unwrap_or(pb::ArrayField::Unspecified);
        if field == pb::ArrayField::TextureBytes {
            let t = self.textures.get_mut(&c.path).ok_or_else(|| invalid(&c.path, "chunk", "no texture delta precedes this chunk"))?;
            let mut filled = 0;
            return fill(&t.source, "texture bytes", &mut t.bytes, t.declared, c.offset, &c.data, &mut filled);
        }
        if field == pb::ArrayField::InstanceTransforms {
            let (prim, data) =
                self.instancers.get_mut(&c.path).ok_or_else(|| invalid(&c.path, "chunk", "no instancer delta precedes this chunk"))?;
            let mut filled = 0;
            return fill(&c.path, "transforms", data, prim.transforms_len, c.offset, &c.doubles, &mut filled);
        }
        if matches!(field, pb::ArrayField::VolumeDensity | pb::ArrayField::VolumeTemperature | pb::ArrayField::VolumeColor) {
            let v = self.volumes.get_mut(&c.path).ok_or_else(|| invalid(&c.path, "chunk", "no volume delta precedes this chunk"))?;
            let (name, values, declared, filled) = match field {
                pb::ArrayField::VolumeDensity => ("density", &mut v.density, v.prim.density_len, &mut v.filled[0]),
                pb::ArrayField::VolumeTemperature => ("temperature", &mut v.temperature, v.prim.temperature_len, &mut v.filled[1]),
                _ => ("color", &mut v.color, v.prim.color_len, &mut v.filled[2]),
            };
            return fill(&c.path, name, values, declared, c.offset, &c.floats, filled);
        }
        let staged = self
            .meshes
            .get_mut(&c.path)
            .ok_or_else(|| invalid(&c.path, "chunk", "no mesh delta with dirty geometry precedes this chunk"))?;
        match field {
            pb::ArrayField::Points => {
                fill(&c.path, "points", &mut staged.points, staged.prim.points_len, c.offset, &c.floats, &mut staged.filled[0])
            }
            pb::ArrayField::TriangleIndices => fill(
                &c.path,
                "triangle_indices",
                &mut staged.indices,
                staged.prim.triangle_indices_len,
                c.offset,
                &c.uints,
                &mut staged.filled[1],
            ),
            pb::ArrayField::Normals => {
                fill(&c.path, "normals", &mut staged.normals, staged.prim.normals_len, c.offset, &c.floats, &mut staged.filled[2])
            }
            pb::ArrayField::Uvs => fill(&c.path, "uvs", &mut staged.uvs, staged.prim.uvs_len, c.offset, &c.floats, &mut staged.filled[3]),
            pb::ArrayField::Primvar => {
                let k = c.primvar as usize;
                let (Some(info), Some((values, filled))) = (staged.prim.primvars.get(k), staged.primvars.get_mut(k)) else {
                    return Err(invalid(&c.path, "chunk.primvar", format!("no primvar {k} was declared")));
                };
                fill(&c.path, &format!("primvars:{}", info.name), values, info.len, c.offset, &c.floats, filled)
            }
            _ => Err(invalid(&c.path, "chunk.field", format!("unknown array field {}", c.field))),
        }
    }

    /// Decodes the uploaded textures (checking each against its hash) into the store, then
    /// gives the description exactly the textures its materials name: from this upload, or
    /// from the store when an earlier sync (of any session) brought them.
    fn finish_textures(&mut self) -> Result<(), Status> {
        for (hash, t) in std::mem::take(&mut self.textures) {
            if t.bytes.len() as u64 != t.declared {
                return Err(invalid(&t.source, "texture bytes", format!("received {} of {} declared bytes", t.bytes.len(), t.declared)));
            }
            if content_hash(&t.bytes) != hash {
                return Err(invalid(&t.source, "texture", format!("the bytes do not hash to {hash}")));
            }
            let free = self.budgets.iter().map(|b| b.available()).min().unwrap_or(u64::MAX);
            let image = render_core::texture::Image::decode_within(&t.bytes, &t.source, self.limits.max_texture_texels, free).map_err(
                |e| match e {
                    render_core::texture::TextureError::OverBudget { .. } => Status::resource_exhausted(e.to_string()),
                    e => Status::invalid_argument(e.to_string()),
                },
            )?;
            let image = Arc::new(image);
            // Into the shared store only once the whole sync has committed.
            self.decoded.push((hash.clone(), Arc::clone(&image)));
            self.desc.textures.insert(hash, image);
        }
        let mut named = std::collections::BTreeSet::new();
        for (material, network) in &self.desc.materials {
            for node in &network.nodes {
                for (input, value) in &node.parameters {
                    for (hash, source) in value.texture_files() {
                        named.insert(hash.to_string());
                        if self.desc.textures.contains_key(hash) {
                            continue;
                        }
                        let image = self.store.get(hash).ok_or_else(|| {
                            Status::failed_precondition(format!(
                                "{material}: {}: input '{input}' names texture '{source}' ({hash}), which was not uploaded; send it as a TexturePrim",
                                node.path
                            ))
                        })?;
                        self.desc.textures.insert(hash.to_string(), image);
                    }
                }
            }
        }
        for (light, l) in &self.desc.lights {
            let Some(t) = &l.texture else { continue };
            named.insert(t.hash.clone());
            if !self.desc.textures.contains_key(&t.hash) {
                let image = self.store.get(&t.hash).ok_or_else(|| {
                    Status::failed_precondition(format!(
                        "{light}: texture:file '{}' ({}) was not uploaded; send it as a TexturePrim",
                        t.source, t.hash
                    ))
                })?;
                self.desc.textures.insert(t.hash.clone(), image);
            }
        }
        self.desc.textures.retain(|h, _| named.contains(h));
        Ok(())
    }

    /// Assembles staged arrays into the final description, and hands back the reservation of
    /// the staged arrays (dropped once the scene's own is taken).
    fn finish(mut self) -> Result<Finished, Status> {
        self.finish_textures()?;
        for (path, s) in self.meshes {
            let p = &s.prim;
            for (name, got, want) in [
                ("points", s.filled[0], p.points_len),
                ("triangle_indices", s.filled[1], p.triangle_indices_len),
                ("normals", s.filled[2], p.normals_len),
                ("uvs", s.filled[3], p.uvs_len),
            ] {
                if got != want {
                    return Err(invalid(&path, name, format!("received {got} of {want} declared values")));
                }
            }
            for (info, (_, got)) in p.primvars.iter().zip(&s.primvars) {
                if *got != info.len {
                    return Err(invalid(
                        &path,
                        &format!("primvars:{}", info.name),
                        format!("received {got} of {} declared values", info.len),
                    ));
                }
            }
            let mut positions: Vec<glam::Vec3> = s.points.chunks_exact(3).map(|v| glam::Vec3::new(v[0], v[1], v[2])).collect();
            // The frame's points first, then the deformation's sets.
            let deformation = positions.split_off(positions.len() / (1 + p.point_samples as usize));
            let indices = s.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            let nrm: Vec<glam::Vec3> = s.normals.chunks_exact(3).map(|v| glam::Vec3::new(v[0], v[1], v[2])).collect();
            let normals = convert::attribute_from_wire(nrm, p.normal_interpolation);
            let st: Vec<glam::Vec2> = s.uvs.chunks_exact(2).map(|v| glam::Vec2::new(v[0], v[1])).collect();
            let uvs = convert::attribute_from_wire(st, p.uv_interpolation);
            let primvars = p
                .primvars
                .iter()
                .zip(s.primvars)
                .map(|(info, (v, _))| Primvar {
                    name: info.name.clone(),
                    values: convert::attribute_from_wire(
                        v.chunks_exact(3).map(|v| glam::Vec3::new(v[0], v[1], v[2])).collect(),
                        info.interpolation,
                    ),
                })
                .collect();
            let mesh = Mesh { positions, indices, normals, uvs, primvars, deformation };
            render_core::scene::validate_mesh(&path, &mesh).map_err(|e| Status::invalid_argument(e.to_string()))?;
            let transform = convert::affine(&path, "transform", &p.transform)?;
            let motion = convert::motion_from_wire(&path, "motion", &p.motion)?;
            let (material, visible, link_collections) = (p.material_path.clone(), p.visible, p.link_collections.clone());
            // Checked when the delta arrived.
            let light = p.light.as_ref().and_then(|l| convert::mesh_light_from_wire(&path, l).ok());
            self.desc.meshes.insert(path, MeshDesc { mesh: Arc::new(mesh), transform, motion, material, visible, link_collections, light });
        }
        for (path, (prim, data)) in self.instancers {
            let k = prim.motion_samples;
            let affines = |field: &str, values: &[f64]| {
                values
                    .chunks_exact(16)
                    .map(|m| convert::affine(&path, field, &Some(pb::Matrix4 { m: m.to_vec() })))
                    .collect::<Result<Vec<_>, _>>()
            };
            let instances = data.len() / (16 * (1 + k as usize));
            let transforms = affines("transforms", &data[..16 * instances])?;
            let motion = affines("motion", &data[16 * instances..])?;
            let (prototype, link_collections) = (prim.prototype_path, prim.link_collections);
            self.desc.instancers.insert(path, InstancerDesc { prototype, transforms, motion, link_collections });
        }
        for (path, v) in self.volumes {
            let volume = volume_from_staged(&path, v)?;
            render_core::volume::validate_volume(&path, &volume).map_err(|e| Status::invalid_argument(e.to_string()))?;
            self.desc.volumes.insert(path, volume);
        }
        let total: u64 = self.desc.meshes.values().map(|m| m.mesh.indices.len() as u64).sum();
        if total > self.limits.max_total_triangles {
            return Err(Status::resource_exhausted(format!(
                "the scene has {total} triangles, over the limit of {}",
                self.limits.max_total_triangles
            )));
        }
        Ok(Finished { desc: self.desc, staged: self.memory, decoded: self.decoded })
    }
}

/// A staged volume's grids, once all their voxels arrived.
fn volume_from_staged(path: &str, v: StagedVolume) -> Result<VolumeDesc, Status> {
    let p = &v.prim;
    for (name, got, want) in
        [("density", v.filled[0], p.density_len), ("temperature", v.filled[1], p.temperature_len), ("color", v.filled[2], p.color_len)]
    {
        if got != want {
            return Err(invalid(path, name, format!("received {got} of {want} declared values")));
        }
    }
    let grid = |values: Vec<f32>| {
        Arc::new(VoxelGrid {
            origin: glam::IVec3::new(p.origin_x, p.origin_y, p.origin_z),
            dims: glam::UVec3::new(p.dims_x, p.dims_y, p.dims_z),
            values,
        })
    };
    let channel = |k: usize| grid(v.color.iter().skip(k).step_by(3).copied().collect());
    Ok(VolumeDesc {
        color: (p.color_len > 0).then(|| [channel(0), channel(1), channel(2)]),
        temperature: (p.temperature_len > 0).then(|| grid(v.temperature)),
        density: grid(v.density),
        index_to_world: convert::affine(path, "index_to_world", &p.index_to_world)?,
        shading: convert::volume_shading_from_wire(&p.shading),
        motion: convert::motion_from_wire(path, "motion", &p.motion)?,
        link_collections: convert::link_collections_from_wire(path, &p.link_collections)?,
    })
}

pub use crate::limits::MAX_PRIM_PATH_BYTES;

/// A prim path as the wire carries it: absolute, bounded, printable (no NUL or other control
/// characters, which would corrupt every message that names the prim).
#[allow(clippy::result_large_err)]
pub fn check_prim_path(path: &str) -> Result<(), Status> {
    let shown: String = path.chars().take(80).collect::<String>().escape_debug().to_string();
    if !path.starts_with('/') {
        return Err(Status::invalid_argument(format!("prim path \"{shown}\" is not an absolute USD path")));
    }
    if path.len() > MAX_PRIM_PATH_BYTES {
        return Err(Status::invalid_argument(format!(
            "prim path \"{shown}...\" is {} bytes, over the limit of {MAX_PRIM_PATH_BYTES}",
            path.len()
        )));
    }
    if path.chars().any(char::is_control) {
        return Err(Status::invalid_argument(format!("prim path \"{shown}\" holds a control character (NUL, newline, ...)")));
    }
    Ok(())
}

//! Conversions between wire messages and render-core types, with validation that names the
//! prim and field at fault. This is the one place protocol errors become `Status`es.

use glam::{Affine3A, DMat4, Mat4, Vec3};
use render_core::camera::CameraDesc;
use render_core::film::{Aov, TileFilm};
use render_core::light::{LightDesc, LightKind, MaterialSync, MeshLight};
use render_core::material::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use render_core::render::MAX_COARSE_START;
use tessera_proto::v1 as pb;
use tonic::Status;

/// An invalid-argument status naming a prim and a field.
pub fn invalid(prim: &str, field: &str, problem: impl std::fmt::Display) -> Status {
    Status::invalid_argument(format!("{prim}: {field}: {problem}"))
}

/// A wire matrix (USD row-vector order) to an affine map.
pub fn affine(prim: &str, field: &str, m: &Option<pb::Matrix4>) -> Result<Affine3A, Status> {
    let Some(m) = m else {
        return Ok(Affine3A::IDENTITY);
    };
    if m.m.len() != 16 {
        return Err(invalid(prim, field, format!("a matrix needs 16 values, got {}", m.m.len())));
    }
    if m.m.iter().any(|x| !x.is_finite()) {
        return Err(invalid(prim, field, "matrix has NaN or Inf"));
    }
    let d = DMat4::from_cols_array(&<[f64; 16]>::try_from(m.m.as_slice()).expect("length checked"));
    Ok(Affine3A::from_mat4(Mat4::from_cols_array(&d.to_cols_array().map(|x| x as f32))))
}

/// An affine map to a wire matrix.
pub fn matrix(a: &Affine3A) -> pb::Matrix4 {
    pb::Matrix4 { m: Mat4::from(*a).to_cols_array().iter().map(|&x| x as f64).collect() }
}

fn float3(v: Vec3) -> pb::Float3 {
    pb::Float3 { x: v.x, y: v.y, z: v.z }
}

fn vec3(v: &Option<pb::Float3>, default: Vec3) -> Vec3 {
    v.as_ref().map_or(default, |c| Vec3::new(c.x, c.y, c.z))
}

/// Wire light to render-core.
pub fn light_from_wire(prim: &str, l: &pb::LightPrim) -> Result<LightDesc, Status> {
    let kind = match pb::LightType::try_from(l.light_type).unwrap_or(pb::LightType::Unspecified) {
        pb::LightType::Sphere => LightKind::Sphere { radius: l.radius },
        pb::LightType::Rect => LightKind::Rect { width: l.width, height: l.height },
        pb::LightType::Disk => LightKind::Disk { radius: l.radius },
        pb::LightType::Distant => LightKind::Distant { angle_degrees: l.angle },
        pb::LightType::Dome => LightKind::Dome,
        pb::LightType::Cylinder => LightKind::Cylinder { radius: l.radius, length: l.length },
        pb::LightType::Unspecified => return Err(invalid(prim, "light_type", "unspecified")),
    };
    check_finite(
        prim,
        &[
            ("intensity", l.intensity),
            ("exposure", l.exposure),
            ("radius", l.radius),
            ("width", l.width),
            ("height", l.height),
            ("angle", l.angle),
            ("length", l.length),
            ("diffuse", l.diffuse.unwrap_or(1.0)),
            ("specular", l.specular.unwrap_or(1.0)),
        ],
    )?;
    for (name, v) in [("radius", l.radius), ("width", l.width), ("height", l.height), ("angle", l.angle), ("length", l.length)] {
        if v < 0.0 {
            return Err(invalid(prim, name, format!("{v} is negative; sizes are zero or more")));
        }
    }
    check_color(prim, "color", &l.color)?;
    Ok(LightDesc {
        light_link: link(prim, "light_link", &l.light_link)?,
        shadow_link: link(prim, "shadow_link", &l.shadow_link)?,
        kind,
        transform: affine(prim, "transform", &l.transform)?,
        intensity: l.intensity,
        exposure: l.exposure,
        color: vec3(&l.color, Vec3::ONE),
        normalize: l.normalize,
        visible_to_camera: l.visible,
        diffuse: l.diffuse.unwrap_or(1.0),
        specular: l.specular.unwrap_or(1.0),
        texture: l.texture.as_ref().map(|t| render_core::texture::TextureRef { hash: t.content_hash.clone(), source: t.source.clone() }),
        motion: motion_from_wire(prim, "motion", &l.motion)?,
        shaping: match &l.shaping {
            None => None,
            Some(s) => {
                for (name, v) in
                    [("shaping.cone_angle", s.cone_angle), ("shaping.cone_softness", s.cone_softness), ("shaping.focus", s.focus)]
                {
                    if !v.is_finite() {
                        return Err(invalid(prim, name, format!("{v} is not finite")));
                    }
                }
                Some(render_core::light::Shaping {
                    cone_angle: s.cone_angle,
                    cone_softness: s.cone_softness,
                    focus: s.focus,
                    focus_tint: vec3(&s.focus_tint, Vec3::ZERO),
                })
            }
        },
    })
}

/// render-core light to wire.
pub fn light_to_wire(l: &LightDesc) -> pb::LightPrim {
    let mut w = pb::LightPrim {
        transform: Some(matrix(&l.transform)),
        intensity: l.intensity,
        exposure: l.exposure,
        color: Some(float3(l.color)),
        normalize: l.normalize,
        visible: l.visible_to_camera,
        diffuse: (l.diffuse != 1.0).then_some(l.diffuse),
        specular: (l.specular != 1.0).then_some(l.specular),
        motion: motion_to_wire(&l.motion),
        shaping: l.shaping.map(|s| pb::Shaping {
            cone_angle: s.cone_angle,
            cone_softness: s.cone_softness,
            focus: s.focus,
            focus_tint: Some(float3(s.focus_tint)),
        }),
        texture: l.texture.as_ref().map(|t| pb::TextureRef { content_hash: t.hash.clone(), source: t.source.clone() }),
        light_link: l.light_link.clone().unwrap_or_default(),
        shadow_link: l.shadow_link.clone().unwrap_or_default(),
        ..Default::default()
    };
    match l.kind {
        LightKind::Sphere { radius } => (w.light_type, w.radius) = (pb::LightType::Sphere as i32, radius),
        LightKind::Rect { width, height } => (w.light_type, w.width, w.height) = (pb::LightType::Rect as i32, width, height),
        LightKind::Disk { radius } => (w.light_type, w.radius) = (pb::LightType::Disk as i32, radius),
        LightKind::Distant { angle_degrees } => (w.light_type, w.angle) = (pb::LightType::Distant as i32, angle_degrees),
        LightKind::Dome => w.light_type = pb::LightType::Dome as i32,
        LightKind::Cylinder { radius, length } => (w.light_type, w.radius, w.length) = (pb::LightType::Cylinder as i32, radius, length),
    }
    w
}

/// A wire mesh light to render-core: its inputs finite, its colour not negative.
pub fn mesh_light_from_wire(prim: &str, l: &pb::MeshLight) -> Result<MeshLight, Status> {
    let inputs = [
        ("light.intensity", l.intensity),
        ("light.exposure", l.exposure),
        ("light.diffuse", l.diffuse.unwrap_or(1.0)),
        ("light.specular", l.specular.unwrap_or(1.0)),
    ];
    check_finite(prim, &inputs)?;
    check_color(prim, "light.color", &l.color)?;
    let sync = match pb::MaterialSync::try_from(l.material_sync) {
        Ok(pb::MaterialSync::GlowTintsLight) => MaterialSync::GlowTintsLight,
        Ok(pb::MaterialSync::Independent) => MaterialSync::Independent,
        Ok(pb::MaterialSync::NoMaterialResponse) => MaterialSync::NoMaterialResponse,
        Err(_) => return Err(invalid(prim, "light.material_sync", format!("{} is not a MaterialSync", l.material_sync))),
    };
    Ok(MeshLight {
        intensity: l.intensity,
        exposure: l.exposure,
        color: vec3(&l.color, Vec3::ONE),
        normalize: l.normalize,
        diffuse: l.diffuse.unwrap_or(1.0),
        specular: l.specular.unwrap_or(1.0),
        sync,
        light_link: link(prim, "light.light_link", &l.light_link)?,
        shadow_link: link(prim, "light.shadow_link", &l.shadow_link)?,
        part_of: part_of(prim, &l.part_of)?,
    })
}

/// The mesh a mesh light is a part of (`light.part_of`): an absolute prim path, bounded and
/// printable, or none.
fn part_of(prim: &str, path: &str) -> Result<Option<String>, Status> {
    const FIELD: &str = "light.part_of";
    check_printable(prim, FIELD, "a prim path", path)?;
    match path {
        "" => Ok(None),
        p if p.starts_with('/') => Ok(Some(p.to_string())),
        _ => Err(invalid(prim, FIELD, "not an absolute prim path")),
    }
}

/// render-core mesh light to wire.
pub fn mesh_light_to_wire(l: &MeshLight) -> pb::MeshLight {
    let sync = match l.sync {
        MaterialSync::GlowTintsLight => pb::MaterialSync::GlowTintsLight,
        MaterialSync::Independent => pb::MaterialSync::Independent,
        MaterialSync::NoMaterialResponse => pb::MaterialSync::NoMaterialResponse,
    };
    pb::MeshLight {
        intensity: l.intensity,
        exposure: l.exposure,
        color: Some(float3(l.color)),
        normalize: l.normalize,
        diffuse: (l.diffuse != 1.0).then_some(l.diffuse),
        specular: (l.specular != 1.0).then_some(l.specular),
        material_sync: sync as i32,
        light_link: l.light_link.clone().unwrap_or_default(),
        shadow_link: l.shadow_link.clone().unwrap_or_default(),
        part_of: l.part_of.clone().unwrap_or_default(),
    }
}

/// Each (field, value) of `prim` finite, or an error naming the first that is not.
fn check_finite(prim: &str, fields: &[(&str, f32)]) -> Result<(), Status> {
    match fields.iter().find(|(_, v)| !v.is_finite()) {
        Some((name, v)) => Err(invalid(prim, name, format!("{v} is not finite"))),
        None => Ok(()),
    }
}

/// A colour (`field` of `prim`) that is finite and not negative, when given.
fn check_color(prim: &str, field: &str, c: &Option<pb::Float3>) -> Result<(), Status> {
    match c {
        Some(c) if !(c.x.is_finite() && c.y.is_finite() && c.z.is_finite() && c.x >= 0.0 && c.y >= 0.0 && c.z >= 0.0) => {
            Err(invalid(prim, field, format!("({}, {}, {}) must be finite and not negative", c.x, c.y, c.z)))
        }
        _ => Ok(()),
    }
}

/// A light-link collection name (`field` of `prim`), checked; empty for none.
fn link(prim: &str, field: &str, name: &str) -> Result<Option<String>, Status> {
    check_link_collection(prim, field, name)?;
    Ok((!name.is_empty()).then(|| name.to_string()))
}

/// Most light-link collections one prim may belong to.
pub const MAX_LINK_COLLECTIONS: usize = 1024;

/// Longest light-link collection name, in bytes (a USD collection's path is a prim path and a
/// property name).
pub const MAX_LINK_COLLECTION_BYTES: usize = 8192;

/// A light-link collection name as a client sends it: bounded and printable.
fn check_link_collection(prim: &str, field: &str, name: &str) -> Result<(), Status> {
    check_printable(prim, field, "a collection name", name)
}

/// A name (`what`: a collection name, a prim path) as a client sends it: at most
/// [`MAX_LINK_COLLECTION_BYTES`] long, without control characters.
fn check_printable(prim: &str, field: &str, what: &str, name: &str) -> Result<(), Status> {
    if name.len() > MAX_LINK_COLLECTION_BYTES {
        return Err(invalid(prim, field, format!("{what} of {} bytes, over the limit of {MAX_LINK_COLLECTION_BYTES}", name.len())));
    }
    if name.chars().any(char::is_control) {
        return Err(invalid(prim, field, format!("{what} holds a control character")));
    }
    Ok(())
}

/// A prim's light-link collections (`link_collections` of `prim`), checked.
pub fn link_collections_from_wire(prim: &str, names: &[String]) -> Result<Vec<String>, Status> {
    if names.len() > MAX_LINK_COLLECTIONS {
        return Err(invalid(prim, "link_collections", format!("{} collections, more than {MAX_LINK_COLLECTIONS}", names.len())));
    }
    for name in names {
        check_link_collection(prim, "link_collections", name)?;
    }
    Ok(names.to_vec())
}

/// Placements over the shutter (`field` of `prim`): 2 to
/// [`render_core::motion::MAX_MOTION_SAMPLES`] finite, invertible matrices, or none.
pub fn motion_from_wire(prim: &str, field: &str, samples: &[pb::Matrix4]) -> Result<Vec<Affine3A>, Status> {
    // Counted before anything is converted: a client may send millions.
    if samples.len() > render_core::motion::MAX_MOTION_SAMPLES {
        return Err(invalid(
            prim,
            field,
            format!("{} motion samples; a motion has 2 to {}", samples.len(), render_core::motion::MAX_MOTION_SAMPLES),
        ));
    }
    let motion = samples.iter().map(|m| affine(prim, field, &Some(m.clone()))).collect::<Result<Vec<_>, _>>()?;
    render_core::motion::check_samples(&motion).map_err(|e| invalid(prim, field, e))?;
    Ok(motion)
}

/// render-core placements over the shutter to wire.
pub fn motion_to_wire(motion: &[Affine3A]) -> Vec<pb::Matrix4> {
    motion.iter().map(matrix).collect()
}

/// Wire camera to render-core.
pub fn camera_from_wire(prim: &str, c: &pb::CameraPrim) -> Result<CameraDesc, Status> {
    for (name, v) in
        [("focal_length", c.focal_length), ("horizontal_aperture", c.horizontal_aperture), ("vertical_aperture", c.vertical_aperture)]
    {
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(prim, name, format!("{v} must be positive")));
        }
    }
    if c.exposure.is_nan() || c.exposure.abs() > render_core::camera::MAX_EXPOSURE_STOPS {
        let most = render_core::camera::MAX_EXPOSURE_STOPS;
        return Err(invalid(prim, "exposure", format!("{} stops; an exposure is within ±{most}", c.exposure)));
    }
    Ok(CameraDesc {
        transform: affine(prim, "transform", &c.transform)?,
        focal_length: c.focal_length,
        horizontal_aperture: c.horizontal_aperture,
        vertical_aperture: c.vertical_aperture,
        horizontal_aperture_offset: c.horizontal_aperture_offset,
        vertical_aperture_offset: c.vertical_aperture_offset,
        near: c.near_clip,
        far: c.far_clip,
        orthographic: c.orthographic,
        f_stop: c.f_stop,
        focus_distance: c.focus_distance,
        shutter_open: c.shutter_open,
        shutter_close: c.shutter_close,
        motion: motion_from_wire(prim, "motion", &c.motion)?,
        exposure: c.exposure,
    })
}

/// render-core camera to wire.
pub fn camera_to_wire(c: &CameraDesc) -> pb::CameraPrim {
    pb::CameraPrim {
        transform: Some(matrix(&c.transform)),
        focal_length: c.focal_length,
        horizontal_aperture: c.horizontal_aperture,
        vertical_aperture: c.vertical_aperture,
        horizontal_aperture_offset: c.horizontal_aperture_offset,
        vertical_aperture_offset: c.vertical_aperture_offset,
        near_clip: c.near,
        far_clip: c.far,
        orthographic: c.orthographic,
        f_stop: c.f_stop,
        focus_distance: c.focus_distance,
        shutter_open: c.shutter_open,
        shutter_close: c.shutter_close,
        motion: motion_to_wire(&c.motion),
        exposure: c.exposure,
    }
}

/// Wire material network to render-core.
pub fn material_from_wire(m: &pb::MaterialNetwork) -> MaterialNetwork {
    MaterialNetwork {
        nodes: m
            .nodes
            .iter()
            .map(|n| MaterialNode {
                path: n.path.clone(),
                node_type_id: n.node_type_id.clone(),
                parameters: n.parameters.iter().filter_map(|(k, v)| param_from_wire(v).map(|p| (k.clone(), p))).collect(),
            })
            .collect(),
        connections: m
            .connections
            .iter()
            .map(|c| MaterialConnection {
                downstream_node: c.downstream_node.clone(),
                downstream_input: c.downstream_input.clone(),
                upstream_node: c.upstream_node.clone(),
                upstream_output: c.upstream_output.clone(),
            })
            .collect(),
        surface_node: m.surface_node.clone(),
    }
}

fn param_from_wire(v: &pb::ParamValue) -> Option<ParamValue> {
    use pb::param_value::Value as V;
    Some(match v.value.as_ref()? {
        V::FloatValue(f) => ParamValue::Float(*f),
        V::Float3Value(c) => ParamValue::Float3(Vec3::new(c.x, c.y, c.z)),
        V::IntValue(i) => ParamValue::Int(*i),
        V::BoolValue(b) => ParamValue::Bool(*b),
        V::StringValue(s) => ParamValue::String(s.clone()),
        V::AssetValue(s) => ParamValue::Asset(s.clone()),
        V::Float2Value(c) => ParamValue::Float2(glam::Vec2::new(c.x, c.y)),
        V::Float4Value(c) => ParamValue::Float4(glam::Vec4::new(c.x, c.y, c.z, c.w)),
        V::TextureValue(t) => ParamValue::Texture { hash: t.content_hash.clone(), source: t.source.clone() },
        V::UdimValue(u) => ParamValue::Udim {
            // A tile number past u16 stays out of range; validation names it.
            tiles: u.tiles.iter().map(|t| (u16::try_from(t.tile).unwrap_or(u16::MAX), t.content_hash.clone())).collect(),
            source: u.source.clone(),
        },
    })
}

/// A mesh attribute (normals, uvs) as flat floats and its interpolation on the wire.
pub fn attribute_to_wire<T: Copy, const N: usize>(
    a: &render_core::geometry::Attribute<T>,
    flat: impl Fn(T) -> [f32; N],
) -> (Vec<f32>, pb::NormalInterpolation) {
    use render_core::geometry::Attribute;
    match a {
        Attribute::None => (Vec::new(), pb::NormalInterpolation::NormalsNone),
        Attribute::Vertex(v) => (v.iter().flat_map(|&x| flat(x)).collect(), pb::NormalInterpolation::NormalsVertex),
        Attribute::FaceVarying(v) => (v.iter().flat_map(|&x| flat(x)).collect(), pb::NormalInterpolation::NormalsFaceVarying),
    }
}

/// The inverse of [`attribute_to_wire`]: values already grouped, laid out by `interpolation`
/// (an unknown value reads as none).
pub fn attribute_from_wire<T>(values: Vec<T>, interpolation: i32) -> render_core::geometry::Attribute<T> {
    use render_core::geometry::Attribute;
    match pb::NormalInterpolation::try_from(interpolation).unwrap_or(pb::NormalInterpolation::NormalsNone) {
        pb::NormalInterpolation::NormalsNone => Attribute::None,
        pb::NormalInterpolation::NormalsVertex => Attribute::Vertex(values),
        pb::NormalInterpolation::NormalsFaceVarying => Attribute::FaceVarying(values),
    }
}

/// render-core material network to wire.
pub fn material_to_wire(m: &MaterialNetwork) -> pb::MaterialNetwork {
    use pb::param_value::Value as V;
    pb::MaterialNetwork {
        nodes: m
            .nodes
            .iter()
            .map(|n| pb::MaterialNode {
                path: n.path.clone(),
                node_type_id: n.node_type_id.clone(),
                parameters: n
                    .parameters
                    .iter()
                    .map(|(k, p)| {
                        let value = match p {
                            ParamValue::Float(f) => V::FloatValue(*f),
                            ParamValue::Float3(c) => V::Float3Value(float3(*c)),
                            ParamValue::Int(i) => V::IntValue(*i),
                            ParamValue::Bool(b) => V::BoolValue(*b),
                            ParamValue::String(s) => V::StringValue(s.clone()),
                            ParamValue::Asset(s) => V::AssetValue(s.clone()),
                            ParamValue::Float2(c) => V::Float2Value(pb::Float2 { x: c.x, y: c.y }),
                            ParamValue::Float4(c) => V::Float4Value(pb::Float4 { x: c.x, y: c.y, z: c.z, w: c.w }),
                            ParamValue::Texture { hash, source } => {
                                V::TextureValue(pb::TextureRef { content_hash: hash.clone(), source: source.clone() })
                            }
                            ParamValue::Udim { tiles, source } => V::UdimValue(pb::UdimSet {
                                tiles: tiles
                                    .iter()
                                    .map(|(tile, hash)| pb::UdimTile { tile: u32::from(*tile), content_hash: hash.clone() })
                                    .collect(),
                                source: source.clone(),
                            }),
                        };
                        (k.clone(), pb::ParamValue { value: Some(value) })
                    })
                    .collect(),
            })
            .collect(),
        connections: m
            .connections
            .iter()
            .map(|c| pb::MaterialConnection {
                downstream_node: c.downstream_node.clone(),
                downstream_input: c.downstream_input.clone(),
                upstream_node: c.upstream_node.clone(),
                upstream_output: c.upstream_output.clone(),
            })
            .collect(),
        surface_node: m.surface_node.clone(),
    }
}

/// A tile of one AOV as a wire message.
pub fn tile_to_wire(tile: &TileFilm, aov: Aov, pass: u32, format: pb::PixelFormat) -> pb::Tile {
    let data = tile.resolve(aov);
    let pixels = match format {
        pb::PixelFormat::F32 => data.iter().flat_map(|v| v.to_le_bytes()).collect(),
        pb::PixelFormat::F16 => data.iter().flat_map(|v| half::f16::from_f32(*v).to_le_bytes()).collect(),
    };
    pb::Tile {
        aov: aov.name().into(),
        x: tile.rect.x,
        y: tile.rect.y,
        width: tile.rect.width,
        height: tile.rect.height,
        channels: aov.channels() as u32,
        pass_index: pass,
        samples: tile.samples,
        format: format as i32,
        pixels,
        pixel_size: 0,
    }
}

/// Decodes a wire tile's pixels to f32, one value per pixel of its rect: a coarse tile's
/// blocks are scaled up (each value fills its block).
pub fn tile_pixels(t: &pb::Tile) -> Result<Vec<f32>, Status> {
    let block = t.pixel_size.max(1);
    if block > MAX_COARSE_START {
        return Err(Status::invalid_argument(format!("tile: pixel_size {block} exceeds {MAX_COARSE_START}")));
    }
    let values = decode_values(t, (t.width.div_ceil(block) * t.height.div_ceil(block) * t.channels) as usize)?;
    if block == 1 {
        return Ok(values);
    }
    let (c, row) = (t.channels as usize, t.width.div_ceil(block) as usize);
    let mut out = Vec::with_capacity((t.width * t.height) as usize * c);
    for y in 0..t.height as usize {
        for x in 0..t.width as usize {
            let i = ((y / block as usize) * row + x / block as usize) * c;
            out.extend_from_slice(&values[i..i + c]);
        }
    }
    Ok(out)
}

fn decode_values(t: &pb::Tile, expected: usize) -> Result<Vec<f32>, Status> {
    let out: Vec<f32> = match pb::PixelFormat::try_from(t.format) {
        Ok(pb::PixelFormat::F32) => t.pixels.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect(),
        Ok(pb::PixelFormat::F16) => t.pixels.chunks_exact(2).map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32()).collect(),
        Err(_) => {
            return Err(Status::invalid_argument(format!("tile: unknown pixel format {}", t.format)));
        }
    };
    if out.len() != expected {
        return Err(Status::invalid_argument(format!("tile: {} values, {expected} expected", out.len())));
    }
    Ok(out)
}

/// Volume shading to the wire.
pub fn volume_shading_to_wire(s: &render_core::volume::VolumeShading) -> pb::VolumeShading {
    pb::VolumeShading {
        density: s.density,
        color: Some(float3(s.color)),
        anisotropy: s.anisotropy,
        emission: Some(float3(s.emission)),
        blackbody_intensity: s.blackbody_intensity,
        blackbody_tint: Some(float3(s.blackbody_tint)),
        temperature: s.temperature,
    }
}

/// Volume shading from the wire: Blender's defaults when absent (validated at commit).
pub fn volume_shading_from_wire(s: &Option<pb::VolumeShading>) -> render_core::volume::VolumeShading {
    let d = render_core::volume::VolumeShading::default();
    let Some(s) = s else { return d };
    render_core::volume::VolumeShading {
        density: s.density,
        color: vec3(&s.color, d.color),
        anisotropy: s.anisotropy,
        emission: vec3(&s.emission, d.emission),
        blackbody_intensity: s.blackbody_intensity,
        blackbody_tint: vec3(&s.blackbody_tint, d.blackbody_tint),
        temperature: s.temperature,
    }
}

//! `UsdVolVolume` prims: their `field:*` relationships to `OpenVDBAsset` fields, the grids
//! read from the VDB files (with the `vdb-rs` crate), made dense over their active voxels, and
//! the bound material's `tessera:Volume` shader (Blender's Principled Volume inputs).

use anyhow::{Context, Result};
use glam::IVec3;
use render_core::volume::{VolumeDesc, VolumeShading, VoxelGrid};

use super::render_settings::valid_targets;
use super::*;

/// The fields a volume renders; any other `field:` relationship is reported. A colour field
/// (`color`, Houdini's `Cd`) is a vec3s grid, which vdb-rs 0.6 cannot read: the renderer and the
/// wire take one (`VolumeDesc::color`), the reader reports it.
const FIELDS: [&str; 2] = ["density", "temperature"];

/// One grid of a VDB file as read: its active voxels (position, value, edge in voxels) and
/// its index-to-object transform.
struct SparseGrid {
    voxels: Vec<(IVec3, f32, i32)>,
    index_to_object: Affine3A,
    /// The file it came from, resolved, and the grid's name there.
    file: String,
    name: String,
}

impl SparseGrid {
    /// Its active voxels, a tile counting each voxel it covers.
    fn active_voxels(&self) -> u64 {
        self.voxels.iter().map(|&(_, _, size)| (size as u64).pow(3)).sum()
    }

    /// The inclusive box of its active voxels (None when it has none).
    fn bounds(&self) -> Option<(IVec3, IVec3)> {
        self.voxels.iter().map(|&(p, _, size)| (p, p + IVec3::splat(size - 1))).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Its values over the box `(lo, hi)`, dense, 0 where inactive.
    fn dense(&self, (lo, hi): (IVec3, IVec3)) -> VoxelGrid {
        let dims = (hi - lo + IVec3::ONE).as_uvec3();
        let mut values = vec![0.0; VoxelGrid::voxel_count(dims) as usize];
        let at = |p: IVec3| {
            let l = (p - lo).as_uvec3();
            l.x as usize + dims.x as usize * (l.y as usize + dims.y as usize * l.z as usize)
        };
        for &(p, v, size) in &self.voxels {
            let (a, b) = (p.max(lo), (p + IVec3::splat(size - 1)).min(hi));
            for z in a.z..=b.z {
                for y in a.y..=b.y {
                    for x in a.x..=b.x {
                        values[at(IVec3::new(x, y, z))] = v;
                    }
                }
            }
        }
        VoxelGrid { origin: lo, dims, values }
    }
}

/// Reads the float grid `name` of the VDB file at `path`. The crate panics on what it does not
/// support (some transforms, older files): caught and reported as an error.
fn read_vdb(path: &std::path::Path, name: &str) -> Result<SparseGrid> {
    let file = std::fs::File::open(path).with_context(|| format!("cannot open '{}'", path.display()))?;
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| -> Result<SparseGrid> {
        let mut reader = vdb_rs::VdbReader::new(std::io::BufReader::new(file)).map_err(|e| anyhow::anyhow!("{e}"))?;
        let Some(descriptor) = reader.grid_descriptors.get(name) else {
            anyhow::bail!("it has no grid '{name}' (it has {})", reader.available_grids().join(", "));
        };
        // vdb-rs 0.6 reads every tree's background and tile values as 4 bytes: a vec3s grid's
        // topology comes out empty (docs/dependencies.md).
        if descriptor.grid_type != "Tree_float_5_4_3" {
            anyhow::bail!("grid '{name}' is a {}, which the VDB reader (vdb-rs 0.6) cannot read: float grids only", descriptor.grid_type);
        }
        let grid = reader.read_grid::<f32>(name).map_err(|e| anyhow::anyhow!("grid '{name}': {e}"))?;
        let voxels =
            grid.iter().map(|(p, v, level)| (IVec3::from_array(p.to_array().map(|x| x as i32)), v, level.scale() as i32)).collect();
        Ok(SparseGrid {
            voxels,
            index_to_object: index_to_object(&grid.transform),
            file: path.display().to_string(),
            name: name.to_string(),
        })
    }));
    read.unwrap_or_else(|_| Err(anyhow::anyhow!("the VDB reader cannot read it (an unsupported transform or file version)")))
}

/// A VDB transform as an affine map from index space to the grid's object space.
fn index_to_object(map: &vdb_rs::Map) -> Affine3A {
    let (scale, translation) = match map {
        vdb_rs::Map::UniformScaleMap { voxel_size, .. } => (voxel_size.to_array(), [0.0; 3]),
        vdb_rs::Map::ScaleTranslateMap { voxel_size, translation, .. } => (voxel_size.to_array(), translation.to_array()),
    };
    Affine3A::from_scale_rotation_translation(
        Vec3::from_array(scale.map(|x| x as f32)),
        glam::Quat::IDENTITY,
        Vec3::from_array(translation.map(|x| x as f32)),
    )
}

impl Reader<'_> {
    /// A Volume prim: its density (and temperature) grids and shading.
    pub(super) fn volume(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let mut grids = std::collections::BTreeMap::new();
        for rel in prim.relationships()? {
            let rel = rel.path().property_suffix().trim_start_matches('.').to_string();
            let Some(field) = rel.strip_prefix("field:").map(str::to_string) else { continue };
            if matches!(field.as_str(), "color" | "Cd") {
                self.out.warnings.push(format!(
                    "{p}: field '{field}' is a vector grid, which the VDB reader (vdb-rs 0.6) cannot read; the volume renders without its colour"
                ));
                continue;
            }
            if !FIELDS.contains(&field.as_str()) {
                self.out.warnings.push(format!("{p}: field '{field}' is not rendered (only density and temperature)"));
                continue;
            }
            let Some(target) = valid_targets(prim, p, &rel)?.into_iter().next() else { continue };
            grids.insert(field.clone(), self.field(p, &field, &target)?);
        }
        let (world, motion) = (self.affine(prim, p)?, self.motion(prim, p)?);
        let mut source = VolumeSource { path: p.to_string(), world, motion, fields: Vec::new(), active_voxels: Vec::new() };
        for (field, g) in &grids {
            source.fields.push((field.clone(), g.file.clone(), g.name.clone()));
            source.active_voxels.push(g.active_voxels());
        }
        let Some(density) = grids.remove("density") else {
            self.out.warnings.push(format!("{p}: no field:density relationship; the volume is not rendered"));
            self.out.skipped.push(p.to_string());
            return Ok(());
        };
        let temperature = grids.remove("temperature").filter(|t| {
            let same = t.index_to_object.abs_diff_eq(density.index_to_object, 1e-6);
            if !same {
                self.out.warnings.push(format!("{p}: the temperature grid's voxels are not the density grid's; it is not used"));
            }
            same
        });
        // With no active voxel at all, an empty box: the grids come out with no voxels.
        let bounds = [density.bounds(), temperature.as_ref().and_then(SparseGrid::bounds)]
            .into_iter()
            .flatten()
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
            .unwrap_or((IVec3::ZERO, IVec3::splat(-1)));
        let voxels = VoxelGrid::voxel_count((bounds.1 - bounds.0 + IVec3::ONE).max(IVec3::ZERO).as_uvec3());
        if voxels > render_core::volume::grid::MAX_VOXELS {
            anyhow::bail!(
                "{p}: the grids' active voxels span {voxels} voxels, over the {} one volume may have",
                render_core::volume::grid::MAX_VOXELS
            );
        }
        let desc = VolumeDesc {
            density: Arc::new(density.dense(bounds)),
            temperature: temperature.map(|t| Arc::new(t.dense(bounds))),
            color: None,
            index_to_world: source.world * density.index_to_object,
            shading: self.volume_shading(prim, p)?,
            motion: source.motion.iter().map(|world| *world * density.index_to_object).collect(),
        };
        if visible {
            self.out.volumes.push((p.to_string(), desc));
            self.out.volume_sources.push(source);
        }
        Ok(())
    }

    /// The grid an `OpenVDBAsset` field prim names: its file and `fieldName`.
    fn field(&mut self, p: &str, field: &str, target: &sdf::Path) -> Result<SparseGrid> {
        let asset = self.stage.prim(target.clone());
        let kind = asset.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
        if kind != "OpenVDBAsset" {
            anyhow::bail!("{p}: field:{field} targets {target}, a '{kind}', not an OpenVDBAsset");
        }
        let file = match get(&asset, "filePath", self.time)? {
            Some(Value::AssetPath(a)) if !a.is_empty() => a,
            _ => anyhow::bail!("{target}: attribute 'filePath' is missing or not an asset path"),
        };
        let resolved = file.resolved_path().map(|r| r.to_string()).unwrap_or_else(|| file.as_str().to_string());
        let name = get(&asset, "fieldName", self.time)?.as_ref().and_then(values::token).unwrap_or_else(|| field.to_string());
        read_vdb(std::path::Path::new(&resolved), &name).with_context(|| format!("{target}: filePath '{}'", file.as_str()))
    }

    /// The bound material's `outputs:volume` shader, read as a `tessera:Volume`; Blender's
    /// Principled Volume defaults without one.
    fn volume_shading(&mut self, prim: &Prim, p: &str) -> Result<VolumeShading> {
        let d = VolumeShading::default();
        let Some(material) = self.bound_material(prim)? else { return Ok(d) };
        let m = self.stage.prim(sdf::Path::new(&material)?);
        let Some(source) = ["outputs:volume", "outputs:tessera:volume"]
            .into_iter()
            .find_map(|o| m.attribute(o).connections().ok().and_then(|c| c.into_iter().next()))
        else {
            self.out.warnings.push(format!("{p}: material {material} has no outputs:volume; Principled Volume defaults are used"));
            return Ok(d);
        };
        let shader = self.stage.prim(source.prim_path());
        let id = get(&shader, "info:id", self.time)?.as_ref().and_then(values::token).unwrap_or_default();
        if id != "tessera:Volume" {
            self.out.warnings.push(format!(
                "{}: volume shader '{id}' is not supported (tessera:Volume is); Principled Volume defaults are used",
                shader.path()
            ));
            return Ok(d);
        }
        let time = self.time;
        let float = |name: &str, default: f32| -> Result<f32> {
            Ok(get(&shader, &format!("inputs:{name}"), time)?.as_ref().and_then(values::scalar).map_or(default, |x| x as f32))
        };
        let color = |name: &str, default: Vec3| -> Result<Vec3> {
            Ok(get(&shader, &format!("inputs:{name}"), time)?.as_ref().and_then(values::vec3).unwrap_or(default))
        };
        Ok(VolumeShading {
            density: float("density", d.density)?,
            color: color("color", d.color)?,
            anisotropy: float("anisotropy", d.anisotropy)?,
            emission: color("emissionColor", Vec3::ONE)? * float("emissionStrength", 0.0)?,
            blackbody_intensity: float("blackbodyIntensity", d.blackbody_intensity)?,
            blackbody_tint: color("blackbodyTint", d.blackbody_tint)?,
            temperature: float("temperature", d.temperature)?,
        })
    }
}
